"""Tasks, outcomes and the serial runner; :func:`runner` picks serial or Ray."""

from __future__ import annotations

import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

#: ``--ray`` without an address: start Ray on this machine with its cores.
LOCAL = "local"


@dataclass(frozen=True)
class Task:
    """One independent piece of work: ``fn(*args)``.

    ``fn`` must be a module-level function (a Ray worker imports it by name); ``label`` names
    the input in reports (a file, a policy and its seeds); ``num_cpus`` is what Ray reserves.
    """

    label: str
    fn: Callable[..., Any]
    args: tuple[Any, ...] = ()
    num_cpus: float = 1.0


@dataclass
class Outcome:
    """What became of a task: ``value``, or ``error`` (one line: type and message)."""

    label: str
    value: Any = None
    error: str | None = None
    #: times the task was started (more than 1: its worker died and Ray retried it); None:
    #: unknown (the Ray actor counting attempts died during the run)
    attempts: int | None = 1
    details: str = field(default="", repr=False)  # the traceback, for AEROMAG_DEBUG
    #: the exception itself (the task's own, also from a Ray worker), to re-raise unchanged
    exception: BaseException | None = field(default=None, repr=False)

    @property
    def ok(self) -> bool:
        return self.error is None


class Runner(Protocol):
    """Runs tasks; ``progress(outcome)`` is called as each one ends (any order)."""

    name: str
    #: labels of the tasks that were started more than once (their worker died), so far
    retried: list[str]
    #: False once a run lost its attempt counts: other tasks may have been retried too
    retries_known: bool

    def run(
        self, tasks: Sequence[Task], progress: Callable[[Outcome], None] | None = None
    ) -> list[Outcome]: ...


def one_line(e: BaseException) -> str:
    """``Type: message`` on one line."""
    text = " ".join(str(e).split())
    return f"{type(e).__name__}: {text}" if text else type(e).__name__


class SerialRunner:
    """This process, one task after another (the default; nothing imports Ray)."""

    name = "serial"
    #: labels of the tasks run again after their worker died (never, here)
    retried: list[str] = []  # noqa: RUF012  (always empty)
    retries_known = True

    def __enter__(self) -> SerialRunner:
        return self

    def __exit__(self, *exc: object) -> None:
        return None

    def run(
        self, tasks: Sequence[Task], progress: Callable[[Outcome], None] | None = None
    ) -> list[Outcome]:
        outcomes = []
        for task in tasks:
            try:
                outcome = Outcome(task.label, value=task.fn(*task.args))
            except Exception as e:  # reported with its input; the other tasks go on
                outcome = Outcome(
                    task.label, error=one_line(e), details=traceback.format_exc(), exception=e
                )
            outcomes.append(outcome)
            if progress is not None:
                progress(outcome)
        return outcomes


def retry_note(runner: Runner) -> str | None:
    """One line on the tasks run again after their Ray worker died, or on retries that are
    unknown because the attempt counts were lost; None when there is nothing to say."""
    notes = []
    if runner.retried:
        notes.append(
            f"{len(runner.retried)} task(s) ran again after their Ray worker died (same "
            f"results): {'; '.join(runner.retried)}"
        )
    if not runner.retries_known:
        notes.append(
            "retries unknown: the Ray actor counting task attempts died during the run (the "
            "results are complete)"
        )
    return "; ".join(notes) or None


def failures(outcomes: Sequence[Outcome]) -> list[Outcome]:
    """The outcomes that ended in an error."""
    return [o for o in outcomes if not o.ok]
