"""Discovery with the magnetic ground separated (``--ground separate``): the ground leaves the
fits, tests and gap; fast effects are found over it; what it hides is listed."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from aeromag_env.cli.main import main
from aeromag_env.discovery.base_model import base_columns
from aeromag_env.discovery.ground import (
    KNOT_FACTORS,
    MIN_RUN_SAMPLES,
    as_fitted,
    base_off_ground,
    ground_reference,
)
from aeromag_env.discovery.noise_model import NoiseModel, fit_noise
from aeromag_env.discovery.preparation import prepare
from aeromag_env.discovery.suite import Case, base_config, build_case
from aeromag_env.discovery.workflow import discover
from aeromag_env.errors import AeromagError
from aeromag_env.flight.data import Flight
from aeromag_env.flight.files import write_flight
from aeromag_env.simulation.config import GeologyConfig, SimulationConfig
from aeromag_env.simulation.simulate import simulate_flight

SLOW = ("external_field_variation", "permanent_field_drift", "altitude_gradient")


def _over_ground(cfg: SimulationConfig, rms_nt: float) -> SimulationConfig:
    return dataclasses.replace(cfg, geology=GeologyConfig(rms_nt=rms_nt))


@pytest.fixture(scope="module")
def ground_flight() -> Flight:
    """The suite's 30-min flight over 50 nT of ground (at 400 m), nothing hidden."""
    return simulate_flight(_over_ground(base_config(1800.0), 50.0), 91_002)


def _crust(flight: Flight) -> np.ndarray:
    return np.column_stack([flight[f"truth_crust_{a}"] for a in "xyz"])


def test_the_ground_span_takes_the_crust_and_leaves_the_manoeuvres(ground_flight: Flight) -> None:
    """On the true crustal field in body axes, the runs' splines leave under 2 % of its RMS; of
    the eddy-like regressor Ṫ on the calibration box they leave most."""
    data = prepare(ground_flight, "flux_a", None, ground=True)
    ref = data.ground
    assert ref is not None and ref.runs and not ref.dropped
    used = np.concatenate([r.idx for r in ref.runs])
    crust = _crust(ground_flight)
    left = ref.remove(crust)[used]
    assert np.sqrt(np.mean(left**2)) < 0.02 * np.sqrt(np.mean(crust[used] ** 2))
    box = used[ground_flight["alt"][used] > 2500.0]
    tdot = data.ctx.tdot_b
    kept = ref.remove(tdot)[box] - ref.remove(tdot)[box].mean(axis=0)
    assert np.sum(kept**2) > 0.5 * np.sum((tdot[box] - tdot[box].mean(axis=0)) ** 2)
    # the knots follow the clearance: about 3 s apart at 400 m, over 10 s on the box at 3000 m
    spacing = {round(r.clearance_m, -2): r.spacing_s for r in ref.runs}
    assert spacing[400.0] < 4.0 < 10.0 < spacing[3000.0]


@pytest.mark.slow
def test_stronger_ground_gets_closer_knots() -> None:
    """AIC picks closer knots where the ground leaves more of itself between them."""
    factors = {}
    for rms in (5.0, 500.0):
        flight = simulate_flight(_over_ground(base_config(1200.0), rms), 91_003)
        ref = prepare(flight, "flux_a", None, ground=True).ground
        assert ref is not None
        factors[rms] = np.mean([r.knots_per_clearance for r in ref.runs])
    assert factors[500.0] < factors[5.0] <= KNOT_FACTORS[0]


@pytest.mark.slow
@pytest.mark.parametrize(("extra", "source"), [("radar", "radar"), ("dem", "alt − dem")])
def test_the_clearance_comes_from_the_radar_or_the_terrain_model(
    ground_flight: Flight, extra: str, source: str
) -> None:
    """Over terrain at 300 m (radar ``alt − 300``, or ``dem`` 300) the lines are 100 m above
    the ground: their knots are 4× closer than at the 400 m the altitude says; a few bad radar
    samples (0 m) do not move them."""
    alt = ground_flight["alt"]
    values = np.full_like(alt, 300.0) if extra == "dem" else alt - 300.0
    if extra == "radar":
        values[::500] = 0.0
    flight = dataclasses.replace(ground_flight, fields={**ground_flight.fields, extra: values})
    ref = prepare(flight, "flux_a", None, ground=True).ground
    plain = prepare(ground_flight, "flux_a", None, ground=True).ground
    assert ref is not None and plain is not None
    assert ref.clearance_source == f"{source} on 100% of samples"
    low = [r for r in ref.runs if r.clearance_m < 150.0]
    assert low and all(r.clearance_m > 90.0 for r in low)
    assert min(r.spacing_s for r in low) < 0.35 * min(r.spacing_s for r in plain.runs)


@pytest.mark.slow
def test_a_radar_out_of_range_leaves_the_clearance_to_the_altitude(ground_flight: Flight) -> None:
    """A radar that reads NaN above 1000 m: the lines take its 100 m, the box at 3000 m its
    altitude (knots over 10 s apart, not the 0.5 s a zero-filled radar would give)."""
    alt = ground_flight["alt"]
    radar = np.where(alt < 1000.0, alt - 300.0, np.nan)
    flight = dataclasses.replace(ground_flight, fields={**ground_flight.fields, "radar": radar})
    ref = prepare(flight, "flux_a", None, ground=True).ground
    assert ref is not None
    assert (
        ref.clearance_source.startswith("radar on ")
        and "alt (ground at 0 m) on" in ref.clearance_source
    )
    box = [r for r in ref.runs if r.clearance_m > 2500.0]
    assert box and min(r.spacing_s for r in box) > 10.0
    assert min(r.clearance_m for r in ref.runs) == pytest.approx(100.0, abs=1.0)


@pytest.mark.slow
def test_over_ground_nothing_is_named_and_the_gap_no_longer_measures_geology(
    ground_flight: Flight,
) -> None:
    """Ignored, the ground is the held-out gap (tens of nT); separated, the gap is at the noise
    floor, nothing is named, and the slow effects are listed as absorbed by the ground."""
    ignored = discover(ground_flight).report
    assert ignored["gap"]["rms_before_nt"] > 20.0 and ignored["ground"] == {"mode": "ignore"}
    sep = discover(ground_flight, ground="separate").report
    assert sep["missing_effects"] == [] and sep["gap"]["rms_before_nt"] < 0.5
    assert sep["verdict"] == "nothing significant is missing off the ground"
    assert sep["ground"]["mode"] == "separate" and sep["ground"]["columns"] > 100
    absorbed = {c["name"] for c in sep["candidates"] if c["verdict"] == "absorbed"}
    assert set(SLOW) <= absorbed
    assert len(sep["caveats"]) == 1 and all(n in sep["caveats"][0] for n in SLOW)
    assert "isotropic part of A" in sep["ground"]["base_model"]


@pytest.mark.slow
@pytest.mark.parametrize(
    ("seed", "name"), [(92_003, "induced_second_order"), (92_006, "sensor_lag")]
)
def test_a_fast_effect_over_ground_is_named_only_with_the_ground_separated(
    seed: int, name: str
) -> None:
    """At SNR 2 over 50 nT of ground: ignoring the ground, induced_second_order is lost (README
    table); separated, each is named alone and its gap shrinks."""
    cfg, _ = build_case(Case("single", seed, (name,), 2.0))
    flight = simulate_flight(_over_ground(cfg, 50.0), seed)
    sep = discover(flight, ground="separate").report
    assert [e["name"] for e in sep["missing_effects"]] == [name]
    assert sep["gap"]["rms_after_nt"] < 0.5 * sep["gap"]["rms_before_nt"]
    if name == "induced_second_order":
        assert name not in [e["name"] for e in discover(flight).report["missing_effects"]]


@pytest.mark.slow
def test_the_base_model_reads_only_the_traceless_part_of_a_off_ground(
    ground_flight: Flight,
) -> None:
    """A_zz's column is zeroed off the ground and the reading removes A's isotropic part; the
    traceless part agrees with the fit that ignores the ground on the same flight without it."""
    data = prepare(ground_flight, "flux_a", None, ground=True)
    assert data.ground is not None
    base = base_off_ground(data.ground, base_columns(data.ctx.t_b, data.ctx.tdot_b))
    assert not base[:, 2, 17].any() and base[:, 0, 1].any()
    beta = np.arange(21.0)
    read = as_fitted(beta, data.ground)
    assert np.allclose(read[[1, 9, 17]].sum(), 0) and np.array_equal(as_fitted(beta, None), beta)
    assert np.allclose(np.delete(read - beta, [1, 9, 17]), 0)
    plain = simulate_flight(base_config(1800.0), 91_002)
    a_sep = np.array(
        discover(ground_flight, ground="separate").report["base_model"]["coefficients"]["induced"]
    ).reshape(3, 3)
    a_plain = np.array(discover(plain).report["base_model"]["coefficients"]["induced"])
    a_plain = a_plain.reshape(3, 3) - np.trace(a_plain.reshape(3, 3)) / 3 * np.eye(3)
    assert np.abs(a_sep - a_plain).max() < 3e-4


@pytest.mark.slow
def test_runs_too_short_for_the_ground_are_dropped(ground_flight: Flight) -> None:
    """A 30-sample calibration island inside a held-out block is its own run, too short: it is
    dropped; the held-out samples on either side stay runs of their own. A spike (an unusable
    sample) does not split a run."""
    data = prepare(ground_flight, "flux_a", None)
    calibration, usable = data.calibration.copy(), data.usable.copy()
    assert not calibration[1300:1330].any() and usable[1290:1340].all()
    calibration[1300:1330] = True
    usable[1500] = False
    ref = ground_reference(
        ground_flight,
        data.ctx.c_nb,
        data.y,
        base_columns(data.ctx.t_b, data.ctx.tdot_b),
        usable,
        calibration,
    )
    assert [d.tolist() for d in ref.dropped] == [list(range(1300, 1330))]
    starts = {int(r.idx[0]): int(r.idx[-1]) for r in ref.runs}
    assert starts[1330] == 1799 and 1299 in starts.values()
    assert all(r.idx.size >= MIN_RUN_SAMPLES for r in ref.runs)


def test_the_noise_fit_survives_a_correlation_time_that_underflows() -> None:
    """A white residual lets the search drive the FOGM's τ to 0 (exp underflows); that point is
    refused, not a ZeroDivisionError."""
    rng = np.random.default_rng(0)
    r = rng.standard_normal((4000, 3))
    gap = np.r_[np.inf, np.full(3999, 0.1)]
    start = NoiseModel(np.ones(3), np.full(3, 0.5), np.full(3, math.exp(-720.0)))
    fit = fit_noise(r, gap, start)
    assert np.all(np.isfinite(fit.white_std_nt)) and np.all(fit.white_std_nt > 0.5)


@pytest.mark.slow
def test_ground_mode_is_validated_and_reaches_the_cli(
    ground_flight: Flight, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(AeromagError, match="ground must be one of ignore, separate"):
        discover(ground_flight, ground="band")
    path = write_flight(ground_flight, tmp_path / "ground.h5")
    out = tmp_path / "d"
    assert main(["discover", str(path), "--out", str(out), "--ground", "separate"]) == 0
    report = json.loads((out / "report.json").read_text())
    assert report["ground"]["mode"] == "separate" and report["ground"]["runs"] > 10
    assert "Magnetic ground: separated" in (out / "report.md").read_text()
    err = capsys.readouterr().err
    assert "ground reference absorbs" in err and "slow signal" not in err
    with pytest.raises(SystemExit) as exit_info:
        main(["discover", str(path), "--out", str(tmp_path / "e"), "--ground", "band"])
    assert exit_info.value.code == 2
    assert "invalid choice: 'band'" in capsys.readouterr().err
    # a fleet (a folder) passes the mode on to each flight
    fleet = tmp_path / "fleet"
    fleet.mkdir()
    path.rename(fleet / "ground.h5")
    assert (
        main(
            [
                "discover",
                str(fleet),
                "--out",
                str(tmp_path / "f"),
                "--ground",
                "separate",
                "--quiet",
            ]
        )
        == 0
    )
    one = json.loads((tmp_path / "f" / "ground" / "report.json").read_text())
    assert one["ground"]["mode"] == "separate" and one["report_version"] == 4
