"""Output sets written as sets (issue 20): a refusal before anything is written, the old set
or the new one after an exception or a kill -9, no temporary files left behind by the next run.
"""

from __future__ import annotations

import hashlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from aeromag_env.atomic import (
    COMMIT_MARK,
    STAGE_PREFIX,
    atomic_path,
    check_output_set,
    output_set,
    recover,
)
from aeromag_env.cli.main import main
from aeromag_env.errors import AeromagError
from aeromag_env.flight.files import write_flight
from aeromag_env.jobs.compensate import OUTPUTS as COMPENSATE_OUTPUTS
from tests._flights import simulated

NAMES = ("a.h5", "b.json", "c.png")


def _digest(folder: Path, visible: bool = False) -> dict[str, str]:
    """Every entry of ``folder`` (``visible``: but the staging folders) with its bytes' hash."""
    return {
        p.name: hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "<dir>"
        for p in sorted(folder.iterdir())
        if not (visible and p.name.startswith(STAGE_PREFIX))
    }


def _write_set(folder: Path, text: str) -> None:
    with output_set(folder, NAMES) as stage:
        for name in NAMES:
            (stage / name).write_text(f"{text} {name}")


def test_a_set_replaces_the_old_one_and_leaves_nothing_else(tmp_path: Path) -> None:
    _write_set(tmp_path, "old")
    _write_set(tmp_path, "new")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(NAMES)
    assert all((tmp_path / n).read_text() == f"new {n}" for n in NAMES)


def test_an_exception_while_writing_keeps_the_old_set(tmp_path: Path) -> None:
    _write_set(tmp_path, "old")
    before = _digest(tmp_path)
    with pytest.raises(RuntimeError), output_set(tmp_path, NAMES) as stage:
        (stage / NAMES[0]).write_text("new")
        raise RuntimeError("the plot failed")
    assert _digest(tmp_path) == before


def test_a_set_missing_a_file_replaces_nothing(tmp_path: Path) -> None:
    _write_set(tmp_path, "old")
    before = _digest(tmp_path)
    with pytest.raises(AeromagError, match=r"lacks c\.png"), output_set(tmp_path, NAMES) as stage:
        (stage / NAMES[0]).write_text("new")
        (stage / NAMES[1]).write_text("new")
    assert _digest(tmp_path) == before


@pytest.mark.parametrize("hazard", ["same", "symlink", "hardlink"])
def test_an_input_named_like_an_output_is_refused_before_anything_is_written(
    tmp_path: Path, hazard: str
) -> None:
    source = tmp_path / "input.png"
    source.write_bytes(b"the user's picture")
    out = tmp_path / "out"
    out.mkdir()
    if hazard == "same":
        source = out / "c.png"
        source.write_bytes(b"the user's picture")
    elif hazard == "symlink":
        (out / "c.png").symlink_to(source)
    else:
        os.link(source, out / "c.png")
    before = _digest(out)
    with (
        pytest.raises(AeromagError, match="is the input file"),
        output_set(out, NAMES, inputs=[source]),
    ):
        raise AssertionError("the block must not run")
    assert _digest(out) == before
    assert source.read_bytes() == b"the user's picture"


def test_an_out_that_is_a_file_or_holds_a_folder_of_an_output_name_is_refused(
    tmp_path: Path,
) -> None:
    (tmp_path / "file").write_text("x")
    with pytest.raises(AeromagError, match="is a file, not a folder"):
        check_output_set(tmp_path / "file", NAMES)
    (tmp_path / "out" / "b.json").mkdir(parents=True)
    with pytest.raises(AeromagError, match="is a folder"):
        check_output_set(tmp_path / "out", NAMES)


def test_a_refused_set_does_not_create_the_folder(tmp_path: Path) -> None:
    out = tmp_path / "new"
    with pytest.raises(RuntimeError), output_set(out, NAMES):
        raise RuntimeError("failed before writing")
    assert not out.exists()


_KILL_DURING_COMMIT = """
import os, sys
from pathlib import Path
import aeromag_env.atomic as atomic
real = os.replace
def replace(src, dst):
    real(src, dst)
    if atomic.STAGE_PREFIX in str(src) and atomic.STAGE_PREFIX not in str(dst):
        os._exit(9)  # killed after the first file of the set is in place
atomic.os.replace = replace
names = ("a.h5", "b.json", "c.png")
with atomic.output_set(Path(sys.argv[1]), names) as stage:
    for name in names:
        (stage / name).write_text(f"new {name}")
"""


def test_a_kill_during_the_renames_is_completed_by_the_next_run(tmp_path: Path) -> None:
    _write_set(tmp_path, "old")
    res = subprocess.run([sys.executable, "-c", _KILL_DURING_COMMIT, str(tmp_path)], check=False)
    assert res.returncode == 9
    stages = list(tmp_path.glob(f"{STAGE_PREFIX}*"))
    assert len(stages) == 1 and (stages[0] / COMMIT_MARK).exists()
    placed = recover(tmp_path)
    assert len(placed) == len(NAMES) - 1
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(NAMES)
    assert all((tmp_path / n).read_text() == f"new {n}" for n in NAMES)


def test_stale_temporaries_of_dead_writers_are_removed_and_live_ones_kept(tmp_path: Path) -> None:
    dead = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"],
        capture_output=True,
        text=True,
        check=True,
    )
    pid = int(dead.stdout)
    stale_file = tmp_path / f".x.json.tmp-{pid}-abc"
    stale_stage = tmp_path / f"{STAGE_PREFIX}{pid}-abc"
    live_stage = tmp_path / f"{STAGE_PREFIX}{os.getppid()}-abc"
    stale_file.write_text("partial")
    for stage in (stale_stage, live_stage):
        stage.mkdir()
        (stage / "a.h5").write_text("partial")
    with atomic_path(tmp_path / "x.json") as tmp:
        tmp.write_text("{}")
    assert not stale_file.exists()
    recover(tmp_path)
    assert not stale_stage.exists() and live_stage.exists()


# ----------------------------------------------------------------------- kill -9 of the CLI


def _start(argv: list[str], cwd: Path) -> subprocess.Popen:
    code = "import sys; from aeromag_env.cli.main import main; sys.exit(main(sys.argv[1:]))"
    return subprocess.Popen(
        [sys.executable, "-c", code, *argv],
        cwd=cwd,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )


def _timed_run(argv: list[str], cwd: Path) -> float:
    t0 = time.perf_counter()
    assert _start(argv, cwd).wait() == 0
    return time.perf_counter() - t0


def _kill_at(argv: list[str], cwd: Path, delay_s: float) -> None:
    proc = _start(argv, cwd)
    time.sleep(delay_s)
    proc.send_signal(signal.SIGKILL)
    proc.wait()


@pytest.fixture(scope="module")
def short_flight(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("kill") / "flight.h5"
    write_flight(simulated(trajectory__duration_s=600.0), path)
    return path


@pytest.mark.slow
def test_kill_9_during_compensate_leaves_the_old_set_or_the_new_one(
    tmp_path: Path, short_flight: Path
) -> None:
    out = tmp_path / "out"
    assert main(["compensate", str(short_flight), "--method", "lsq", "--out", str(out)]) == 0
    old = _digest(out)
    argv = ["compensate", str(short_flight), "--method", "kf", "--out", str(out)]
    seen = set()
    full = _timed_run(argv, tmp_path)  # the new set, to know how long a run takes
    new = _digest(out)
    assert set(new) == set(COMPENSATE_OUTPUTS)
    assert main(["compensate", str(short_flight), "--method", "lsq", "--out", str(out)]) == 0
    for fraction in (0.3, 0.6, 0.8, 0.9, 0.95, 1.0):
        _kill_at(argv, tmp_path, fraction * full)
        committed = any(out.glob(f"{STAGE_PREFIX}*/{COMMIT_MARK}"))
        visible = _digest(out, visible=True)
        assert committed or visible in (old, new) or _is_new_run(out), f"mixed at {fraction}"
        recover(out)  # what the next run into the folder does first
        now = _digest(out)
        assert now in (old, new) or _is_new_run(out), f"mixed set after a kill at {fraction}"
        seen.add("old" if now == old else "new")
        if now != old:  # back to the old set for the next kill
            assert (
                main(["compensate", str(short_flight), "--method", "lsq", "--out", str(out)]) == 0
            )
    assert "old" in seen  # a kill before the end must have hit the work, not the commit


def _is_new_run(out: Path) -> bool:
    """The set is complete and from a kf run (a new PNG can differ in its metadata)."""
    names = sorted(p.name for p in out.iterdir())
    report = json.loads((out / "report.json").read_text()) if "report.json" in names else {}
    return names == sorted(COMPENSATE_OUTPUTS) and report.get("method") == "kf"


@pytest.mark.slow
def test_kill_9_during_simulate_leaves_the_old_file_or_the_new_one(tmp_path: Path) -> None:
    out = tmp_path / "sim.h5"
    base = ["simulate", "--duration-s", "900", "--quiet", "--out", str(out)]
    assert main([*base, "--seed", "1"]) == 0
    old = out.read_bytes()
    full = _timed_run([*base, "--seed", "2"], tmp_path)
    new = out.read_bytes()
    assert main([*base, "--seed", "1"]) == 0
    for fraction in (0.5, 0.8, 0.95):
        _kill_at([*base, "--seed", "2"], tmp_path, fraction * full)
        assert out.read_bytes() in (old, new)
    # the next run removes what the killed ones left
    assert main([*base, "--seed", "1"]) == 0
    assert [p.name for p in tmp_path.iterdir()] == ["sim.h5"]


@pytest.mark.parametrize(
    ("command", "name"),
    [
        ("compensate", "compensation.png"),
        ("compensate", "report.json"),
        ("discover", "residual.png"),
    ],
)
def test_a_flight_file_named_like_an_output_in_out_is_refused_and_kept(
    tmp_path: Path, short_flight: Path, command: str, name: str, capsys: pytest.CaptureFixture
) -> None:
    """Before issue 20 the PNG writers skipped the input check: the plot replaced the input."""
    out = tmp_path / "out"
    out.mkdir()
    source = out / name  # formats are found from the content, so this is a readable flight
    source.write_bytes(short_flight.read_bytes())
    before = _digest(out)
    method = ["--method", "lsq"] if command == "compensate" else []
    assert main([command, str(source), *method, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "is the input file" in err
    assert _digest(out) == before
