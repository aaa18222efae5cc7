"""Train a tuner: :func:`train`, the job of ``aeromag train``.

One run (:func:`agents.training.ppo.train_ppo` for PPO, :func:`agents.training.learners.
train_learner` for the other learners) into ``out``, keeping the best validated policy as
``out/policy.npz`` with its learning curve (``report.html``); or one run per seed, each in
``out/seed_<k>/`` (here one after another, or side by side on Ray), and the seeds' summary
``seeds.json`` with ``report.html``. A PPO run resumes from the checkpoint in its folder.
"""

from __future__ import annotations

import json
import math
import statistics
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from aeromag_env import reports
from aeromag_env.atomic import check_output_set, output_set, write_text
from aeromag_env.errors import AeromagError, ArgumentError
from aeromag_env.jobs.limits import MAX_SEEDS, MAX_TIMESTEPS, check_count, check_seed
from aeromag_env.parallel import Outcome, Task, failures, runner


@dataclass(frozen=True, kw_only=True)
class TrainRequest:
    """What a training job is asked for (validated by :meth:`check`).

    Attributes
    ----------
    out : Path
        The run's folder (with ``seeds``: the folder of the runs ``seed_<k>/`` and the summary).
    learner : str
        One of :data:`agents.training.LEARNERS`.
    scenario : str
        The training scenario (:func:`agents.training.training_scenario` fills the default).
    timesteps : int or None
        Environment steps (None: the hyperparameters'; ``quick``: the quick preset's).
    seed : int
        The training seed of a single run.
    seeds : tuple of int or None
        One run per seed instead of a single run.
    quick : bool
        The sizes of :data:`agents.training.quick.QUICK` (about a minute; checks the set-up).
    hyperparams : Path or None
        A hyperparameter file (None: the shipped one).
    ray : str or None
        With ``seeds``: None runs them one after another here, ``local`` or an address on Ray.
    html : bool
        Write the learning curves, ``report.html``.
    """

    out: Path
    learner: str = "ppo"
    scenario: str = "nonstationary"
    timesteps: int | None = None
    seed: int = 0
    seeds: tuple[int, ...] | None = None
    quick: bool = False
    hyperparams: Path | None = None
    ray: str | None = None
    html: bool = True

    def check(self) -> None:
        """One-line errors for unusable arguments, before any training."""
        from agents.training import training_scenario

        training_scenario(self.learner, self.scenario)
        check_seed("seed", self.seed)
        if self.timesteps is not None:
            check_count(
                "timesteps",
                self.timesteps,
                1,
                MAX_TIMESTEPS,
                "environment steps",
                "10⁹ is 333× the shipped policies' 3e6 and days of CPU time",
            )
        if self.seeds is not None:
            self.check_seeds()
        elif self.ray is not None:
            raise ArgumentError("ray", "runs several training seeds side by side: give seeds too")

    def check_seeds(self) -> None:
        """``seeds``: distinct, at most :data:`~aeromag_env.jobs.limits.MAX_SEEDS`, each a seed."""
        seeds = self.seeds or ()
        if not seeds or len(set(seeds)) < len(seeds) or len(seeds) > MAX_SEEDS:
            raise ArgumentError(
                "seeds", f"must name 1 to {MAX_SEEDS} distinct seeds", ",".join(map(str, seeds))
            )
        for seed in seeds:
            check_seed("seeds", seed)

    def hyperparams_file(self) -> Path:
        """The hyperparameter file the runs read (never overwritten)."""
        if self.hyperparams is not None:
            return self.hyperparams
        from agents.training import learners, ppo

        return ppo.HYPERPARAMS if self.learner == "ppo" else learners.HYPERPARAMS

    def run_outputs(self) -> tuple[str, ...]:
        """The files one run writes in its folder."""
        from agents.training import learners, ppo

        if self.learner == "ppo":
            return (*ppo.CHECKPOINT, *ppo.OUTPUTS)
        return learners.OUTPUTS


@dataclass(frozen=True)
class TrainResult:
    """What :func:`train` produced.

    Attributes
    ----------
    learner, scenario : str
        What was trained, and on what.
    summary : dict
        A single run: its ``training.json`` summary (steps, seconds, best validation RMSE [nT],
        the learning curve). Several seeds: ``seeds.json``'s content — per seed its folder, best
        validation RMSE [nT], steps, attempts and error; the mean and SD over the seeds.
    paths : tuple of Path
        The summary files written (a seed's own files are in ``out/seed_<k>/``).
    failed : tuple of Outcome
        The seeds whose run failed (the others completed); empty for a single run.
    """

    learner: str
    scenario: str
    summary: dict[str, Any]
    paths: tuple[Path, ...]
    failed: tuple[Outcome, ...] = ()


def train(
    out: str | Path,
    *,
    learner: str = "ppo",
    scenario: str | None = None,
    timesteps: int | None = None,
    seed: int = 0,
    seeds: Sequence[int] | None = None,
    quick: bool = False,
    hyperparams: str | Path | None = None,
    ray: str | None = None,
    html: bool = True,
    show_progress: bool = False,
    on_seed: Callable[[Outcome], Any] | None = None,
) -> TrainResult:
    """Train a tuner, as ``aeromag train`` does.

    Parameters
    ----------
    out : str or Path
        The run's folder (with ``seeds``: one folder ``seed_<k>/`` per seed in it).
    learner, scenario, timesteps, seed, seeds, quick, hyperparams, ray, html
        See :class:`TrainRequest`; ``scenario`` None is the learner's default.
    show_progress : bool
        A single run's progress bar on stderr.
    on_seed : callable or None
        With ``seeds``: called with each run's outcome as it ends.

    Returns
    -------
    TrainResult
        With ``seeds``, a failed seed is reported in ``failed`` with its folder; the rest
        complete.

    Raises
    ------
    AeromagError
        Bad arguments, a missing extra (torch, stable-baselines3), an unreadable
        hyperparameter file or an output that is an input (one line), before training.
    """
    try:
        from agents.training import training_scenario
    except ImportError as e:  # pragma: no cover - agents ships with the package
        raise AeromagError(f"training needs the agents package: {e}") from None
    request = TrainRequest(
        out=Path(out),
        learner=learner,
        scenario=training_scenario(learner, scenario),
        timesteps=timesteps,
        seed=seed,
        seeds=None if seeds is None else tuple(seeds),
        quick=quick,
        hyperparams=None if hyperparams is None else Path(hyperparams),
        ray=ray,
        html=html,
    )
    request.check()
    _require_rl_extra()
    if request.seeds is not None:
        return train_seeds(request, on_seed)
    return train_one(request, show_progress)


def _require_rl_extra() -> None:
    """A one-line error when the ``rl`` extra (torch, stable-baselines3) is missing."""
    try:
        import stable_baselines3  # noqa: F401
        import torch  # noqa: F401
    except ImportError as e:
        raise AeromagError(
            f"training needs the rl extra (pip install 'aeromag-env[rl]'): {e}"
        ) from None


def train_one(req: TrainRequest, show_progress: bool = False) -> TrainResult:
    """One run of a checked request into ``req.out``, with ``report.html`` beside it."""
    from agents.training import learners, ppo

    if req.learner == "ppo":
        summary = ppo.train_ppo(
            req.scenario,
            req.timesteps,
            req.seed,
            req.out,
            req.quick,
            progress=show_progress,
            hyperparams=req.hyperparams_file(),
        )
    else:
        summary = learners.train_learner(
            req.learner,
            req.seed,
            req.out,
            req.timesteps,
            req.quick,
            hyperparams=req.hyperparams_file(),
        )
    paths: tuple[Path, ...] = ()
    if req.html:  # the learning curve beside training.json
        page = reports.train_page({"run": summary}, f"Training: {req.learner} on {req.scenario}")
        paths = (write_text(req.out / reports.PAGE, page),)
    return TrainResult(req.learner, req.scenario, summary, paths)


def train_seeds(req: TrainRequest, on_seed: Callable[[Outcome], Any] | None = None) -> TrainResult:
    """One run per seed of a checked request (tasks of a runner, one CPU each), then the seeds'
    summary ``seeds.json`` (and ``report.html``) in ``req.out``."""
    from agents.training import learners, ppo

    assert req.seeds is not None
    folder, hp = req.out, req.hyperparams_file()
    for seed in req.seeds:
        check_output_set(folder / f"seed_{seed}", req.run_outputs(), [hp])
    outputs = ("seeds.json", reports.PAGE) if req.html else ("seeds.json",)
    check_output_set(folder, outputs, [hp])

    def task(seed: int) -> Task:
        where = folder / f"seed_{seed}"
        if req.learner == "ppo":
            args: tuple = (req.scenario, req.timesteps, seed, where, req.quick, False, hp, True)
            return Task(f"seed {seed} ({where})", ppo.train_ppo, args)
        args = (req.learner, seed, where, req.timesteps, req.quick, False, hp)
        return Task(f"{req.learner} seed {seed} ({where})", learners.train_learner, args)

    with runner(req.ray) as r:
        outcomes = r.run([task(seed) for seed in req.seeds], on_seed)
    summary = {
        "scenario": req.scenario,
        "learner": req.learner,
        "runner": r.name,
        "seeds": [_seed_row(folder, s, o) for s, o in zip(req.seeds, outcomes, strict=True)],
    }
    summary |= _spread(summary["seeds"])
    with output_set(folder, outputs, [hp]) as stage:
        write_text(stage / "seeds.json", json.dumps(summary, indent=2))
        if req.html:
            runs = {f"seed {s}": o.value for s, o in zip(req.seeds, outcomes, strict=True) if o.ok}
            title = f"Training: {req.learner} on {req.scenario}"
            write_text(stage / reports.PAGE, reports.train_page(runs, title))
    paths = tuple(folder / name for name in outputs)
    return TrainResult(req.learner, req.scenario, summary, paths, tuple(failures(outcomes)))


def _seed_row(folder: Path, seed: int, o: Outcome) -> dict[str, Any]:
    """One seed's row of ``seeds.json``."""
    return {
        "seed": seed,
        "folder": str(folder / f"seed_{seed}"),
        "attempts": o.attempts,
        "best_validation_rmse_nt": o.value["best_validation_rmse_nt"] if o.ok else None,
        "timesteps": o.value["timesteps"] if o.ok else None,
        "error": o.error,
    }


def _spread(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Mean and SD of the seeds' finite best validation RMSEs (SD from 2 seeds on)."""
    finite = [
        v for r in rows if (v := r["best_validation_rmse_nt"]) is not None and math.isfinite(v)
    ]
    sd = statistics.stdev(finite) if len(finite) > 1 else None
    return {
        "validation_rmse_nt_mean": statistics.fmean(finite) if finite else None,
        "validation_rmse_nt_sd": sd,
    }
