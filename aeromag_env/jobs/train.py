"""Train a tuner: :func:`train`, the job of ``aeromag train``.

One run (:func:`agents.training.ppo.train_ppo` for PPO, :func:`agents.training.learners.
train_learner` for the other learners) into ``out``, keeping the best validated policy as
``out/policy.npz`` with its learning curve (``report.html``); or one run per seed, each in
``out/seed_<k>/`` (here one after another, or side by side on Ray), and the seeds' summary
``seeds.json`` with ``report.html``.

Rerunning a request finishes it: a PPO run resumes from the checkpoint in its folder and trains
up to the requested total of environment steps (not that many more), another learner's run
(which keeps no checkpoint) starts again; a run whose ``training.json`` already reached the total
is not trained again (:func:`finished_run`), and a folder holding another run (another learner,
scenario or seed) is refused.
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

    def total_timesteps(self) -> int:
        """The environment steps each run ends at: ``timesteps``, else the quick preset's with
        ``quick``, else the hyperparameters' (PPO: :data:`agents.training.ppo.TIMESTEPS`)."""
        from agents.training import learners, ppo
        from agents.training.quick import QUICK, sized

        if self.learner == "ppo":
            return sized(self.timesteps, ppo.TIMESTEPS, self.quick, QUICK.train_timesteps)
        settings = learners.learner_settings(
            self.learner, self.hyperparams_file(), quick=self.quick, timesteps=self.timesteps
        )
        return int(settings.timesteps)

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
    finished : tuple of int
        The seeds whose run had already reached the requested total: not trained again (a
        single run: its seed, and ``paths`` is empty: nothing was written).
    """

    learner: str
    scenario: str
    summary: dict[str, Any]
    paths: tuple[Path, ...]
    failed: tuple[Outcome, ...] = ()
    finished: tuple[int, ...] = ()


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


def finished_run(folder: Path, req: TrainRequest, seed: int) -> dict[str, Any] | None:
    """The ``training.json`` summary of the run of ``req`` with ``seed`` in ``folder`` when it
    has reached the requested total (:meth:`TrainRequest.total_timesteps`), else None (no run
    there, or one to resume or start again).

    Raises
    ------
    AeromagError
        ``folder`` holds another run (its learner, scenario or seed differ), or an unreadable
        ``training.json``: one line, before anything is trained.
    """
    path = folder / "training.json"
    try:
        summary = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        return None
    except (OSError, ValueError) as e:
        raise AeromagError(
            f"cannot read {path} ({type(e).__name__}: {e}); remove it to train afresh, or "
            "choose another --out"
        ) from None
    if not isinstance(summary, dict) or not isinstance(summary.get("timesteps"), int):
        raise AeromagError(f"{path} is no training summary; remove it or choose another --out")
    held = (summary.get("learner", "ppo"), summary.get("scenario"), summary.get("seed"))
    if held != (req.learner, req.scenario, seed):
        learner, scenario, other = held
        raise AeromagError(
            f"{folder} holds a training run of {learner} on {scenario}, seed {other} "
            f"({path.name}): rerun that command to finish it, or choose another --out"
        )
    return summary if summary["timesteps"] >= req.total_timesteps() else None


def train_one(req: TrainRequest, show_progress: bool = False) -> TrainResult:
    """One run of a checked request into ``req.out``, with ``report.html`` beside it; nothing
    when the folder's run already reached the requested total."""
    from agents.training import learners, ppo

    done = finished_run(req.out, req, req.seed)
    if done is not None:
        return TrainResult(req.learner, req.scenario, done, (), finished=(req.seed,))
    if req.learner == "ppo":
        summary = ppo.train_ppo(
            req.scenario,
            req.timesteps,
            req.seed,
            req.out,
            req.quick,
            progress=show_progress,
            hyperparams=req.hyperparams_file(),
            total=True,
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
    done = {seed: finished_run(folder / f"seed_{seed}", req, seed) for seed in req.seeds}
    finished = tuple(seed for seed, summary in done.items() if summary is not None)
    if len(finished) == len(req.seeds) and (folder / "seeds.json").exists():
        stored = json.loads((folder / "seeds.json").read_text(encoding="utf-8"))
        return TrainResult(req.learner, req.scenario, stored, (), finished=finished)

    def task(seed: int) -> Task:
        where = folder / f"seed_{seed}"
        if req.learner == "ppo":
            args: tuple = (req.scenario, req.timesteps, seed, where, req.quick, False, hp, True)
            return Task(f"seed {seed} ({where})", ppo.train_ppo, args)
        args = (req.learner, seed, where, req.timesteps, req.quick, False, hp)
        return Task(f"{req.learner} seed {seed} ({where})", learners.train_learner, args)

    todo = [seed for seed in req.seeds if seed not in finished]
    with runner(req.ray if todo else None) as r:
        ran = dict(zip(todo, r.run([task(seed) for seed in todo], on_seed), strict=True))
    outcomes = [
        ran[seed] if seed in ran else Outcome(f"seed {seed}", done[seed], attempts=0)
        for seed in req.seeds
    ]
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
    failed = tuple(failures(outcomes))
    return TrainResult(req.learner, req.scenario, summary, paths, failed, finished)


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
