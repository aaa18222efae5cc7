"""Fleets of flight files (``aeromag compensate|discover DIR_OR_GLOB``): one output set per
flight, the same as the one-file command's; a summary in fleet.csv / fleet.png; a broken file
reported with its name while the rest complete (exit 2); nothing half-written; stem collisions
kept apart; serial and Ray agree."""

from __future__ import annotations

import csv
import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from aeromag_env.cli.main import main
from aeromag_env.discovery.suite import base_config
from aeromag_env.flight.files import write_flight
from aeromag_env.jobs.fleet import output_names
from aeromag_env.simulation.simulate import simulate_flight

#: 600 s flights: the shortest discover accepts with its default held-out scheme (300 s of
#: calibration data at least), and a fraction of a second each to compensate.
DURATION_S = 600.0
GOOD = ("alpha.h5", "bravo.h5", "charlie.csv")  # charlie: HDF5 content behind a .csv suffix
BROKEN = "broken.h5"  # text, not HDF5
#: The columns that depend on how the run went, not on the flight.
RUN_COLUMNS = ("attempts",)


@pytest.fixture(scope="module")
def fleet_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Three small simulated flights, a broken one, and files a fleet must not read."""
    folder = tmp_path_factory.mktemp("fleet")
    for seed, name in enumerate(GOOD, start=1):
        path = write_flight(simulate_flight(base_config(DURATION_S), seed), folder / "tmp.h5")
        path.rename(folder / name)  # the reader warns about charlie's suffix
    (folder / BROKEN).write_text("not a flight\n")
    (folder / "notes.txt").write_text("not a flight either\n")
    shutil.copy(folder / GOOD[0], folder / ".hidden.h5")
    return folder


def _rows(out: Path) -> list[dict[str, str]]:
    with open(out / "fleet.csv", newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def _report(folder: Path) -> dict:
    return json.loads((folder / "report.json").read_text(encoding="utf-8"))


def _leftovers(out: Path) -> list[Path]:
    """Temporary files and staging folders of atomic writes (their names start with a dot)."""
    return [p for p in out.rglob("*") if p.name.startswith(".")]


def _check_fleet_run(fleet_dir: Path, out: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """What every fleet run over ``fleet_dir`` gives: one folder per good flight, the broken one
    reported on stderr and in fleet.csv, the summary line, nothing half-written."""
    captured = capsys.readouterr()
    assert "1 of 4 flights failed" in captured.out
    errors = [line for line in captured.err.splitlines() if ": error: " in line]
    assert len(errors) == 1 and f"{fleet_dir / BROKEN}: error: " in errors[0]
    assert sorted(p.name for p in out.iterdir() if p.is_dir()) == ["alpha", "bravo", "charlie"]
    assert (out / "fleet.png").stat().st_size > 0
    rows = _rows(out)
    assert [(r["file"], r["output"], r["status"]) for r in rows] == [
        (str(fleet_dir / "alpha.h5"), "alpha", "ok"),
        (str(fleet_dir / "bravo.h5"), "bravo", "ok"),
        (str(fleet_dir / BROKEN), "broken", "error"),
        (str(fleet_dir / "charlie.csv"), "charlie", "ok"),
    ]
    broken = rows[2]
    assert broken["error"] and "\n" not in broken["error"] and broken["attempts"] == "1"
    charlie = rows[3]
    assert charlie["warnings"] == "1" and "as the suffix says" in charlie["warning_text"]
    assert f"{fleet_dir / 'charlie.csv'}: warning: " in captured.err
    assert not _leftovers(out)


@pytest.mark.slow
def test_compensate_fleet_writes_the_one_file_outputs_and_a_summary(
    fleet_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    assert main(["compensate", str(fleet_dir), "--method", "lsq", "--out", str(out)]) == 2
    _check_fleet_run(fleet_dir, out, capsys)
    for row in _rows(out):
        if row["status"] != "ok":
            continue
        single = tmp_path / "single" / row["output"]
        assert main(["compensate", row["file"], "--method", "lsq", "--out", str(single)]) == 0
        report = _report(single)
        assert _report(out / row["output"]) == report
        head = report["headline"]
        assert float(row["improvement_ratio"]) == pytest.approx(head["improvement_ratio"], 1e-5)
        assert float(row["std_compensated_nt"]) == pytest.approx(head["std_compensated_nt"], 1e-5)
        assert row["method"] == "lsq" and row["fom_nt"]  # the flights fly a calibration box
        assert sorted(p.name for p in (out / row["output"]).iterdir()) == sorted(
            p.name for p in single.iterdir()
        )


@pytest.mark.slow
def test_discover_fleet_writes_the_one_file_outputs_and_a_summary(
    fleet_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    assert main(["discover", str(fleet_dir / "*"), "--out", str(out), "--quiet"]) == 2
    _check_fleet_run(fleet_dir, out, capsys)
    for row in _rows(out):
        if row["status"] != "ok":
            continue
        single = tmp_path / "single" / row["output"]
        assert main(["discover", row["file"], "--out", str(single), "--quiet"]) == 0
        report = _report(single)
        assert _report(out / row["output"]) == report
        assert row["verdict"] == report["verdict"]
        assert float(row["gap_before_nt"]) == pytest.approx(report["gap"]["rms_before_nt"], 1e-5)
        assert row["named_effects"] == "; ".join(e["name"] for e in report["missing_effects"])


def test_a_rerun_into_the_input_folder_reads_only_the_flights(
    fleet_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """fleet.csv and OUT/*/compensated.h5 have flight suffixes; a second run never reads them."""
    folder = tmp_path / "flights"
    folder.mkdir()
    shutil.copy(fleet_dir / "alpha.h5", folder / "alpha.h5")
    for _ in range(2):
        assert main(["compensate", str(folder), "--method", "lsq", "--out", str(folder)]) == 0
        assert "0 of 1 flights failed" in capsys.readouterr().out
        assert [r["file"] for r in _rows(folder)] == [str(folder / "alpha.h5")]
    assert not _leftovers(folder)


def test_files_with_the_same_stem_get_their_own_folders(
    fleet_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    for sub in ("a", "b"):
        (tmp_path / sub).mkdir()
        shutil.copy(fleet_dir / "alpha.h5", tmp_path / sub / "flight.h5")
    shutil.copy(fleet_dir / "bravo.h5", tmp_path / "b" / "Flight-2.h5")
    out = tmp_path / "out"
    pattern = str(tmp_path / "**" / "*.h5")
    assert main(["compensate", pattern, "--method", "lsq", "--out", str(out)]) == 0
    rows = _rows(out)
    assert [(r["file"], r["output"]) for r in rows] == [
        (str(tmp_path / "a" / "flight.h5"), "flight"),
        (str(tmp_path / "b" / "Flight-2.h5"), "Flight-2"),
        (str(tmp_path / "b" / "flight.h5"), "flight-3"),  # flight-2 is taken, whatever the case
    ]
    for row in rows:
        assert _report(out / row["output"])["input"] == row["file"]


def test_output_names_never_take_a_summary_file_name() -> None:
    files = [Path("x/fleet.csv.h5"), Path("y/FLEET.CSV.mat"), Path("z/fleet.h5")]
    assert output_names(files) == ["fleet.csv-2", "FLEET.CSV-3", "fleet"]


@pytest.mark.parametrize("make", ["nothing", "empty folder", "no flight suffix"])
def test_a_fleet_without_flight_files_is_one_line_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], make: str
) -> None:
    arg = str(tmp_path / "none" / "*.h5")
    if make != "nothing":
        arg = str(tmp_path / "flights")
        Path(arg).mkdir()
        if make == "no flight suffix":
            (Path(arg) / "notes.txt").write_text("hello\n")
    assert main(["discover", arg, "--out", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "error: no flight files (.h5, .hdf5" in err
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_a_fleet_does_not_import_ray_without_the_flag(fleet_dir: Path, tmp_path: Path) -> None:
    pattern = str(fleet_dir / "[ab][lr][pa]*")  # alpha.h5, bravo.h5
    argv = ["compensate", pattern, "--method", "lsq", "--out", str(tmp_path)]
    code = f"import sys; from aeromag_env.cli.main import main; main({argv!r}); "
    code += "print('ray' in sys.modules)"
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert run.stdout.strip().splitlines()[-1] == "False"
    assert [r["output"] for r in _rows(tmp_path)] == ["alpha", "bravo"]


def _comparable(out: Path) -> list[dict[str, str]]:
    return [{k: v for k, v in r.items() if k not in RUN_COLUMNS} for r in _rows(out)]


@pytest.mark.ray
@pytest.mark.parametrize("command", ["compensate", "discover"])
def test_on_ray_a_fleet_gives_what_it_gives_here(
    local_ray: None,
    fleet_dir: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    command: str,
) -> None:
    extra = ["--method", "lsq"] if command == "compensate" else ["--quiet"]
    here, there = tmp_path / "serial", tmp_path / "ray"
    assert main([command, str(fleet_dir), "--out", str(here), *extra]) == 2
    capsys.readouterr()
    assert main([command, str(fleet_dir), "--out", str(there), "--ray", *extra]) == 2
    _check_fleet_run(fleet_dir, there, capsys)
    assert _comparable(there) == _comparable(here)
    assert [r["attempts"] for r in _rows(there)] == ["1"] * 4  # nothing died, nothing retried
    for row in _rows(here):
        if row["status"] == "ok":
            assert _report(there / row["output"]) == _report(here / row["output"])
