"""Tests for aeromag_env.flight.selection: lines, time segments and the calibration line found
from the labels or from the attitude alone, on simulated calibration + survey flights."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from aeromag_env.cli.main import main
from aeromag_env.errors import AeromagError
from aeromag_env.flight.data import Flight
from aeromag_env.flight.files import read_flight, write_flight
from aeromag_env.flight.selection import (
    find_calibration_line,
    line_mask,
    segment_mask,
    subset,
)
from aeromag_env.simulation.config import preset, with_overrides
from aeromag_env.simulation.simulate import simulate_flight

#: The simulator's line ids: 1 the calibration box, 0 transits and turns, 1001… survey lines.
BOX_LINE = 1.0


@pytest.fixture(scope="module", params=[("nominal", 1), ("paper", 7)])
def survey(request: pytest.FixtureRequest) -> Flight:
    """One calibration box then survey lines (about 35 minutes)."""
    name, seed = request.param
    cfg = with_overrides(preset(name), {"trajectory.pattern": "calibration+survey"})
    return simulate_flight(cfg, rng=seed)


def _without(flight: Flight, *names: str) -> Flight:
    return Flight({k: v for k, v in flight.fields.items() if k not in names}, dict(flight.attrs))


def test_calibration_line_from_the_labels(survey: Flight) -> None:
    cal = find_calibration_line(survey)
    assert cal.line == BOX_LINE and "labelled" in cal.reason
    np.testing.assert_array_equal(cal.mask, survey["line"] == BOX_LINE)
    # every labelled manoeuvre sample is on it
    assert np.all(cal.mask[survey["maneuver"] > 0])


def test_calibration_line_from_the_attitude_alone(survey: Flight) -> None:
    """Without the labels, the box is told from the survey lines (straight, one heading) and
    from the transits and turns (several headings, but no fast roll and pitch swings)."""
    cal = find_calibration_line(_without(survey, "maneuver"))
    assert cal.line == BOX_LINE and "roll/pitch activity" in cal.reason


def test_no_box_is_an_error_not_a_guess(survey: Flight) -> None:
    lines_only = subset(survey, survey["line"] != BOX_LINE, "survey lines")
    with pytest.raises(AeromagError, match="no line flown with manoeuvres"):
        find_calibration_line(_without(lines_only, "maneuver"))
    with pytest.raises(AeromagError, match="needs a 'line' field"):
        find_calibration_line(_without(survey, "line"))


def test_given_line_is_used_and_checked(survey: Flight) -> None:
    assert find_calibration_line(survey, 1003.0).mask.sum() == np.sum(survey["line"] == 1003)
    with pytest.raises(AeromagError, match=r"line 77, not in this flight \(it has 1, 0, 1001"):
        find_calibration_line(survey, 77.0)


def test_lines_and_segments_select_samples(survey: Flight) -> None:
    mask = line_mask(survey, (1001.0, 1003.0))
    assert set(np.unique(survey["line"][mask])) == {1001.0, 1003.0}
    t0, t1 = 100.0, 400.5
    seg = segment_mask(survey, (t0, t1))
    assert survey.tt[seg].min() >= 100.0 and survey.tt[seg].max() <= 400.5
    part = subset(survey, mask, "lines 1001, 1003")
    assert part.n == mask.sum() and part.attrs["selection"] == "lines 1001, 1003"
    assert part.names == survey.names


def test_a_segment_outside_the_flight_is_refused(survey: Flight) -> None:
    with pytest.raises(AeromagError, match="holds 0 samples"):
        segment_mask(survey, (1e7, 2e7))


# --- the options on the command line -------------------------------------------------------


@pytest.fixture(scope="module")
def survey_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A calibration box then survey lines, written as a file (nominal, seed 1)."""
    cfg = with_overrides(preset("nominal"), {"trajectory.pattern": "calibration+survey"})
    path = tmp_path_factory.mktemp("survey") / "survey.h5"
    write_flight(simulate_flight(cfg, rng=1), path)
    return path


def test_tl_fitted_on_the_calibration_line_and_judged_on_the_lines(
    survey_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The industry's recipe: fit on the box, apply to the lines; the held-out figures are the
    lines' own, and they are close to those of a fit on the whole flight (the box excites every
    term, the lines add little)."""
    out = tmp_path / "cal"
    assert (
        main(
            [
                "compensate",
                str(survey_file),
                "--method",
                "tl",
                "--out",
                str(out),
                "--calibration-line",
            ]
        )
        == 0
    )
    report = json.loads((out / "report.json").read_text())
    cal = report["selection"]["calibration_line"]
    assert cal["line"] == 1 and "labelled" in cal["reason"]
    assert report["settings"]["calibration_samples"] == cal["samples"]
    held = report["held_out"]
    flight = read_flight(survey_file)
    assert held["samples"] == flight.n - cal["samples"]
    assert held["improvement_ratio"] > 5.0  # the fit carries over to the lines [-]
    whole = tmp_path / "whole"
    assert main(["compensate", str(survey_file), "--method", "tl", "--out", str(whole)]) == 0
    rmse_whole = json.loads((whole / "report.json").read_text())["metrics"]["compensation_rmse_nt"]
    # within a factor 2 of the fit that saw the lines too [nT]
    assert held["compensation_rmse_nt"] < 2.0 * rmse_whole


def test_line_selection_keeps_the_calibration_line(survey_file: Path, tmp_path: Path) -> None:
    out = tmp_path / "line"
    assert (
        main(
            [
                "compensate",
                str(survey_file),
                "--method",
                "lsq",
                "--out",
                str(out),
                "--line",
                "1002",
                "--calibration-line",
                "1",
            ]
        )
        == 0
    )
    written = read_flight(out / "compensated.h5")
    assert set(np.unique(written["line"])) == {1.0, 1002.0}
    report = json.loads((out / "report.json").read_text())
    assert report["selection"]["lines"] == [1002]
    assert report["held_out"]["samples"] == np.sum(written["line"] == 1002)


def test_info_on_one_line(survey_file: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["info", str(survey_file), "--line", "1003", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["selection"]["lines"] == [1003]
    assert [fl["id"] for fl in summary["flight_lines"]] == [1003]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--line", "77"], "line 77, not in this flight"),
        (["--segment", "3:1"], "finite T0 < T1"),
        (["--calibration-line", "x"], "--calibration-line takes one line id"),
        (["--calibration-line", "--calibration-window", "0", "500"], "not both"),
    ],
)
def test_bad_selections_are_one_line_errors(
    survey_file: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    args: list[str],
    message: str,
) -> None:
    code = main(
        ["compensate", str(survey_file), "--method", "lsq", "--out", str(tmp_path / "x"), *args]
    )
    err = capsys.readouterr().err.strip()
    assert code == 2 and message in err and len(err.splitlines()) == 1
    assert not (tmp_path / "x").exists()


def test_discover_fits_on_the_calibration_line(survey_file: Path, tmp_path: Path) -> None:
    """The calibration line becomes discover's calibration window (the box is one stretch)."""
    out = tmp_path / "disc"
    assert (
        main(["discover", str(survey_file), "--out", str(out), "--calibration-line", "--quiet"])
        == 0
    )
    report = json.loads((out / "report.json").read_text())
    assert report["selection"]["calibration_line"]["line"] == 1
    flight = read_flight(survey_file)
    # discover drops a sample or two at the ends for its derivatives [samples]
    assert abs(report["data"]["calibration_samples"] - np.sum(flight["line"] == 1)) <= 4
