"""The task runners: serial and Ray give the same outcomes, in task order; a raising task is
reported with its input while the rest complete; nothing imports Ray without --ray."""

from __future__ import annotations

import subprocess
import sys

import pytest

from aeromag_env.parallel import SerialRunner, Task, failures, runner


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
