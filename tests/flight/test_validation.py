"""Checks on loaded flights: structure, time, units (field and attitude), non-finite report."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import h5py
import numpy as np
import pytest

from aeromag_env.errors import FlightFileError
from aeromag_env.flight.data import Flight
from aeromag_env.flight.files import load_flight, read_flight, write_flight
from aeromag_env.flight.validation import (
    format_nonfinite,
    needed_fields,
    nonfinite_report,
    validate,
)
from tests._synthetic_flights import (
    in_radians,
    northbound_flight,
    only,
    turning_flight,
    with_fields,
)

EVERYTHING = ("tt", "position", "attitude", "date", "flux_a", "mag_1_uc")
ATTITUDE_ONLY = ("tt", "ins_roll", "ins_pitch", "ins_yaw")


def raises_one_line(flight: Flight, needs: Iterable[str], *words: str) -> str:
    """Validate, expect a FlightFileError whose one-line message names the file and ``words``."""
    with pytest.raises(FlightFileError) as exc:
        validate(flight, "dir/flight.h5", needs)
    message = str(exc.value)
    assert "\n" not in message and message.startswith("dir/flight.h5: ")
    for word in words:
        assert word in message, f"{word!r} not in {message!r}"
    return message


def test_a_plausible_flight_passes_without_warnings() -> None:
    assert validate(turning_flight(), "f.h5", EVERYTHING) == []
    assert validate(northbound_flight(), "f.h5", EVERYTHING) == []


def test_needed_fields_expand_groups_and_vectors() -> None:
    flight = with_fields(turning_flight(), alt=None, utm_z=np.full(900, 3000.0))
    expected = {"lat", "lon", "utm_z", "flux_a_x", "flux_a_y", "flux_a_z", "cur_strb"}
    assert needed_fields(flight, ("position", "flux_a", "cur_strb")) == expected


def test_length_mismatch_names_fields_and_lengths() -> None:
    flight = turning_flight()
    flight.fields["mag_1_uc"] = flight["mag_1_uc"][:-2]
    flight.fields["cur_strb"] = flight["cur_strb"][:-1]
    raises_one_line(flight, ("tt",), "different lengths", "mag_1_uc has 898", "cur_strb has 899")
    raises_one_line(flight, ("tt",), "other 12 field(s) have 900")


def test_length_mismatch_in_a_file(tmp_path: Path) -> None:
    path = tmp_path / "ragged.h5"
    with h5py.File(path, "w") as f:
        f["tt"] = np.arange(10.0)
        f["lat"] = np.full(10, 45.0)
        f["lon"] = np.full(9, -75.0)
    with pytest.raises(
        FlightFileError, match=r"ragged\.h5: fields of different lengths: lon has 9"
    ):
        read_flight(path)


@pytest.mark.parametrize(
    ("index", "value", "words"),
    [
        (5, 0.4, ["not strictly increasing", "index 5 t = 0.4 s follows t = 0.4 s"]),
        (5, 0.3, ["not strictly increasing", "index 5", "t = 0.3 s follows t = 0.4 s"]),
        (7, np.nan, ["tt", "non-finite", "index 7"]),
    ],
)
def test_time_must_be_finite_and_strictly_increasing(
    index: int, value: float, words: list[str]
) -> None:
    flight = turning_flight()
    flight["tt"][index] = value
    raises_one_line(flight, ("tt",), *words)


def test_empty_flights_are_refused() -> None:
    raises_one_line(Flight({}), ("tt",), "no numeric")
    raises_one_line(Flight({"tt": np.empty(0)}), ("tt",), "no samples")


@pytest.mark.parametrize(
    ("scale", "unit", "factor"), [(1e-3, "µT", "1000"), (1e-5, "gauss", "1e5"), (1e-9, "T", "1e9")]
)
def test_fluxgate_in_another_unit_is_refused_when_needed(
    scale: float, unit: str, factor: str
) -> None:
    flight = turning_flight()
    for axis in "xyz":
        flight.fields[f"flux_a_{axis}"] = flight[f"flux_a_{axis}"] * scale
    raises_one_line(flight, ("flux_a",), "flux_a", f"looks like {unit}; expected nT", factor)
    warnings = validate(flight, "f.h5", ("tt",))  # not needed: a warning only
    assert any(f"looks like {unit}" in w for w in warnings)


def test_scalar_in_microtesla_is_refused() -> None:
    flight = turning_flight()
    flight.fields["mag_1_uc"] = flight["mag_1_uc"] / 1000.0
    raises_one_line(flight, ("mag_1_uc",), "mag_1_uc looks like µT", "multiply by 1000")


def test_large_real_interference_is_not_refused() -> None:
    flight = turning_flight()
    flight.fields["flux_a_x"] = flight["flux_a_x"] + 80_000.0  # |field| 80–110 µT, in nT
    warnings = validate(flight, "f.h5", ("flux_a",))
    assert len(warnings) == 1 and "outside the Earth-field range" in warnings[0]


def test_field_far_beyond_the_earth_is_refused() -> None:
    flight = turning_flight()
    flight.fields["mag_1_uc"] = flight["mag_1_uc"] * 10.0
    raises_one_line(flight, ("mag_1_uc",), "mag_1_uc", "implausible", "nT")


def test_radians_attitude_is_refused_by_the_fluxgate_test() -> None:
    message = raises_one_line(
        in_radians(turning_flight()),
        ("attitude",),
        "ins_roll/ins_pitch/ins_yaw look like radians; expected degrees (multiply by 180/π)",
    )
    assert "IGRF direction vs flux_a" in message


def test_radians_attitude_is_refused_by_the_course_test() -> None:
    flight = only(in_radians(turning_flight()), "tt", "lat", "lon", "alt", *ATTITUDE_ONLY[1:])
    raises_one_line(flight, ("attitude",), "look like radians", "course over ground")


def test_radians_attitude_with_a_turn_is_refused_without_other_channels() -> None:
    flight = only(in_radians(turning_flight()), *ATTITUDE_ONLY)
    raises_one_line(flight, ("attitude",), "look like radians", "turns through 3.1")


def test_northbound_line_in_degrees_is_not_flagged() -> None:
    # every angle is within ±2π and the yaw spans 5 (> 3): only physics can tell
    flight = northbound_flight()
    assert np.abs(flight["ins_yaw"]).max() < 2.6 and np.ptp(flight["ins_yaw"]) > 4.9
    assert validate(flight, "f.h5", ("attitude",)) == []
    no_fluxgate = only(flight, "tt", "lat", "lon", "alt", *ATTITUDE_ONLY[1:])
    assert validate(no_fluxgate, "f.h5", ("attitude",)) == []


def test_ambiguous_attitude_without_evidence_is_a_warning() -> None:
    warnings = validate(only(northbound_flight(), *ATTITUDE_ONLY), "f.h5", ("attitude",))
    assert len(warnings) == 1 and "ambiguous" in warnings[0]


def test_radians_attitude_is_only_a_warning_when_not_needed() -> None:
    warnings = validate(in_radians(turning_flight()), "f.h5", ("flux_a",))
    assert any("look like radians" in w for w in warnings)


def test_latitude_out_of_range_and_bad_date() -> None:
    flight = turning_flight()
    flight.fields["lat"] = flight["lat"] + 60.0
    raises_one_line(flight, ("position",), "lat reaches", "±90")
    flight = turning_flight()
    flight.attrs["date"] = "first of June"
    raises_one_line(flight, ("date",), "unreadable date", "first of June")


def test_nonfinite_report_counts_and_locates() -> None:
    flight = turning_flight()
    flight["flux_a_x"][[10, 11, 12, 50]] = [np.nan, np.nan, np.inf, -np.inf]
    flight["mag_1_uc"][[1, 3, 5, 7, 9, 11, 13]] = np.nan
    report = nonfinite_report(flight, max_ranges=5)
    assert set(report) == {"flux_a_x", "mag_1_uc"}
    flux = report["flux_a_x"]
    assert flux["count"] == 4 and flux["samples"] == 900
    assert flux["ranges"] == [[10, 12], [50, 50]] and flux["n_ranges"] == 2
    assert (flux["first_index"], flux["last_index"]) == (10, 50)
    assert (flux["first_time_s"], flux["last_time_s"]) == (1.0, 5.0)
    assert format_nonfinite("flux_a_x", flux) == (
        "flux_a_x: 4 of 900 non-finite at index 10–12, 50, t 1–5 s"
    )
    mag = report["mag_1_uc"]
    assert mag["n_ranges"] == 7 and len(mag["ranges"]) == 5
    assert "(+2 more ranges)" in format_nonfinite("mag_1_uc", mag)


def test_nonfinite_samples_load_and_are_reported(tmp_path: Path) -> None:
    flight = turning_flight()
    flight["cur_strb"][100:110] = np.nan
    path = write_flight(flight, tmp_path / "gaps.csv")
    back, warnings = load_flight(path, needs=EVERYTHING)
    assert np.isnan(back["cur_strb"][100:110]).all()
    assert nonfinite_report(back)["cur_strb"]["ranges"] == [[100, 109]]
    expected = "cur_strb: 10 of 900 non-finite at index 100–109, t 10–10.9 s"
    assert warnings == [f"non-finite samples in 1 field(s): {expected}"]


def test_a_single_token_string_is_one_need() -> None:
    flight = only(turning_flight(), "tt", "flux_a_x", "flux_a_y")
    raises_one_line(flight, "flux_a", "missing required field(s) flux_a_z;")
