"""The benchmark of ``aeromag discover`` as a user runs it (fresh processes), and what it shows:
peak memory that grows linearly with the flight."""

from __future__ import annotations

import json
import runpy
import sys
from pathlib import Path

import pytest

from aeromag_env.errors import AeromagError
from aeromag_env.jobs.bench import discover_cli as bench_discover
from aeromag_env.jobs.bench.discover_cli import bench_discover_cli
from tests._helpers import ROOT, assert_one_line_error


@pytest.mark.parametrize(
    ("hours", "repeats", "word"), [((1.0,), 0, "repeats"), ((0.1,), 1, "hours"), ((), 1, "hours")]
)
def test_bad_arguments_are_one_line_errors(
    hours: tuple[float, ...], repeats: int, word: str
) -> None:
    with pytest.raises(AeromagError) as err:
        bench_discover_cli(hours, repeats)
    assert_one_line_error(err, word)


def test_a_failing_run_says_its_last_line(tmp_path: Path) -> None:
    (tmp_path / "flight.h5").write_text("not a flight")
    with pytest.raises(AeromagError) as err:
        bench_discover._run(tmp_path / "flight.h5", tmp_path / "out")
    assert_one_line_error(err, "aeromag discover failed in the benchmark")


@pytest.mark.slow
def test_the_script_reports_a_quick_run(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    script = ROOT / "benchmarks" / "discover_cli.py"
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(sys, "argv", [str(script), "--quick", "--out", str(tmp_path / "f.json")])
        with pytest.raises(SystemExit) as done:
            runpy.run_path(str(script), run_name="__main__")
    assert done.value.code == 0
    figures = json.loads((tmp_path / "f.json").read_text())
    assert figures == json.loads(capsys.readouterr().out)
    assert figures["discover_cli_0.5h_s_per_flight_hour"] > 0
    assert 100 < figures["discover_cli_0.5h_peak_mb"] < 4000  # a Python process with numpy


@pytest.mark.slow
def test_peak_memory_grows_linearly_with_the_flight() -> None:
    """Peak resident memory of fresh ``aeromag discover`` processes on 0.5-, 1- and 2-hour
    flights: the second flight-hour adds at most 2.5 times what the second half hour did
    (linear growth: twice; with the external field's splines dense, which grow with the flight,
    memory grew with its square: four times), plus 40 MB for the resident set's noise."""
    figures = bench_discover_cli((0.5, 1.0, 2.0), repeats=1)
    half, one, two = (figures[f"discover_cli_{h}h_peak_mb"] for h in ("0.5", "1", "2"))
    assert half < one < two
    assert two - one <= 2.5 * (one - half) + 40.0, (half, one, two)
