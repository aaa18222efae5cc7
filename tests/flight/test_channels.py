"""Tests for aeromag_env.flight.channels: which scalar, fluxgate and altitude a run uses, why, and
the fallbacks of real files (an all-NaN ``flux_a`` as in SGL Flt1002, a fluxgate in µT, spikes,
altitude channels that disagree), on small IGRF-built flights and through ``aeromag compensate``."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from aeromag_env.cli.main import main
from aeromag_env.errors import AeromagError
from aeromag_env.flight.channels import (
    ALTITUDE_MARGIN_M,
    choose_channels,
    with_altitude,
)
from aeromag_env.flight.data import Flight, vector_names
from aeromag_env.flight.earth_model import earth_model_ned
from aeromag_env.flight.files import write_flight
from tests._flights import simulated
from tests._synthetic_flights import turning_flight


def _with(flight: Flight, **fields: np.ndarray | None) -> Flight:
    """A copy of ``flight`` with fields added, replaced, or (None) removed."""
    out = {k: v.copy() for k, v in flight.fields.items()}
    for name, values in fields.items():
        if values is None:
            out.pop(name, None)
        else:
            out[name] = np.asarray(values, dtype=float)
    return Flight(out, dict(flight.attrs))


def _flux(flight: Flight, prefix: str, values: np.ndarray) -> dict[str, np.ndarray]:
    return dict(zip(vector_names(prefix), values.T, strict=True))


@pytest.fixture(scope="module")
def base() -> Flight:
    return turning_flight()


def test_a_clean_file_uses_the_first_channel_of_each_kind(base: Flight) -> None:
    ch = choose_channels(base)
    assert (ch.fluxgate.name, ch.scalar.name, ch.altitude.name) == ("flux_a", "mag_1_uc", "alt")
    assert ch.fluxgate.reason.startswith("first clean fluxgate in name order (100 % finite")
    assert ch.warnings == ()
    assert set(ch.to_dict()) == {"fluxgate", "scalar", "altitude"}


def test_an_all_nan_flux_a_falls_back_to_flux_b_and_says_why(base: Flight) -> None:
    """SGL Flt1002: flux_a is all NaN, flux_b holds the data."""
    flight = _with(
        base,
        **_flux(base, "flux_b", base.vector("flux_a")),
        **_flux(base, "flux_a", np.full((base.n, 3), np.nan)),
    )
    ch = choose_channels(flight, require=("fluxgate",))
    assert ch.fluxgate.name == "flux_b"
    assert "passed over flux_a: all non-finite" in ch.fluxgate.reason
    assert ch.warnings == ("fluxgate: using flux_b, not flux_a (flux_a: all non-finite)",)


def test_a_missing_flux_a_uses_the_fluxgate_there_is_without_a_warning(base: Flight) -> None:
    flight = _with(
        base,
        **_flux(base, "flux_c", base.vector("flux_a")),
        **dict.fromkeys(vector_names("flux_a")),
    )
    ch = choose_channels(flight)
    assert ch.fluxgate.name == "flux_c" and ch.warnings == ()


def test_a_fluxgate_in_microtesla_and_one_full_of_spikes_are_passed_over(base: Flight) -> None:
    spiky = base.vector("flux_a").copy()
    spiky[560:860:25, 1] += 5_000.0  # 12 single spikes of 5000 nT on the straight leg (> 0.1 %)
    flight = _with(
        base,
        **_flux(base, "flux_a", base.vector("flux_a") / 1000.0),
        **_flux(base, "flux_b", spiky),
        **_flux(base, "flux_c", base.vector("flux_a")),
    )
    ch = choose_channels(flight)
    assert ch.fluxgate.name == "flux_c"
    assert "flux_a: flux_a_x/y/z looks like µT" in ch.fluxgate.reason
    assert re.search(r"flux_b: 100 % finite, median \d+ nT, 12 spike\(s\)", ch.fluxgate.reason)


def test_without_a_clean_candidate_the_most_complete_is_used(base: Flight) -> None:
    a, b = base.vector("flux_a").copy(), base.vector("flux_a").copy()
    a[:300] = np.nan  # 67 % finite
    b[:100] = np.nan  # 89 % finite
    flight = _with(base, **_flux(base, "flux_a", a), **_flux(base, "flux_b", b))
    ch = choose_channels(flight)
    assert ch.fluxgate.name == "flux_b" and ch.fluxgate.reason.startswith("none clean")


def test_no_usable_fluxgate_is_a_one_line_error_naming_each(base: Flight) -> None:
    flight = _with(base, **_flux(base, "flux_a", np.full((base.n, 3), np.nan)))
    with pytest.raises(AeromagError, match=r"no usable fluxgate channel: flux_a: all non-finite"):
        choose_channels(flight, require=("fluxgate",))
    bare = _with(base, **dict.fromkeys(vector_names("flux_a")))
    with pytest.raises(AeromagError, match="none in the file"):
        choose_channels(bare, require=("fluxgate",))
    assert choose_channels(bare).fluxgate is None  # not required: no error


def test_an_explicit_name_is_used_as_given(base: Flight) -> None:
    flight = _with(base, **_flux(base, "flux_b", base.vector("flux_a")))
    assert choose_channels(flight, flux="flux_b").fluxgate.name == "flux_b"
    with pytest.raises(AeromagError) as err:
        choose_channels(flight, flux="flux_q")
    assert str(err.value) == (
        "--flux flux_q: no fluxgate flux_q (flux_q_x/y/z) in the file; fluxgates present: "
        "flux_a, flux_b"
    )
    with pytest.raises(AeromagError, match="scalars present: mag_1_uc"):
        choose_channels(flight, scalar="mag_7_uc")
    empty = _with(flight, **_flux(base, "flux_a", np.full((base.n, 3), np.nan)))
    ch = choose_channels(empty, flux="flux_a")
    assert ch.fluxgate.name == "flux_a"  # the user's choice stands, with a warning
    assert any("flux_a is all non-finite" in w and "flux_b" in w for w in ch.warnings)


def test_scalars_are_taken_in_numeric_order(base: Flight) -> None:
    flight = _with(base, mag_1_uc=None, mag_10_uc=base["mag_1_uc"], mag_2_uc=base["mag_1_uc"])
    assert choose_channels(flight).scalar.name == "mag_2_uc"


@pytest.mark.parametrize(
    ("offset_m", "scale", "warned", "hint"),
    [
        (30.0, 1.0, False, ""),  # ellipsoid vs sea level: within the geoid's undulation
        (300.0, 1.0, True, ""),
        (0.0, 3.28084, True, "utm_z looks like feet"),
    ],
)
def test_altitude_channels_that_disagree_are_warned_about(
    base: Flight, offset_m: float, scale: float, warned: bool, hint: str
) -> None:
    flight = _with(base, utm_z=base["alt"] * scale + offset_m)
    ch = choose_channels(flight)
    assert ch.altitude.name == "alt"  # the preference order decides; the warning says so
    messages = [w for w in ch.warnings if "altitude channels disagree" in w]
    assert bool(messages) == warned
    if warned:
        assert f"(> {ALTITUDE_MARGIN_M:.0f} m)" in messages[0] and hint in messages[0]


def test_an_empty_alt_falls_back_to_utm_z_which_the_earth_model_then_reads(base: Flight) -> None:
    flight = _with(base, alt=np.full(base.n, np.nan), utm_z=base["alt"] + 1000.0)
    ch = choose_channels(flight)
    assert ch.altitude.name == "utm_z" and "passed over alt: all non-finite" in ch.altitude.reason
    work = with_altitude(flight, ch.altitude)
    np.testing.assert_array_equal(work["alt"], flight["utm_z"])
    assert "alt" in flight and np.isnan(flight["alt"]).all()  # the input is not touched
    # 1000 m higher: IGRF weaker by ~0.02–0.03 nT/m, so by 15–40 nT [nT]
    drop = np.linalg.norm(earth_model_ned(base), axis=1) - np.linalg.norm(
        earth_model_ned(work), axis=1
    )
    assert 15.0 < float(np.median(drop)) < 40.0
    assert with_altitude(base, choose_channels(base).altitude) is base


def test_compensate_falls_back_to_flux_b_and_reports_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """SGL-like: flux_a empty, flux_b the data; utm_z 300 m off alt."""
    f = simulated("nominal", 0)
    flight = _with(
        f,
        **_flux(f, "flux_b", f.vector("flux_a")),
        **_flux(f, "flux_a", np.full((f.n, 3), np.nan)),
        utm_z=f["alt"] + 300.0,
    )
    path = write_flight(flight, tmp_path / "nan_flux_a.h5")
    assert main(["compensate", str(path), "--method", "lsq", "--out", str(tmp_path / "o")]) == 0
    err = capsys.readouterr().err.splitlines()
    report = json.loads((tmp_path / "o" / "report.json").read_text())
    assert err == [
        "aeromag compensate: warning: fluxgate: using flux_b, not flux_a (flux_a: all non-finite)",
        "aeromag compensate: warning: altitude channels disagree: alt and utm_z differ by a median "
        "300 m (> 100 m); using alt (IGRF changes by ~0.03 nT/m with height)",
        # the reader's input problems follow, each one line (the empty flux_a among them)
        *(f"aeromag compensate: warning: {p}" for p in report["input_problems"]),
    ]
    assert any(p.startswith("non-finite samples") for p in report["input_problems"])
    assert report["channels"]["altitude"]["name"] == "alt"
    assert report["channels"]["fluxgate"]["name"] == "flux_b"
    assert "flux_a: all non-finite" in report["channels"]["fluxgate"]["reason"]
    assert report["settings"]["flux"] == "flux_b"
    assert report["metrics"]["improvement_ratio"] > 10


def test_compensate_with_an_unknown_fluxgate_is_a_one_line_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = write_flight(turning_flight(), tmp_path / "f.h5")
    code = main(
        [
            "compensate",
            str(path),
            "--method",
            "lsq",
            "--flux",
            "flux_z",
            "--out",
            str(tmp_path / "o"),
        ]
    )
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "fluxgates present: flux_a" in err
