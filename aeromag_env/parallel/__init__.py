"""Run independent tasks here or on a Ray cluster: one face for evaluation sweeps, training
seeds and fleets of flight files.

:func:`runner` gives a :class:`SerialRunner` (the default: this process, in order) or, for
``--ray [ADDRESS]``, a :class:`~aeromag_env.parallel.ray_runner.RayRunner`. Both take a list of
:class:`Task` and give one :class:`Outcome` per task, in the tasks' order: its value, or the
one-line error it raised with the task's label (its input), and how many attempts it took
(:func:`retry_note` says which were retried, or that this is unknown). A task that raises does
not stop the others. Ray is imported only by the Ray runner.
"""

from typing import Any

from aeromag_env.parallel.tasks import (
    LOCAL,
    Outcome,
    Runner,
    SerialRunner,
    Task,
    failures,
    retry_note,
)


def runner(ray: str | None) -> Any:
    """The runner for ``--ray``: None → :class:`SerialRunner`; ``"local"`` → Ray started here
    with this machine's cores; an address (``host:port`` or ``ray://…``) → join that cluster.
    Use as a context manager (Ray is shut down on exit if this call started it)."""
    if ray is None:
        return SerialRunner()
    from aeromag_env.parallel.ray_runner import RayRunner

    return RayRunner(None if ray == LOCAL else ray)


__all__ = ["LOCAL", "Outcome", "Runner", "SerialRunner", "Task", "failures", "retry_note", "runner"]
