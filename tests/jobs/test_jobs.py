"""The jobs' one door (:mod:`aeromag_env.jobs`): the command line and the library give the same
numbers and the same warnings, and ``compensate_vector`` is never silent about a rotated
fluxgate.

The flight: the simulator's nominal calibration box (seed 5, 527 s at 10 Hz) delivered as a real
file would be, with ``flux_a`` turned 45° about z (sensor axes = body axes yawed by 45°), a 30 s
logger gap (300–330 s) and one 1e6 nT spike in ``mag_1_uc``.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import aeromag_env as am
from aeromag_env.cli.main import main
from aeromag_env.cli.summaries import compensate_line, discover_line
from aeromag_env.errors import AeromagError, AeromagWarning
from aeromag_env.flight.data import Flight, vector_names
from aeromag_env.jobs.reports import report_json
from tests._flights import simulated

#: The fluxgate's turn about the body z axis [deg].
YAW_DEG = 45.0


def _rotated(flight: Flight, yaw_deg: float) -> Flight:
    """``flight`` with ``flux_a`` read in axes yawed by ``yaw_deg`` from the body axes."""
    c, s = np.cos(np.deg2rad(yaw_deg)), np.sin(np.deg2rad(yaw_deg))
    body_to_sensor = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    turned = flight.vector("flux_a") @ body_to_sensor.T
    return Flight(
        {**flight.fields, **dict(zip(vector_names("flux_a"), turned.T, strict=True))}, flight.attrs
    )


@pytest.fixture(scope="module")
def delivered() -> Flight:
    """The rotated flight with a gap and a spike (module docstring)."""
    flight = _rotated(simulated("nominal", 5), YAW_DEG)
    fields = {name: values.copy() for name, values in flight.fields.items()}
    fields["mag_1_uc"][np.searchsorted(flight.tt, 400.0)] += 1e6
    keep = ~((flight.tt >= 300.0) & (flight.tt < 330.0))
    return Flight({name: values[keep] for name, values in fields.items()}, dict(flight.attrs))


@pytest.fixture(scope="module")
def flight_file(delivered: Flight, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return am.write_flight(delivered, tmp_path_factory.mktemp("jobs") / "delivered.h5")


def _cli(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[str, list[str]]:
    """``aeromag ARGV`` (exit 0 asserted): its stdout and its warning lines (without prefix)."""
    capsys.readouterr()
    assert main(list(argv)) == 0
    out, err = capsys.readouterr()
    prefix = f"aeromag {argv[0]}: warning: "
    said = [line.removeprefix(prefix) for line in err.splitlines()]
    assert all(line.startswith(prefix) for line in err.splitlines()), err
    return out, said


def _library(job: Callable[..., Any], *args: Any, **options: Any) -> tuple[Any, list[str]]:
    """Run a job door; its result and the AeromagWarnings it issued, in order."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = job(*args, **options)
    return result, [str(w.message) for w in caught if issubclass(w.category, AeromagWarning)]


@pytest.mark.parametrize("mount", ["auto", "identity"])
def test_compensate_cli_and_library_agree(
    flight_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], mount: str
) -> None:
    cli_out, lib_out = tmp_path / "cli", tmp_path / "lib"
    argv = ["compensate", str(flight_file), "--method", "lsq", "--mount", mount]
    printed, cli_said = _cli(capsys, *argv, "--out", str(cli_out))
    result, issued = _library(am.compensate, flight_file, "lsq", lib_out, mount=mount)

    cli_report = (cli_out / "report.json").read_text(encoding="utf-8")
    assert (lib_out / "report.json").read_text(encoding="utf-8") == cli_report
    assert report_json(result.report) == cli_report
    assert printed == compensate_line(result.report, cli_out) + "\n"
    assert list(result.warnings) == issued  # the command prints them, then the input problems
    assert cli_said == [*result.warnings, *result.input_problems]
    assert result.paths == tuple(
        lib_out / n for n in ("compensated.h5", "report.json", "compensation.png", "report.html")
    )
    # the gap, the spike and the mount are in the numbers both doors gave
    assert result.report["metrics"]["segments"]["count"] == 2
    assert any("mag_1_uc: 1 spike(s)" in problem for problem in result.input_problems)
    assert result.report["mount"]["estimate"]["angle_from_body_deg"] == pytest.approx(
        YAW_DEG, abs=1.0
    )
    if mount == "identity":  # the sensor axes taken for body axes: said, with the angle
        assert len(result.warnings) == 1 and "45.0°" in result.warnings[0]
    else:  # the estimate applied: nothing to warn about
        assert result.report["mount"]["applied"] and result.warnings == ()


def test_compensate_takes_a_flight_in_memory(delivered: Flight, flight_file: Path) -> None:
    """A flight in memory gives the file's numbers; the report has no input file."""
    from_file = am.compensate(flight_file, "lsq")
    in_memory = am.compensate(delivered, "lsq")
    assert in_memory.metrics == from_file.metrics
    assert in_memory.coefficients == from_file.coefficients
    assert in_memory.report["input"] is None and in_memory.report["input_sha256"] is None
    assert in_memory.paths == ()


def test_compensate_refuses_an_unknown_option_or_method(flight_file: Path) -> None:
    with pytest.raises(AeromagError, match="unknown option 'mounts'"):
        am.compensate(flight_file, "lsq", mounts="auto")
    with pytest.raises(AeromagError, match="method must be one of"):
        am.compensate(flight_file, "lms")


@pytest.mark.slow
def test_discover_cli_and_library_agree(
    flight_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cli_out, lib_out = tmp_path / "cli", tmp_path / "lib"
    argv = ["discover", str(flight_file), "--mount", "identity", "--quiet"]
    printed, cli_said = _cli(capsys, *argv, "--out", str(cli_out))
    result, issued = _library(am.discover, flight_file, lib_out, mount="identity")
    for name in ("report.json", "report.md", "model_config.json"):
        assert (lib_out / name).read_bytes() == (cli_out / name).read_bytes()
    assert printed == discover_line(result.report, cli_out) + "\n"
    assert list(result.warnings) == issued  # the command prints them, then the input problems
    assert cli_said == [*result.warnings, *result.report["input_problems"]]
    assert any("45.0°" in line for line in result.warnings)


def test_fleet_library_rows_match_the_cli_summary(
    flight_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = tmp_path / "flights"
    folder.mkdir()
    for name in ("a.h5", "b.h5"):
        (folder / name).write_bytes(flight_file.read_bytes())
    capsys.readouterr()
    assert main(["compensate", str(folder), "--method", "tl", "--out", str(tmp_path / "cli")]) == 0
    err = capsys.readouterr().err
    result, issued = _library(am.fleet, folder, tmp_path / "lib", method="tl")
    said = [line.replace(": warning: ", ": ", 1) for line in err.splitlines()]
    assert [line.removeprefix("aeromag compensate: ") for line in said] == list(result.warnings)
    assert issued == list(result.warnings) and result.warnings  # the input problems
    assert result.failed == 0 and [row["output"] for row in result.rows] == ["a", "b"]
    cli_csv = (tmp_path / "cli" / "fleet.csv").read_bytes()
    assert (tmp_path / "lib" / "fleet.csv").read_bytes() == cli_csv
    for name in ("a", "b"):
        assert (tmp_path / "lib" / name / "report.json").read_bytes() == (
            tmp_path / "cli" / name / "report.json"
        ).read_bytes()


def test_compensate_vector_warns_about_a_rotated_fluxgate(delivered: Flight) -> None:
    """Sensor axes taken for body axes 45° off: a warning naming the angle and the fix."""
    with pytest.warns(AeromagWarning, match=r"45\.0° from .* pass mount=") as caught:
        comp = am.compensate_vector(delivered, "lsq")
    assert len(caught) == 1 and caught[0].filename == __file__  # the caller's line
    assert am.score(delivered, comp)["compensation_rmse_nt"] > 1000.0  # why it warns


def test_compensate_vector_is_quiet_on_an_aligned_fluxgate() -> None:
    flight = simulated("nominal", 5)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        am.compensate_vector(flight, "lsq")
    assert not [w for w in caught if issubclass(w.category, AeromagWarning)]
