"""Ctrl-C and rerunning, as a user at a terminal meets them.

A command runs as a terminal job: the leader of its own process group, SIGINT at Python's
default. Ctrl-C is SIGINT to that whole group: the command ends with its one line on stderr and
exit status 130, and no process of it prints a traceback. Rerunning an interrupted ``aeromag
train`` with the same command finishes it: the run ends at the requested total of environment
steps (not that many more), and a finished run says so and trains nothing.

The runs use a small copy of the shipped ``nonstationary`` entry (two environments, 64-step
rollouts, a validation and checkpoint every 256 steps on one flight, no pretraining), so that a
run is a few seconds of training after its imports.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from tests._helpers import ROOT, SHIPPED

pytestmark = pytest.mark.slow

#: ``aeromag`` as a terminal starts it: SIGINT raises KeyboardInterrupt (a test runner started
#: in the background may have it ignored, and a child inherits that).
AEROMAG = (
    "import signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); "
    "from aeromag_env.cli.main import main; sys.exit(main(sys.argv[1:]))"
)
#: What the command line says on Ctrl-C (``aeromag_env.cli.main``).
INTERRUPTED = "aeromag train: interrupted; no output was left half-written\n"
#: Environment steps between the small runs' validations and checkpoints.
EVAL_EVERY = 256
#: How long a condition is waited for [s]: imports, and a loaded 2-core machine.
PATIENCE_S = 600.0


def small_hyperparams(folder: Path, *, prefetch: bool) -> Path:
    """The shipped ``nonstationary`` entry at a test's size, as a hyperparameter file."""
    shipped = json.loads(SHIPPED["hyperparams"].read_text(encoding="utf-8"))
    entry = dict(shipped["scenarios"]["nonstationary"])
    entry.pop("pretrain", None)
    entry.update(
        n_envs=2,
        n_steps=64,
        batch_size=64,
        n_epochs=1,
        eval_every=EVAL_EVERY,
        eval_episodes=1,
        prefetch=prefetch,
    )
    path = folder / f"small_{'prefetch' if prefetch else 'serial'}.json"
    table = {"version": shipped["version"], "scenarios": {"nonstationary": entry}}
    path.write_text(json.dumps(table), encoding="utf-8")
    return path


def start(argv: list[str], cwd: Path) -> subprocess.Popen[str]:
    """``aeromag ARGV`` as a terminal job (its own process group)."""
    return subprocess.Popen(
        [sys.executable, "-c", AEROMAG, *argv],
        cwd=cwd,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )


def run(argv: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    """``aeromag ARGV`` to its end."""
    proc = start(argv, cwd)
    out, err = proc.communicate(timeout=PATIENCE_S)
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err)


def wait_for(condition: Callable[[], bool], proc: subprocess.Popen[str]) -> None:
    """Poll ``condition`` while ``proc`` runs; fail if it ends first or takes too long."""
    deadline = time.monotonic() + PATIENCE_S
    while not condition():
        if proc.poll() is not None:
            pytest.fail(f"ended before the condition held: {proc.communicate()}")
        if time.monotonic() > deadline:
            proc.kill()
            pytest.fail("the condition never held")
        time.sleep(0.2)


def children(pid: int) -> list[int]:
    """The child processes of ``pid`` (Linux's /proc)."""
    path = Path(f"/proc/{pid}/task/{pid}/children")
    return [int(c) for c in path.read_text().split()] if path.exists() else []


def alive(pid: int) -> bool:
    """Whether process ``pid`` exists and is no zombie."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0] != "Z"
    except OSError:
        return False


def ctrl_c(proc: subprocess.Popen[str]) -> tuple[int, str, str]:
    """SIGINT to the job's process group, as a terminal's Ctrl-C; its status, stdout, stderr."""
    os.killpg(proc.pid, signal.SIGINT)
    out, err = proc.communicate(timeout=PATIENCE_S)
    return proc.returncode, out, err


def steps(run_folder: Path, name: str = "training.json") -> int:
    """The environment steps recorded in ``name`` (``curve.json``: its last point's)."""
    record = json.loads((run_folder / name).read_text(encoding="utf-8"))
    return int(record[-1]["timesteps"] if isinstance(record, list) else record["timesteps"])


def test_ctrl_c_during_train_quick_is_one_line_and_130(tmp_path: Path) -> None:
    """``aeromag train --quick`` interrupted in its PPO updates, after the pretraining's
    validation (a long ``--timesteps`` keeps it running)."""
    out = tmp_path / "quick"
    proc = start(
        ["train", "--quick", "--timesteps", "1000000", "--quiet", "--out", str(out)], tmp_path
    )
    wait_for(lambda: (out / "candidate.npz").exists() or (out / "policy.npz").exists(), proc)
    time.sleep(2.0)  # into PPO's rollouts
    status, stdout, stderr = ctrl_c(proc)
    assert (status, stderr, stdout) == (130, INTERRUPTED, "")


def test_ctrl_c_with_the_prefetching_worker_is_one_line_and_130(tmp_path: Path) -> None:
    """The batched environments' worker process simulating flights ahead is in the middle of
    its work: it prints nothing and ends with the command."""
    hp = small_hyperparams(tmp_path, prefetch=True)
    argv = ["train", "--timesteps", "1000000", "--hyperparams", str(hp), "--quiet"]
    proc = start([*argv, "--out", str(tmp_path / "run")], tmp_path)
    wait_for(lambda: bool(children(proc.pid)), proc)
    workers = children(proc.pid)
    time.sleep(3.0)  # the worker simulates the environments' next flights
    status, stdout, stderr = ctrl_c(proc)
    assert (status, stderr, stdout) == (130, INTERRUPTED, "")
    deadline = time.monotonic() + 30.0
    while any(alive(w) for w in workers) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not any(alive(w) for w in workers), "the prefetching worker outlived the command"


def test_an_interrupted_train_rerun_ends_at_the_requested_total(tmp_path: Path) -> None:
    total = 4 * EVAL_EVERY
    hp = small_hyperparams(tmp_path, prefetch=False)
    run_folder = tmp_path / "r1"
    argv = ["train", "--timesteps", str(total), "--hyperparams", str(hp), "--quiet"]
    argv += ["--out", str(run_folder)]
    proc = start(argv, tmp_path)
    wait_for(lambda: (run_folder / "checkpoint.zip").exists(), proc)
    status, _, stderr = ctrl_c(proc)
    assert (status, stderr) == (130, INTERRUPTED)
    interrupted_at = steps(run_folder, "curve.json")  # the checkpoint a rerun resumes from
    assert 0 < interrupted_at < total and not (run_folder / "training.json").exists()

    resumed = run(argv, tmp_path)
    assert resumed.returncode == 0, resumed.stderr
    assert steps(run_folder) == total  # the request, not interrupted_at + total
    assert steps(run_folder, "curve.json") == total
    record = (run_folder / "training.json").read_bytes()

    again = run(argv, tmp_path)
    assert again.returncode == 0, again.stderr
    assert again.stdout.startswith(f"already trained: {total} steps"), again.stdout
    assert (run_folder / "training.json").read_bytes() == record  # nothing trained or written

    other_seed = run([*argv, "--seed", "1"], tmp_path)
    assert other_seed.returncode == 2
    assert other_seed.stderr.count("\n") == 1
    assert "holds a training run of ppo on nonstationary, seed 0" in other_seed.stderr


def test_seeds_rerun_finish_to_the_new_total_and_skip_the_finished(tmp_path: Path) -> None:
    hp = small_hyperparams(tmp_path, prefetch=False)
    folder = tmp_path / "seeds"
    argv = ["train", "--seeds", "0-1", "--hyperparams", str(hp), "--quiet", "--out", str(folder)]
    first = run([*argv, "--timesteps", str(2 * EVAL_EVERY)], tmp_path)
    assert first.returncode == 0, first.stderr
    summary = (folder / "seeds.json").read_bytes()
    again = run([*argv, "--timesteps", str(2 * EVAL_EVERY)], tmp_path)
    assert again.returncode == 0, again.stderr
    assert "already trained to the request's total: seed(s) 0, 1" in again.stdout
    assert (folder / "seeds.json").read_bytes() == summary
    longer = run([*argv, "--timesteps", str(3 * EVAL_EVERY)], tmp_path)
    assert longer.returncode == 0, longer.stderr
    assert [steps(folder / f"seed_{k}") for k in (0, 1)] == [3 * EVAL_EVERY] * 2
    rows = json.loads((folder / "seeds.json").read_text(encoding="utf-8"))["seeds"]
    assert [r["timesteps"] for r in rows] == [3 * EVAL_EVERY] * 2
