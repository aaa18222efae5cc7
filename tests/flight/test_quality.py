"""Tests for aeromag_env.flight.quality: time gaps and spikes found in simulated flights with
faults injected at known places, and no false alarm on clean ones."""

from __future__ import annotations

import numpy as np
import pytest

from aeromag_env.flight.data import Flight
from aeromag_env.flight.files import write_flight
from aeromag_env.flight.info import describe
from aeromag_env.flight.quality import fault_report, find_gaps, segments, spike_flags
from aeromag_env.simulation.config import preset, with_overrides
from aeromag_env.simulation.simulate import simulate_flight
from tests._synthetic_flights import turning_flight


def _flight(pattern: str, seed: int, name: str = "nominal") -> Flight:
    cfg = with_overrides(
        preset(name), {"trajectory.pattern": pattern, "trajectory.duration_s": 1200.0}
    )
    return simulate_flight(cfg, rng=seed)


@pytest.fixture(scope="module")
def clean() -> Flight:
    return _flight("calibration+survey", 11)


def _with(flight: Flight, keep: np.ndarray | None = None, **edits: tuple[int, float]) -> Flight:
    fields = {k: v.copy() for k, v in flight.fields.items()}
    for name, (index, add) in edits.items():
        fields[name][index] += add
    if keep is not None:
        fields = {k: v[keep] for k, v in fields.items()}
    return Flight(fields, dict(flight.attrs))


@pytest.mark.parametrize(
    ("pattern", "seed", "name"),
    [
        ("calibration", 0, "nominal"),
        ("survey", 1, "nominal"),
        ("calibration+survey", 2, "paper"),
        ("calibration", 3, "paper"),
    ],
)
def test_no_false_alarm_on_clean_flights(pattern: str, seed: int, name: str) -> None:
    report = fault_report(_flight(pattern, seed, name))
    assert report["spikes"] == {} and report["gap_count"] == 0 and report["segments"] == 1
    assert report["bad_maneuver_labels"] == 0


def test_no_false_alarm_on_steps_and_sharp_turns() -> None:
    """An instantaneous 25° bank (the synthetic turning flight) and a 300 nT step in the scalar
    (equipment switched on) are not spikes."""
    flight = turning_flight()
    flight["mag_1_uc"][450:] += 300.0  # [nT]
    assert not any(f.any() for f in spike_flags(flight, ["flux_a", "mag_1_uc"]).values())


def test_spikes_found_where_injected(clean: Flight) -> None:
    k_scalar, k_flux = 5000, 9000
    faulty = _with(clean, mag_1_uc=(k_scalar, 1e6), flux_a_y=(k_flux, -5000.0))  # [nT]
    flags = spike_flags(faulty, ["mag_1_uc", "flux_a"])
    assert np.flatnonzero(flags["mag_1_uc"]).tolist() == [k_scalar]
    assert np.flatnonzero(flags["flux_a"]).tolist() == [k_flux]


def test_gap_found_and_flight_split(clean: Flight) -> None:
    keep = (clean.tt < 600.0) | (clean.tt >= 630.0)  # a 30 s hole in the log
    gapped = _with(clean, keep)
    gaps = find_gaps(gapped.tt)
    assert len(gaps) == 1 and gaps[0].duration_s == pytest.approx(30.1, abs=1e-6)  # [s]
    assert gaps[0].t_start_s == pytest.approx(599.9) and gaps[0].t_end_s == pytest.approx(630.0)
    parts = segments(gapped.tt)
    assert [(s.start, s.stop) for s in parts] == [(0, 6000), (6000, gapped.n)]


def test_info_reports_both_faults(clean: Flight, tmp_path) -> None:
    keep = (clean.tt < 600.0) | (clean.tt >= 630.0)
    faulty = _with(_with(clean, mag_1_uc=(5000, 1e6)), keep)
    report = describe(write_flight(faulty, tmp_path / "faulty.h5"))
    text = "\n".join(report.lines)
    assert report.usable
    assert "continuous segments: 2 (1 time gap(s))" in text and "spikes: 1" in text
    assert any("30.1 s at t = 599.9 s" in p for p in report.problems)
    assert any("compensated as 2 continuous segments" in p for p in report.problems)
    spike = "mag_1_uc: 1 spike(s) (t = 500 s…), flagged: left out wherever mag_1_uc is used"
    assert any(p.startswith(spike) for p in report.problems)
    assert report.to_dict()["faults"]["spikes"]["mag_1_uc"]["times_s"] == [500.0]


def test_labels_that_are_not_window_ids_are_warned_and_read_as_outside(
    clean: Flight, tmp_path
) -> None:
    """A corrupt byte made a ``maneuver`` label 2**33 (hypothesis found it): the label reads as
    0, the windows are those of the clean file, and ``info`` says so."""
    labels = clean["maneuver"].copy()
    labels[[10, 20, 30]] = [2.0**33, -1.0, 2.5]
    labels[40] = np.nan  # a missing label is not a bad one
    bad = Flight({**clean.fields, "maneuver": labels}, dict(clean.attrs))
    assert bad.maneuver_windows() == clean.maneuver_windows()
    assert fault_report(bad)["bad_maneuver_labels"] == 3
    report = describe(write_flight(bad, tmp_path / "bad.h5"))
    assert any(
        p.startswith("maneuver: 3 sample(s) hold labels that are not window ids")
        for p in report.problems
    )
