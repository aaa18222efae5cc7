"""``aeromag info``: summary of good and bad flight files, text and JSON."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from aeromag_env.flight.files import write_flight
from aeromag_env.flight.info import describe, group_fields, main_info
from tests._synthetic_flights import in_radians, turning_flight, with_fields


@pytest.fixture
def good_file(tmp_path: Path) -> Path:
    flight = turning_flight()
    flight["flux_a_y"][[20, 21, 400]] = np.nan
    return write_flight(flight, tmp_path / "good.h5")


def test_describe_a_good_file(good_file: Path) -> None:
    report = describe(good_file)
    assert report.usable
    summary = report.to_dict()
    assert summary["format"] == "HDF5" and summary["samples"] == 900
    assert summary["duration_s"] == pytest.approx(89.9, abs=1e-9)
    assert summary["sample_rate_hz"] == pytest.approx(10.0, rel=1e-9)
    assert summary["date"] == "2020-06-01" and summary["attributes"] == ["date", "config"]
    assert summary["fields"]["auxiliary"] == ["cur_strb"]
    assert summary["fields"]["fluxgates"] == ["flux_a_x", "flux_a_y", "flux_a_z"]
    assert summary["fields"]["scalars"] == ["mag_1_uc"]
    assert summary["fields"]["other"] == ["maneuver", "line"]
    assert [w["id"] for w in summary["maneuver_windows"]] == [1, 2, 3]
    assert summary["maneuver_windows"][2] == {"id": 3, "t_start_s": 70.0, "t_end_s": 80.0}
    assert [fl["id"] for fl in summary["flight_lines"]] == [1001, 1002]
    assert summary["flight_lines"][1]["samples"] == 450
    assert summary["nonfinite"]["flux_a_y"]["ranges"] == [[20, 21], [400, 400]]
    assert len(report.problems) == 1 and "non-finite" in report.problems[0]


def test_report_lines_name_what_matters(good_file: Path) -> None:
    text = "\n".join(describe(good_file).lines)
    assert f"file: {good_file} (HDF5)" in text
    assert "maneuver windows: 3" in text and "  3: 70–80 s" in text
    assert "  auxiliary (1): cur_strb" in text
    assert "flight lines: 2" in text and "  1002: 45–89.9 s (450 samples)" in text
    assert "flux_a_y: 3 of 900 non-finite at index 20–21, 400" in text
    assert "problems: 1" in text


def test_json_output_is_strict_json(good_file: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main_info(str(good_file), as_json=True) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed == json.loads(json.dumps(describe(good_file).to_dict(), allow_nan=False))
    assert printed["usable"] is True and len(printed["maneuver_windows"]) == 3


def test_text_output_and_exit_status(good_file: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main_info(str(good_file), as_json=False) == 0
    assert capsys.readouterr().out.splitlines() == describe(good_file).lines


@pytest.mark.parametrize(
    ("content", "word"),
    [(None, "not found"), (b"", "empty"), (b"lat,lon\n45,-75\n", "missing required field(s) tt")],
)
def test_describe_a_bad_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], content: bytes | None, word: str
) -> None:
    path = tmp_path / "bad.csv"
    if content is not None:
        path.write_bytes(content)
    report = describe(path)
    assert not report.usable
    assert len(report.problems) == 1 and word in report.problems[0]
    assert "\n" not in report.problems[0]
    assert json.dumps(report.to_dict(), allow_nan=False)
    assert main_info(str(path), as_json=True) == 2
    assert json.loads(capsys.readouterr().out)["usable"] is False


def test_implausible_units_make_the_file_unusable_but_keep_the_summary(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = write_flight(in_radians(turning_flight()), tmp_path / "radians.csv")
    before = path.read_bytes()
    report = describe(path)
    assert not report.usable  # issue 2: exit non-zero on a file in the wrong units
    assert any("look like radians" in p for p in report.problems)
    assert report.to_dict()["samples"] == turning_flight().n  # the summary is still there
    assert main_info(str(path), as_json=False) == 2
    assert "look like radians" in capsys.readouterr().out
    assert path.read_bytes() == before


def test_single_sample_file_has_no_rate(tmp_path: Path) -> None:
    flight = turning_flight()
    flight = with_fields(flight, **{nm: flight[nm][:1] for nm in flight.names})
    report = describe(write_flight(flight, tmp_path / "one.csv"))
    assert report.usable and report.to_dict()["sample_rate_hz"] is None
    assert json.dumps(report.to_dict(), allow_nan=False)


def test_group_fields_sorts_real_sgl_names() -> None:
    names = ["tt", "utm_z", "ins_vn", "ins_yaw", "flux_b_t", "mag_3_c", "vol_bat_1", "temp_1"]
    names += ["truth_interf_x", "drape", "diurnal"]
    groups = group_fields(names)
    assert groups["navigation"] == ["tt", "utm_z", "ins_vn"]
    assert groups["attitude"] == ["ins_yaw"] and groups["fluxgates"] == ["flux_b_t"]
    assert groups["scalars"] == ["mag_3_c"] and groups["auxiliary"] == ["vol_bat_1", "temp_1"]
    assert groups["truth"] == ["truth_interf_x"] and groups["other"] == ["drape", "diurnal"]
