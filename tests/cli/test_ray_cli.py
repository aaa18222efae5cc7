"""``--ray`` on evaluate and train: the same results as the serial run, bit for bit; a worker
killed mid-run is retried and every episode still arrives, and so do they all when the worker
keeping the attempt counts is killed; a second Ray node joins by address.

All marked ``ray`` (``pytest -m ray``, its own step in ``.ci/run``)."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from aeromag_env.cli.main import main

pytestmark = pytest.mark.ray

EVALUATE = ["evaluate", "--policies", "constant,fis,tuned_constant,privileged", "--quiet"]
#: How long a Ray worker must have been running tasks before the test may kill it [s].
WARM_S = 2.0
#: the aeromag command of this interpreter's environment
AEROMAG = [
    sys.executable,
    "-c",
    "import sys; from aeromag_env.cli.main import main; sys.exit(main(sys.argv[1:]))",
]


def test_evaluate_on_ray_equals_serial_bit_for_bit(local_ray: None, tmp_path: Path) -> None:
    args = [*EVALUATE, "--scenario", "nominal,nonstationary", "--episodes", "10"]
    assert main([*args, "--out", str(tmp_path / "serial")]) == 0
    assert main([*args, "--out", str(tmp_path / "ray"), "--ray"]) == 0
    for scenario in ("nominal", "nonstationary"):
        serial = (tmp_path / "serial" / scenario / "results.json").read_bytes()
        assert (tmp_path / "ray" / scenario / "results.json").read_bytes() == serial
        assert len(json.loads(serial)["policies"]["fis"]["rmse_nt"]) == 10


def test_train_seeds_on_ray_equal_serial(local_ray: None, tmp_path: Path, capsys) -> None:
    base = ["train", "--seeds", "0-1", "--quick", "--quiet"]
    args = [*base, "--timesteps", "512"]
    assert main([*args, "--out", str(tmp_path / "serial")]) == 0
    assert main([*args, "--out", str(tmp_path / "ray"), "--ray"]) == 0
    for seed in (0, 1):
        policy = f"seed_{seed}/policy.npz"
        assert (tmp_path / "ray" / policy).read_bytes() == (
            tmp_path / "serial" / policy
        ).read_bytes()
        assert (tmp_path / "ray" / f"seed_{seed}" / "checkpoint.zip").exists()
    on_ray = json.loads((tmp_path / "ray" / "seeds.json").read_text())
    assert on_ray["runner"] == "ray" and [r["seed"] for r in on_ray["seeds"]] == [0, 1]
    serial = json.loads((tmp_path / "serial" / "seeds.json").read_text())
    assert [r["best_validation_rmse_nt"] for r in on_ray["seeds"]] == [
        r["best_validation_rmse_nt"] for r in serial["seeds"]
    ]
    # resumable: a rerun continues each seed from its checkpoint
    assert main([*base, "--timesteps", "1024", "--out", str(tmp_path / "ray"), "--ray"]) == 0
    again = json.loads((tmp_path / "ray" / "seeds.json").read_text())
    assert [r["timesteps"] for r in again["seeds"]] == [1024, 1024]


def _descendants(pid: int) -> dict[int, str]:
    """pid → command line of every process below ``pid`` (from /proc)."""
    children: dict[int, list[int]] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                ppid = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            children.setdefault(ppid, []).append(int(entry.name))
    out, todo = {}, [pid]
    while todo:
        for child in children.get(todo.pop(), []):
            try:
                out[child] = (
                    (Path("/proc") / str(child) / "cmdline").read_bytes().decode(errors="replace")
                )
            except OSError:
                continue
            todo.append(child)
    return out


def _cpu_ticks(pid: int) -> int:
    """CPU time [clock ticks] of ``pid`` so far (utime + stime), -1 if it is gone."""
    try:
        fields = (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return -1
    return int(fields[11]) + int(fields[12])


def test_a_killed_worker_is_retried_and_every_episode_arrives(tmp_path: Path) -> None:
    """``aeromag evaluate --ray`` in its own process with its own local Ray; one of its task
    workers is killed (SIGKILL) while it runs; the run completes, says so, and its results equal
    the serial run's."""
    args = [*EVALUATE, "--scenario", "nonstationary", "--episodes", "48"]
    env = {**os.environ, "RAY_DEDUP_LOGS": "0"}
    cmd = [*AEROMAG, *args, "--out", str(tmp_path / "ray"), "--ray"]
    run = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    killed, before, deadline = None, {}, time.monotonic() + 120
    streak: dict[int, int] = {}  # polls in a row each worker was seen computing a task
    first: dict[int, float] = {}  # when each worker was first seen running a task
    while killed is None and run.poll() is None and time.monotonic() < deadline:
        busy = {
            p: _cpu_ticks(p)
            for p, cmd in _descendants(run.pid).items()
            if cmd.startswith("ray::aeromag_task")
        }
        now = time.monotonic()
        first.update({p: now for p in busy if p not in first})
        streak = {p: streak.get(p, 0) + 1 for p, t in busy.items() if p in before and t > before[p]}
        # computing for 3 polls in a row and WARM_S after its first task began: past the first
        # instants of a task, in which it records its attempt (a worker killed before that is
        # retried without being counted), and, likely the cause of the failures, past a fresh
        # worker's first imports, which may keep it busy under the task's name before the
        # record (with the 3 polls alone a CI run of 2026-11-26 still killed a worker there,
        # and the run said nothing of the retry)
        ready = [p for p, n in streak.items() if n >= 3 and now - first[p] >= WARM_S]
        for pid in ready[:1]:
            os.kill(pid, signal.SIGKILL)
            killed = pid
        before = busy
        time.sleep(0.1)
    _, err = run.communicate(timeout=300)
    assert killed is not None, "no task worker seen running"
    assert run.returncode == 0, err
    assert "ran again after their Ray worker died" in err
    assert main([*args, "--out", str(tmp_path / "serial")]) == 0
    ray_results = json.loads((tmp_path / "ray" / "results.json").read_text())
    serial = json.loads((tmp_path / "serial" / "results.json").read_text())
    assert ray_results == serial
    assert all(len(p["rmse_nt"]) == 48 for p in ray_results["policies"].values())


def test_a_killed_attempt_log_loses_only_the_retry_count(tmp_path: Path) -> None:
    """``aeromag evaluate --ray`` in its own process; the worker hosting the attempt log
    (``ray::AttemptLog``) is killed (SIGKILL) while a task runs: the run completes, says its
    retries are unknown, and its results equal the serial run's."""
    args = [*EVALUATE, "--scenario", "nonstationary", "--episodes", "16"]  # 8 tasks
    cmd = [*AEROMAG, *args, "--out", str(tmp_path / "ray"), "--ray"]
    run = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    killed, deadline = None, time.monotonic() + 120
    while killed is None and run.poll() is None and time.monotonic() < deadline:
        workers = _descendants(run.pid)
        busy = [p for p, c in workers.items() if c.startswith("ray::aeromag_task")]
        logs = [p for p, c in workers.items() if c.startswith("ray::AttemptLog")]
        if busy and logs:  # a task running: the run has not yet asked the log for its counts
            os.kill(logs[0], signal.SIGKILL)
            killed = logs[0]
        time.sleep(0.1)
    _, err = run.communicate(timeout=600)
    assert killed is not None, "no attempt log seen while a task ran"
    assert run.returncode == 0, err
    assert "aeromag evaluate: retries unknown" in err and "internal error" not in err
    assert main([*args, "--out", str(tmp_path / "serial")]) == 0
    ray_results = json.loads((tmp_path / "ray" / "results.json").read_text())
    serial = json.loads((tmp_path / "serial" / "results.json").read_text())
    assert ray_results == serial
    assert all(len(p["rmse_nt"]) == 16 for p in ray_results["policies"].values())


@pytest.fixture
def two_node_cluster():
    """A Ray head with 1 CPU and a second node with 1 CPU on this machine (``ray start``), each
    in a process group of its own, which the teardown kills: ``ray stop`` would stop every Ray
    on the machine, the ``local_ray`` of this test session's process included."""
    ray = str(Path(sys.executable).with_name("ray"))
    port = "6390"
    env = {**os.environ, "RAY_AUTH_MODE": "token"}  # the head's default; a node must match it
    common = ["--node-ip-address=127.0.0.1", "--num-cpus=1", "--disable-usage-stats"]
    groups = []

    def start(*args: str) -> None:
        cmd = [ray, "start", *args, *common]
        run = subprocess.Popen(
            cmd,
            env=env,
            start_new_session=True,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
        )
        groups.append(run.pid)  # the daemons it leaves behind keep its process group
        assert run.wait(timeout=120) == 0, run.stderr.read() if run.stderr else ""

    try:
        start("--head", f"--port={port}", "--include-dashboard=false")
        start(f"--address=127.0.0.1:{port}")
        yield f"127.0.0.1:{port}", env
    finally:
        for group in groups:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(group, signal.SIGKILL)


def test_evaluate_joins_a_two_node_cluster(two_node_cluster, tmp_path: Path) -> None:
    address, env = two_node_cluster
    nodes = subprocess.run(
        [
            sys.executable,
            "-c",
            "import ray; ray.init(address='" + address + "', "
            "logging_level='ERROR'); print(sum(n['Alive'] for n in ray.nodes()), "
            "int(ray.cluster_resources()['CPU']))",
        ],
        capture_output=True,
        text=True,
        env=env,
        check=True,
    )
    assert nodes.stdout.split() == ["2", "2"]
    args = [*EVALUATE, "--scenario", "nonstationary", "--episodes", "16"]
    run = subprocess.run(
        [*AEROMAG, *args, "--out", str(tmp_path / "ray"), "--ray", address],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert run.returncode == 0, run.stderr
    assert main([*args, "--out", str(tmp_path / "serial")]) == 0
    got = json.loads((tmp_path / "ray" / "results.json").read_text())
    want = json.loads((tmp_path / "serial" / "results.json").read_text())
    assert got == want
    assert np.isfinite(got["policies"]["fis"]["rmse_nt_mean"])


def test_bad_ray_address_is_one_line(tmp_path: Path) -> None:
    cmd = [*AEROMAG, *EVALUATE, "--episodes", "2", "--out", str(tmp_path), "--ray", "127.0.0.1:1"]
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert run.returncode == 2
    assert (
        run.stderr.count("\n") == 1
        and "cannot join Ray at 127.0.0.1:1: Connection refused" in run.stderr
    )


def test_bench_measures_evaluate_on_ray(local_ray: None, tmp_path: Path, capsys) -> None:
    assert main(["bench", "--only", "ray", "--ray", "--quick", "--out", str(tmp_path)]) == 0
    f = json.loads((tmp_path / "bench.json").read_text())["figures"]
    assert f["ray_results_identical"] is True and f["ray_cpus"] == 2
    assert f["ray_evaluate_speedup"] > 0 and f["ray_task_overhead_ms"] > 0
    assert "evaluate 16 flights × 6 policies, Ray, 2 CPUs" in capsys.readouterr().out


def test_bench_only_ray_needs_ray(tmp_path: Path, capsys) -> None:
    assert main(["bench", "--only", "ray", "--out", str(tmp_path)]) == 2
    assert (
        capsys.readouterr().err
        == "aeromag bench: error: --ray is needed to measure the Ray figures\n"
    )


def test_a_task_that_raises_is_reported_with_its_input(
    local_ray: None, tmp_path: Path, capsys
) -> None:
    bad = tmp_path / "bad.npz"
    bad.write_text("not a policy")
    args = ["evaluate", "--policies", f"fis,ppo:{bad}", "--episodes", "2", "--quiet"]
    errors = []
    for extra in ([], ["--ray"]):
        assert main([*args, "--out", str(tmp_path / "out"), *extra]) == 2
        errors.append(capsys.readouterr().err)
    assert errors[0] == errors[1]  # the same one line, here or on Ray
    assert errors[0].count("\n") == 1
    assert f"nominal/ppo:{bad} seeds 100000–100001: cannot load policy" in errors[0]
    assert not (tmp_path / "out" / "results.json").exists()
