"""The jobs of ``agents``: evaluate every tuning policy, train one run per seed.

:func:`evaluate_policies` does everything ``aeromag evaluate`` does (checks the request, flies
every policy on the same test seeds of each scenario, here or on Ray, and writes per scenario
``results.json``, ``evaluation.png`` and ``report.html`` as a set); :func:`train_policies` does
``aeromag train --seeds`` (one PPO run per seed, here or on Ray, and the seeds' summary
``seeds.json`` with ``report.html``). The command line adds the progress bars and prints the
tables (:mod:`aeromag_env.cli.evaluate`, :mod:`aeromag_env.cli.train`). One training run is
:func:`agents.ppo.train_ppo`.
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
from aeromag_env.environment.scenarios import check_scenario
from aeromag_env.errors import AeromagError
from aeromag_env.jobs.reports import jsonable
from aeromag_env.parallel import Outcome, Task, failures, retry_note, runner
from agents import POLICIES
from agents.evaluate import TEST_SEED_START, action_traces, evaluate_scenarios

#: The output set of an evaluation, per scenario.
OUTPUTS = ("results.json", "evaluation.png", reports.PAGE)


@dataclass(frozen=True)
class EvaluationResult:
    """What :func:`evaluate_policies` produced.

    Attributes
    ----------
    results : dict
        Scenario → its ``results.json`` content (each policy's RMSE [nT] with its interval,
        paired differences against ``fis``, the normalized score).
    paths : tuple of Path
        The files written (empty without ``out``).
    note : str or None
        What the runner has to say about retried tasks (Ray), or None.
    """

    results: dict[str, dict[str, Any]]
    paths: tuple[Path, ...]
    note: str | None


def evaluate_policies(
    scenarios: str | Sequence[str],
    policies: Sequence[str],
    episodes: int = 20,
    seed_start: int = TEST_SEED_START,
    out: str | Path | None = None,
    ray: str | None = None,
    html: bool = True,
    progress: Callable[[int], Any] | None = None,
) -> EvaluationResult:
    """Every policy on the same flights of each scenario, as ``aeromag evaluate`` runs them.

    Parameters
    ----------
    scenarios : str or sequence of str
        One scenario, several comma-separated, or a sequence of distinct scenarios.
    policies : sequence of str
        Names of :data:`agents.POLICIES`, or ``ppo:PATH`` for an exported policy file.
    episodes : int
        Flights (seeds) per scenario, ≥ 1.
    seed_start : int
        The first test seed (the flights are ``seed_start … seed_start + episodes − 1``).
    out : str, Path or None
        The output folder: one scenario's set in ``out``, several in ``out/<scenario>/``
        (None: nothing written).
    ray : str or None
        None: this process; ``""`` or an address: on Ray (:func:`aeromag_env.parallel.runner`).
    html : bool
        Write ``report.html`` too (with the first flight's Q/R scales under each policy).
    progress : callable or None
        Called with 1 after each episode.

    Returns
    -------
    EvaluationResult

    Raises
    ------
    AeromagError
        An unknown scenario or policy, no policy, fewer than one episode, or an output that
        is an input (one line), before any flight is flown.
    """
    names = _scenarios(scenarios)
    policies = list(policies)
    unknown = [p for p in policies if p not in POLICIES and not p.startswith("ppo:")]
    if unknown or not policies:
        raise AeromagError(
            f"unknown policy {unknown[0] if unknown else ''!r}; valid policies: "
            f"{', '.join(POLICIES)}"
        )
    if episodes < 1:
        raise AeromagError(f"--episodes must be ≥ 1, got {episodes}")
    policy_files = [Path(p[4:]) for p in policies if p.startswith("ppo:")]
    folder = None if out is None else Path(out)
    outs = {s: folder if len(names) == 1 else folder / s for s in names} if folder else {}
    outputs = OUTPUTS if html else tuple(n for n in OUTPUTS if n != reports.PAGE)
    for where in outs.values():
        check_output_set(where, outputs, policy_files)
    seeds = list(range(seed_start, seed_start + episodes))
    with runner(ray) as tasks:
        results = evaluate_scenarios(names, policies, seeds, progress=progress, runner=tasks)
    paths: list[Path] = []
    for s, where in outs.items():
        paths += _write(where, outputs, policy_files, results[s], policies, seeds[0])
    return EvaluationResult(results, tuple(paths), retry_note(tasks))


def _scenarios(scenarios: str | Sequence[str]) -> list[str]:
    """The distinct, known scenarios asked for (one-line errors)."""
    text = scenarios if isinstance(scenarios, str) else ",".join(scenarios)
    names = [s.strip() for s in text.split(",") if s.strip()]
    if not names or len(set(names)) < len(names):
        raise AeromagError(f"--scenario takes one or more distinct scenarios, got {text!r}")
    for s in names:
        check_scenario(s)
    return names


def _write(
    folder: Path,
    outputs: tuple[str, ...],
    inputs: list[Path],
    results: dict[str, Any],
    policies: list[str],
    seed: int,
) -> list[Path]:
    """One scenario's output set, all replaced together; the paths written."""
    from agents.plots import plot_evaluation

    with output_set(folder, outputs, inputs) as stage:
        write_text(stage / "results.json", json.dumps(jsonable(results), indent=2))
        plot_evaluation(results, stage / "evaluation.png")
        if reports.PAGE in outputs:
            traces = action_traces(results["scenario"], policies, seed)
            write_text(stage / reports.PAGE, reports.evaluate_page(jsonable(results), traces))
    return [folder / name for name in outputs]


@dataclass(frozen=True)
class TrainingResult:
    """What :func:`train_policies` produced.

    Attributes
    ----------
    summary : dict
        The content of ``seeds.json``: per seed its folder, best validation RMSE [nT], steps,
        attempts and error; the mean and SD of the best validation RMSEs [nT].
    paths : tuple of Path
        The summary files written (each seed's files are in ``out/seed_<k>/``).
    failed : tuple of Outcome
        The seeds whose run failed (the others completed).
    """

    summary: dict[str, Any]
    paths: tuple[Path, ...]
    failed: tuple[Outcome, ...]


def train_policies(
    scenario: str,
    seeds: Sequence[int],
    out: str | Path,
    timesteps: int | None = None,
    quick: bool = False,
    hyperparams: Path | None = None,
    ray: str | None = None,
    html: bool = True,
    progress: Callable[[Outcome], Any] | None = None,
    learner: str = "ppo",
) -> TrainingResult:
    """One training run per seed (:func:`agents.ppo.train_ppo`, or for another ``learner``
    :func:`agents.learners.train_learner`; tasks of a runner, one CPU each), as ``aeromag
    train --seeds`` runs them.

    Parameters
    ----------
    scenario : str
        The training scenario (``suite`` for the general policy).
    seeds : sequence of int
        Distinct training seeds; each run goes to ``out/seed_<k>/`` and resumes from its
        checkpoint there.
    out : str or Path
        The folder of the runs and of the summary (``seeds.json``, ``report.html``).
    timesteps : int or None
        Environment steps per run (None: the hyperparameters').
    quick : bool
        The ``--quick`` preset (:mod:`agents.quick`).
    hyperparams : Path or None
        A hyperparameter file (None: the shipped one).
    ray : str or None
        None: one run after another here; ``""`` or an address: on Ray.
    html : bool
        Write the seeds' learning curves, ``report.html``, with the summary.
    progress : callable or None
        Called with each run's outcome as it ends.
    learner : str
        One of :data:`agents.learners.LEARNERS`; all but ``ppo`` train on ``suite`` from
        ``agents/hyperparams/learners.json`` (or ``hyperparams``) and start afresh on a rerun.

    Returns
    -------
    TrainingResult
        A failed seed is reported in ``failed`` with its folder; the rest complete.
    """
    from agents import learners, ppo

    folder = Path(out)
    if learner == "ppo":
        hp = hyperparams or ppo.HYPERPARAMS
        written: tuple[str, ...] = (*ppo.CHECKPOINT, *ppo.OUTPUTS)
    else:
        hp = hyperparams or learners.HYPERPARAMS
        written = learners.OUTPUTS
    for seed in seeds:
        check_output_set(folder / f"seed_{seed}", written, [hp])
    outputs = ("seeds.json", reports.PAGE) if html else ("seeds.json",)
    check_output_set(folder, outputs, [hp])

    def task(seed: int) -> Task:
        where = folder / f"seed_{seed}"
        if learner == "ppo":
            args: tuple = (scenario, timesteps, seed, where, quick, False, hp, True)
            return Task(f"seed {seed} ({where})", ppo.train_ppo, args)
        args = (learner, seed, where, timesteps, quick, False, hp)
        return Task(f"{learner} seed {seed} ({where})", learners.train_learner, args)

    tasks = [task(seed) for seed in seeds]
    with runner(ray) as r:
        outcomes = r.run(tasks, progress)
    rows = [
        {
            "seed": seed,
            "folder": str(folder / f"seed_{seed}"),
            "attempts": o.attempts,
            "best_validation_rmse_nt": o.value["best_validation_rmse_nt"] if o.ok else None,
            "timesteps": o.value["timesteps"] if o.ok else None,
            "error": o.error,
        }
        for seed, o in zip(seeds, outcomes, strict=True)
    ]
    summary = {
        "scenario": scenario,
        "learner": learner,
        "runner": r.name,
        "seeds": rows,
        **_spread(rows),
    }
    with output_set(folder, outputs, [hp]) as stage:
        write_text(stage / "seeds.json", json.dumps(summary, indent=2))
        if html:
            runs = {f"seed {s}": o.value for s, o in zip(seeds, outcomes, strict=True) if o.ok}
            title = f"Training: {learner} on {scenario}"
            write_text(stage / reports.PAGE, reports.train_page(runs, title))
    paths = tuple(folder / name for name in outputs)
    return TrainingResult(summary, paths, tuple(failures(outcomes)))


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
