"""Tasks on Ray: started on this machine (``--ray``) or on a cluster (``--ray ADDRESS``).

Each task is a Ray task reserving ``Task.num_cpus``; a task whose worker dies (killed, out of
memory, node lost) is retried up to :data:`MAX_RETRIES` times by Ray; a task that raises is not
retried (the same input would raise again) and is reported with its label. Attempts are counted
by a small actor, so a summary can say which tasks were retried. That count is bookkeeping: when
the actor's worker dies, Ray restarts the actor, the tasks go on without it, and the run's
attempts become unknown (``Outcome.attempts`` None) instead of the run failing. The workers import
this package by name: on a cluster it must be installed on every node (README, "Running on a
cluster").
"""

from __future__ import annotations

import contextlib
import logging
import pickle
import socket
import traceback
from collections.abc import Callable, Sequence
from typing import Any, cast

from aeromag_env.errors import AeromagError
from aeromag_env.parallel.tasks import Outcome, Task, one_line
from aeromag_env.threads import cores

#: Ray restarts a task whose worker died at most this many times.
MAX_RETRIES = 3
#: How long to wait for a cluster's address to answer before giving up [s].
CONNECT_TIMEOUT_S = 10.0
#: How long a task or the driver waits on the attempt log (while Ray restarts it, say) before
#: going on without it [s].
LOG_TIMEOUT_S = 10.0


def _import_ray() -> Any:
    try:
        import ray
    except ImportError:
        raise AeromagError("--ray needs the ray extra: pip install 'aeromag-env[ray]'") from None
    return ray


class RayRunner:
    """Ray tasks; joins the Ray session already running in this process if there is one."""

    name = "ray"

    def __init__(self, address: str | None = None) -> None:
        self.address = address
        self._started = False
        self._ray: Any = None
        self._log: Any = None
        self._runs = 0  # runs started; the attempt log holds the current one's number
        self.retried: list[str] = []
        self.retries_known = True

    def __enter__(self) -> RayRunner:
        ray = self._ray = _import_ray()
        if not ray.is_initialized():
            kwargs: dict[str, Any] = {
                "include_dashboard": False,
                "log_to_driver": False,
                "logging_level": logging.ERROR,
            }
            if self.address is None:  # a new local Ray, never another process's
                kwargs["num_cpus"] = cores()
            else:
                _check_reachable(self.address)
            try:
                ray.init(address=self.address or "local", **kwargs)
            except (ConnectionError, RuntimeError, ValueError) as e:
                where = self.address or "this machine"
                raise AeromagError(f"cannot start or join Ray at {where}: {one_line(e)}") from None
            self._started = True
        self._log = self._new_log()
        return self

    def _new_log(self) -> Any:
        """The attempt log actor: restarted by Ray whenever its worker dies (it costs no CPU and
        its state is only counts), and its calls retried on the restarted actor."""
        remote = self._ray.remote(num_cpus=0, max_restarts=-1, max_task_retries=-1)
        return remote(AttemptLog).remote()

    def __exit__(self, *exc: object) -> None:
        if self._started:
            self._ray.shutdown()

    @property
    def cpus(self) -> int:
        """CPUs of the cluster (this machine's, locally)."""
        return int(self._ray.cluster_resources().get("CPU", 1))

    def run(
        self, tasks: Sequence[Task], progress: Callable[[Outcome], None] | None = None
    ) -> list[Outcome]:
        ray = self._ray
        self._runs += 1
        logged = self._start_log(self._runs)
        remote = ray.remote(aeromag_task)
        refs = [
            remote.options(
                num_cpus=t.num_cpus, max_retries=MAX_RETRIES, retry_exceptions=False
            ).remote(self._log, i, _payload(t))
            for i, t in enumerate(tasks)
        ]
        index = {ref: i for i, ref in enumerate(refs)}
        outcomes: list[Outcome | None] = [None] * len(tasks)
        pending = list(refs)
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            i = index[done[0]]
            outcomes[i] = self._outcome(tasks[i], done[0])
            if progress is not None:
                progress(outcomes[i])  # type: ignore[arg-type]
        attempts = self._attempts(self._runs) if logged else None
        if attempts is None:
            self.retries_known = False
        finished = cast("list[Outcome]", outcomes)  # every task has ended
        for i, o in enumerate(finished):
            o.attempts = None if attempts is None else attempts.get(i, 0)
        self.retried += [o.label for o in finished if (o.attempts or 0) > 1]
        return finished

    def _start_log(self, run: int) -> bool:
        """Point the attempt log at run ``run`` (its counts start afresh), replacing a log that
        is dead or does not answer by a new one; False when no log answered (the run goes on,
        its attempts unknown)."""
        ray = self._ray
        for last in (False, True):
            try:
                ray.get(self._log.reset.remote(run), timeout=LOG_TIMEOUT_S)
                return True
            except ray.exceptions.RayError:
                if not last:
                    self._log = self._new_log()
        return False

    def _attempts(self, run: int) -> dict[int, int] | None:
        """Task index → attempts of run ``run``, or None when they are unknown: the log died
        during the run (a restarted log no longer knows the run) or does not answer."""
        ray = self._ray
        try:
            logged, counts = ray.get(self._log.counts.remote(), timeout=LOG_TIMEOUT_S)
        except ray.exceptions.RayError:
            return None
        return counts if logged == run else None

    def _outcome(self, task: Task, ref: Any) -> Outcome:
        ray = self._ray
        try:
            return Outcome(task.label, value=ray.get(ref))
        except ray.exceptions.RayTaskError as e:  # the task raised: report its own exception
            cause = e.cause if getattr(e, "cause", None) is not None else e
            return Outcome(task.label, error=one_line(cause), details=str(e), exception=cause)
        except ray.exceptions.RayError as e:  # its worker died more often than retried
            return Outcome(
                task.label, error=one_line(e), details=traceback.format_exc(), exception=e
            )


class AttemptLog:
    """A Ray actor counting how often each task of a run started (a retried task starts again).

    Ray reruns ``__init__`` when it restarts the actor, so a restarted log knows no run (0) and
    the driver, finding another run's number beside the counts, knows they are incomplete.
    """

    def __init__(self) -> None:
        self._run = 0
        self._counts: dict[int, int] = {}

    def reset(self, run: int) -> None:
        """Count afresh for run ``run`` (1, 2, … per runner)."""
        self._run, self._counts = run, {}

    def start(self, index: int) -> None:
        self._counts[index] = self._counts.get(index, 0) + 1

    def counts(self) -> tuple[int, dict[int, int]]:
        """The run counted and, per task index, its attempts."""
        return self._run, dict(self._counts)


def _check_reachable(address: str) -> None:
    """A one-line error at once for an address nothing listens on (Ray itself retries for
    minutes); ``auto`` (the cluster this node belongs to) is left to Ray."""
    if address == "auto":
        return
    host, _, port = address.removeprefix("ray://").rpartition(":")
    try:
        socket.create_connection(
            (host or "127.0.0.1", int(port)), timeout=CONNECT_TIMEOUT_S
        ).close()
    except ValueError:
        raise AeromagError(
            f"--ray takes host:port, ray://host:port or nothing, got {address!r}"
        ) from None
    except OSError as e:
        raise AeromagError(f"cannot join Ray at {address}: {e.strerror or one_line(e)}") from None


def _payload(task: Task) -> bytes:
    """The task's function and arguments, pickled here and unpickled by the task after it has
    recorded its attempt: unpickling imports the function's modules (seconds of work on a fresh
    worker), and a worker killed then must count as an attempt too."""
    return pickle.dumps((task.fn, task.args), protocol=pickle.HIGHEST_PROTOCOL)


def aeromag_task(log: Any, index: int, payload: bytes) -> Any:
    """The Ray task: record the attempt, then ``fn(*args)`` (the worker's process title reads
    ``ray::aeromag_task`` while it runs). A log that is dead or does not answer within
    :data:`LOG_TIMEOUT_S` is passed by: the driver then finds the run's attempts unknown."""
    import ray

    with contextlib.suppress(ray.exceptions.RayError):
        ray.get(log.start.remote(index), timeout=LOG_TIMEOUT_S)
    fn, args = pickle.loads(payload)  # this package's own pickle (:func:`_payload`)
    return fn(*args)
