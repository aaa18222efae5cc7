"""The task runners: serial and Ray give the same outcomes, in task order; a raising task is
reported with its input while the rest complete; nothing imports Ray without --ray."""

from __future__ import annotations

import subprocess
import sys
import time

import pytest

from aeromag_env.parallel import Outcome, SerialRunner, Task, failures, retry_note, runner


def square(x: int) -> int:
    if x == 3:
        raise ValueError(f"three is\nbad ({x})")
    return x * x


TASKS = [Task(f"x={i}", square, (i,)) for i in range(6)]


def test_serial_runner_reports_a_raising_task_and_completes_the_rest() -> None:
    seen: list[str] = []
    with runner(None) as r:
        assert isinstance(r, SerialRunner)
        out = r.run(TASKS, progress=lambda o: seen.append(o.label))
    assert [o.value for o in out if o.ok] == [0, 1, 4, 16, 25]
    (bad,) = failures(out)
    assert bad.label == "x=3" and bad.error == "ValueError: three is bad (3)"  # one line
    assert "Traceback" in bad.details
    assert seen == [t.label for t in TASKS]
    assert [o.attempts for o in out] == [1] * len(TASKS) and retry_note(r) is None


def test_nothing_imports_ray_without_the_flag() -> None:
    code = (
        "import sys; from aeromag_env.cli.main import main; import aeromag_env.parallel as p;"
        "r = p.runner(None); r.run([]); print('ray' in sys.modules)"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert run.stdout.strip() == "False"


@pytest.mark.ray
def test_ray_runner_equals_serial_and_counts_attempts(local_ray: None) -> None:
    with runner("local") as r:
        assert r.name == "ray" and r.cpus == 2
        progress: list[str] = []
        out = r.run(TASKS, progress=lambda o: progress.append(o.label))
        again = r.run(TASKS)  # a second run on the same runner counts its attempts afresh
        assert [o.attempts for o in again] == [1] * len(TASKS) and r.retried == []
    serial = SerialRunner().run(TASKS)
    assert [(o.label, o.value, o.error) for o in out] == [
        (o.label, o.value, o.error) for o in serial
    ]
    assert sorted(progress) == sorted(t.label for t in TASKS)
    assert [o.attempts for o in out] == [1] * len(TASKS)  # nothing died, nothing retried


def slow_square(x: int) -> int:
    time.sleep(0.3)  # long enough that tasks still start after the attempt log was killed
    return x * x


@pytest.mark.ray
@pytest.mark.parametrize("restart", [True, False], ids=["restarted", "gone"])
def test_losing_the_attempt_log_loses_only_the_attempt_counts(
    local_ray: None, restart: bool
) -> None:
    """The attempt log killed after the first task ended, restarted by Ray or gone for good:
    every task still gives its value, the run's attempts are unknown, and the next run on the
    same runner counts them again."""
    import ray

    tasks = [Task(f"x={i}", slow_square, (i,)) for i in range(8)]
    with runner("local") as r:
        killed: list[str] = []

        def kill_log_once(outcome: Outcome) -> None:
            if not killed:
                killed.append(outcome.label)
                ray.kill(r._log, no_restart=not restart)

        out = r.run(tasks, progress=kill_log_once)
        assert [o.value for o in out] == [i * i for i in range(8)] and not failures(out)
        assert [o.attempts for o in out] == [None] * 8
        assert not r.retries_known and r.retried == []
        note = retry_note(r)
        assert note is not None and note.startswith("retries unknown")
        again = r.run(tasks)
        assert [o.attempts for o in again] == [1] * 8 and [o.value for o in again] == [
            o.value for o in out
        ]
