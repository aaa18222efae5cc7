"""The learners' benchmark as four steps: train every learner over seeds, fly the test flights,
choose the policy to ship on validation flights, ship it.

Each step is resumable by its files and runs its pieces as tasks of a runner
(``aeromag_env.parallel.runner``: here one after another, or on Ray):

* ``train`` runs ``agents.training.learners.train_learner`` once per learner × seed into
  ``RUNS/<learner>/seed_<k>/``; a finished run (its ``training.json`` exists) is skipped.
* ``evaluate`` flies every finished run's exported policy beside the anchors
  (``tuned_constant``, ``privileged``) and ``fis`` on the same test flights of every scenario of
  the suite (``aeromag evaluate``'s path, ``agents.evaluation.episodes.evaluate_scenarios``),
  once, and writes the data :mod:`agents.comparison.statistics` reads: ``flights.csv`` (one
  record per learner, seed, scenario and flight: the RMSE), ``curves.csv`` (each validation
  point of each run: environment steps, wall-clock seconds, the validation RMSE per scenario),
  ``runs.json`` (per run its minutes, steps, validation score, hyperparameters, and the anchors'
  RMSE on the validation flights) and ``policies/<learner>_seed<k>.npz`` (every seed's exported
  policy). The test flights are fresh (seeds from ``FIRST_SEED``, never flown for a choice).
* ``select`` chooses the policy to ship on validation flights only: every run's exported
  policy flies the same validation flights per scenario, scored as the runs were (the worst
  scenario's mean RMSE ratio to the tuned constant); the learner with the lowest mean score over
  its seeds wins, and of it the seed with the lowest score (``choose``). Nothing of the test
  flights is read.
* ``ship`` writes the chosen policy as a general policy file, its settings named by their
  preset (``general``) as the shipped files name theirs.

``experiments/compare_learners.py`` is the command line over these steps.
"""

from __future__ import annotations

import csv
import io
import json
import shutil
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from aeromag_env.atomic import output_set, write_text
from aeromag_env.environment.ids import SUITE
from aeromag_env.errors import AeromagError, HyperparameterError
from aeromag_env.parallel import Outcome, Runner, Task
from agents.training.learners import LEARNERS, train_learner

#: The policies flown beside the learners on every test flight.
REFERENCES = ("tuned_constant", "privileged", "fis")
#: The anchors of the normalized score, whose validation RMSE ``runs.json`` records.
ANCHORS = ("tuned_constant", "privileged")
#: The first test flight's seed: fresh for this benchmark (earlier tables flew 100 000 on).
FIRST_SEED = 200_000
#: The data files :func:`evaluate` writes (beside the ``policies/`` folder).
DATA_FILES = ("flights.csv", "curves.csv", "runs.json")
#: The file :func:`select` writes beside them.
SELECTION = "selection.json"
#: How :func:`select` scores a run, as the runs kept their checkpoints.
SELECT_BY = "worst_ratio_to_tuned_constant"
#: The columns of ``curves.csv``.
CURVE_COLUMNS = (
    "learner",
    "seed",
    "timesteps",
    "seconds",
    "train_seconds",
    "scenario",
    "flights",
    "validation_rmse_nt",
)


def run_folder(runs: Path, learner: str, seed: int) -> Path:
    """The folder of ``learner``'s run with training seed ``seed`` under ``runs``."""
    return Path(runs) / learner / f"seed_{seed}"


def check_learners(learners: Sequence[str]) -> None:
    """Refuse a learner that is not one of :data:`~agents.training.LEARNERS`, naming them."""
    unknown = [x for x in learners if x not in LEARNERS]
    if unknown:
        raise HyperparameterError(
            f"unknown learner(s) {', '.join(unknown)}; valid: {', '.join(LEARNERS)}"
        )


def train_run(learner: str, seed: int, folder: str, quick: bool = False) -> dict[str, Any]:
    """One training run into ``folder``, or, when it has finished before, its summary.

    Returns
    -------
    dict
        The run's ``training.json`` summary (its ``train_seconds_this_run`` [s] among the
        fields) and ``"trained_now"``: False when the run was found finished and skipped.
    """
    out = Path(folder)
    done = out / "training.json"
    if done.exists():
        return {**json.loads(done.read_text()), "trained_now": False}
    return {**train_learner(learner, seed, out, quick=quick), "trained_now": True}


def train(
    learners: Sequence[str],
    seeds: Sequence[int],
    runs: Path,
    runner: Runner,
    *,
    quick: bool = False,
    progress: Callable[[Outcome], None] | None = None,
) -> list[Outcome]:
    """Train every learner with every training seed into ``runs`` (:func:`train_run` tasks of
    ``runner``, seed by seed, so that a run cut short has as many seeds of every learner).

    Parameters
    ----------
    learners : sequence of str
        Learners of :data:`~agents.training.LEARNERS`.
    seeds : sequence of int
        Training seeds.
    runs : Path
        The runs' folder (``RUNS/<learner>/seed_<k>/``).
    runner : Runner
        Where the runs go.
    quick : bool
        Test-sized runs (:data:`agents.training.learners.QUICK`).
    progress : callable, optional
        Called with each run's :class:`~aeromag_env.parallel.Outcome` as it ends.

    Returns
    -------
    list of Outcome
        One per run, in the tasks' order; a failed run does not stop the others.
    """
    check_learners(learners)
    tasks = [
        Task(
            f"{learner} seed {seed}",
            train_run,
            (learner, seed, str(run_folder(runs, learner, seed)), quick),
        )
        for seed in seeds
        for learner in learners
    ]
    return runner.run(tasks, progress)


def finished_runs(runs: Path) -> dict[str, Path]:
    """``learner/seed`` → its exported policy, for every finished run under ``runs`` (its
    ``policy.npz`` and ``training.json`` both there), learners in :data:`LEARNERS`' order."""
    found = {}
    for learner in LEARNERS:
        for folder in sorted((Path(runs) / learner).glob("seed_*")):
            if (folder / "policy.npz").exists() and (folder / "training.json").exists():
                found[f"{learner}/{folder.name.removeprefix('seed_')}"] = folder / "policy.npz"
    return found


def _finished(runs: Path) -> dict[str, Path]:
    policies = finished_runs(runs)
    if not policies:
        raise AeromagError(f"no finished runs under {runs} (train them first)")
    return policies


def flights_csv(
    results: Mapping[str, Mapping[str, Any]], names: Mapping[str, str], seeds: Sequence[int]
) -> str:
    """``flights.csv``: one row per policy, scenario and test flight with its RMSE [nT] (the
    references with an empty seed).

    Parameters
    ----------
    results : mapping
        :func:`~agents.evaluation.episodes.evaluate_scenarios`' results by scenario.
    names : mapping
        ``learner/seed`` → the policy's name in ``results`` (``ppo:PATH``).
    seeds : sequence of int
        The test flights' seeds, in the order of each policy's ``rmse_nt``.
    """
    text = io.StringIO()
    w = csv.writer(text, lineterminator="\n")
    w.writerow(["learner", "seed", "scenario", "flight", "rmse_nt"])
    for scenario, r in results.items():
        for ref in REFERENCES:
            for flight, v in zip(seeds, r["policies"][ref]["rmse_nt"], strict=True):
                w.writerow([ref, "", scenario, flight, repr(float(v))])
        for key, name in names.items():
            learner, seed = key.split("/")
            for flight, v in zip(seeds, r["policies"][name]["rmse_nt"], strict=True):
                w.writerow([learner, seed, scenario, flight, repr(float(v))])
    return text.getvalue()


def validation_flights(summary: Mapping[str, Any]) -> int:
    """Validation flights per scenario of a run (its ``eval_episodes`` split over the suite)."""
    return max(int(summary["hyperparams"]["eval_episodes"]) // len(SUITE), 1)


def _kept_point(curve: Sequence[Mapping[str, Any]]) -> Mapping[str, Any]:
    """The validation point a run kept: the lowest score (the mean RMSE for runs without)."""
    return min(curve, key=lambda p: p.get("validation_score", p["validation_rmse_nt"]))


def run_summary(learner: str, seed: str, summary: Mapping[str, Any]) -> dict[str, Any]:
    """A run's record in ``runs.json``: its minutes [min], steps, the kept checkpoint's steps,
    validation flights per scenario, best validation score and hyperparameters."""
    return {
        "learner": learner,
        "seed": int(seed),
        "timesteps": summary["timesteps"],
        "minutes": round(summary["train_seconds_this_run"] / 60.0, 2),
        "validation_flights": validation_flights(summary),
        "kept_timesteps": _kept_point(_curve(summary))["timesteps"],
        "best_validation_score": summary.get("best_validation_score"),
        "hyperparams": summary.get("hyperparams"),
    }


def _curve(summary: Mapping[str, Any], folder: Path | None = None) -> list[dict[str, Any]]:
    """A run's learning curve: in its summary, or (older runs) in ``curve.json`` beside it."""
    if summary.get("curve") or folder is None:
        return list(summary.get("curve") or [])
    return list(json.loads((folder / "curve.json").read_text()))


def curves(policies: Mapping[str, Path]) -> tuple[str, list[dict[str, Any]]]:
    """``curves.csv`` (every validation point of every run, per scenario) and each run's
    record (:func:`run_summary`), from the runs' ``training.json`` beside their policies."""
    text = io.StringIO()
    w = csv.writer(text, lineterminator="\n")
    w.writerow(CURVE_COLUMNS)
    records = []
    for key, path in policies.items():
        learner, seed = key.split("/")
        summary = json.loads((path.parent / "training.json").read_text())
        curve = _curve(summary, path.parent)
        per = validation_flights(summary)
        for point in curve:
            seconds = round(point["seconds"], 2)
            train_s = round(point.get("train_seconds", point["seconds"]), 2)
            for scenario, v in point.get("validation_rmse_by_scenario", {}).items():
                w.writerow(
                    [
                        learner,
                        seed,
                        point["timesteps"],
                        seconds,
                        train_s,
                        scenario,
                        per,
                        repr(float(v)),
                    ]
                )
        records.append(run_summary(learner, seed, {**summary, "curve": curve}))
    return text.getvalue(), records


def validation_anchors(per_scenario: Sequence[int]) -> dict[str, dict[str, dict[str, float]]]:
    """The anchors' mean RMSE [nT] on the first ``n`` validation flights of each scenario, for
    each ``n`` of ``per_scenario``: what a learning curve's normalized score is measured
    against (``n`` → scenario → anchor → RMSE)."""
    from agents.policies import policy_env_kwargs
    from agents.training.validation import validation_rmse

    return {
        str(n): {
            scenario: {
                ref: float(validation_rmse(ref, scenario, n, policy_env_kwargs(ref)).mean())
                for ref in ANCHORS
            }
            for scenario in SUITE
        }
        for n in sorted(set(per_scenario))
    }


@dataclass(frozen=True, kw_only=True)
class Evaluated:
    """What :func:`evaluate` wrote: the data files and the policies copied beside them."""

    files: tuple[Path, ...]
    policies: int


def evaluate(
    runs: Path,
    data: Path,
    runner: Runner,
    *,
    episodes: int,
    first_seed: int = FIRST_SEED,
    command: str,
) -> Evaluated:
    """Fly every finished run's policy and the references on the test flights of every
    scenario of the suite; write the data (module docstring) into ``data`` as one set.

    Parameters
    ----------
    runs : Path
        The runs' folder (:func:`train`'s).
    data : Path
        The data folder (created if missing).
    runner : Runner
        Where the flights go.
    episodes : int
        Test flights per scenario (seeds ``first_seed`` on).
    first_seed : int
        The first test flight's seed (at least the test range's start).
    command : str
        The command line that asked for this, recorded in ``runs.json``.

    Raises
    ------
    AeromagError
        No finished run under ``runs``.
    """
    from agents.evaluation.episodes import evaluate_scenarios

    policies = _finished(runs)
    names = {key: f"ppo:{path}" for key, path in policies.items()}
    seeds = list(range(first_seed, first_seed + episodes))
    results = evaluate_scenarios(list(SUITE), [*REFERENCES, *names.values()], seeds, runner=runner)
    curve_rows, records = curves(policies)
    meta = {
        "command": command,
        "date": datetime.now(UTC).strftime("%Y-%m-%d"),
        "test_flights": {"first_seed": first_seed, "per_scenario": episodes},
        "scenarios": list(SUITE),
        "validation_anchors": validation_anchors([r["validation_flights"] for r in records]),
        "runs": records,
    }
    with output_set(data, DATA_FILES) as stage:
        write_text(stage / "flights.csv", flights_csv(results, names, seeds))
        write_text(stage / "curves.csv", curve_rows)
        write_text(stage / "runs.json", json.dumps(meta, indent=1))
    shelf = Path(data) / "policies"
    shelf.mkdir(parents=True, exist_ok=True)
    for key, path in policies.items():
        learner, seed = key.split("/")
        shutil.copyfile(path, shelf / f"{learner}_seed{seed}.npz")
    return Evaluated(files=tuple(Path(data) / f for f in DATA_FILES), policies=len(policies))


def validate_run(path: str, flights: int) -> dict[str, Any]:
    """The validation point of the exported policy ``path`` on ``flights`` validation flights
    per scenario of the suite, scored by :data:`SELECT_BY` (a task of :func:`select`)."""
    from agents.policies.numpy_policy import NumpyPolicy
    from agents.training.validation import Validator

    return Validator(SELECT_BY, "suite", flights * len(SUITE))(NumpyPolicy.load(path))


def choose(scores: Mapping[str, float]) -> tuple[dict[str, float], dict[str, Any]]:
    """The learner with the lowest mean score over its seeds, and of it the seed with the
    lowest score.

    Parameters
    ----------
    scores : mapping
        ``learner/seed`` → the run's validation score (lower is better).

    Returns
    -------
    means : dict
        Learner → its mean score over its seeds.
    chosen : dict
        ``{"learner": ..., "seed": ...}``.
    """
    by_learner: dict[str, list[float]] = {}
    for key, score in scores.items():
        by_learner.setdefault(key.split("/")[0], []).append(score)
    means = {learner: sum(v) / len(v) for learner, v in by_learner.items()}
    best = min(means, key=means.__getitem__)
    seed = min((k for k in scores if k.startswith(f"{best}/")), key=scores.__getitem__)
    return means, {"learner": best, "seed": int(seed.split("/")[1])}


def select(runs: Path, data: Path, runner: Runner, *, flights: int, command: str) -> dict[str, Any]:
    """Choose the policy to ship on validation flights (module docstring); write
    ``data/selection.json`` and return what it holds.

    Parameters
    ----------
    runs : Path
        The runs' folder (:func:`train`'s).
    data : Path
        The data folder.
    runner : Runner
        Where the validation flights go.
    flights : int
        Validation flights per scenario (the first of each scenario's validation seeds).
    command : str
        The command line that asked for this, recorded in the file.

    Raises
    ------
    AeromagError
        No finished run under ``runs``, or a run whose validation failed (the first, named).
    """
    tasks = [Task(key, validate_run, (str(p), flights)) for key, p in _finished(runs).items()]
    outcomes = runner.run(tasks)
    failed = [o for o in outcomes if not o.ok]
    if failed:
        raise AeromagError(f"{failed[0].label}: {failed[0].error}")
    scored = {t.label: o.value for t, o in zip(tasks, outcomes, strict=True)}
    means, chosen = choose({k: v["validation_score"] for k, v in scored.items()})
    result = {
        "command": command,
        "date": datetime.now(UTC).strftime("%Y-%m-%d"),
        "validation_flights_per_scenario": flights,
        "score": "worst scenario's mean RMSE ratio to tuned_constant (lower is better)",
        "runs": scored,
        "learner_mean_score": means,
        "chosen": chosen,
    }
    write_text(Path(data) / SELECTION, json.dumps(result, indent=1))
    return result


def ship(runs: Path, data: Path, target: Path) -> str:
    """Write the policy :func:`select` chose (``data/selection.json``) to ``target`` as a
    general policy, its settings named by their preset (``general``); unchanged when ``target``
    already holds its arrays. Returns what was done, one line.

    Raises
    ------
    AeromagError
        No choice in ``data``, or the chosen run was not trained with the ``general`` preset's
        settings.
    """
    import numpy as np

    from aeromag_env.environment.config import PRESETS, env_config
    from agents.policies.policy_file import read_policy, write_policy

    selection = Path(data) / SELECTION
    if not selection.exists():
        raise AeromagError(f"no {selection} (choose the policy first: select)")
    chosen = json.loads(selection.read_text())["chosen"]
    source = run_folder(runs, chosen["learner"], chosen["seed"]) / "policy.npz"
    what = f"{chosen['learner']} seed {chosen['seed']}"
    arrays, meta = read_policy(source)
    if env_config(meta.get("env_kwargs", {})) != PRESETS["general"]:
        raise AeromagError(f"{source} was not trained with the general preset's settings")
    if target.exists():
        shipped, _ = read_policy(target)
        same = shipped.keys() == arrays.keys()
        if same and all(np.array_equal(shipped[k], arrays[k]) for k in arrays):
            return f"{target} already holds {what}'s policy"
    meta = {**meta, "env_kwargs": {"preset": "general"}, "learner": chosen["learner"]}
    write_policy(arrays, meta, target)
    return f"wrote {target}: {what}"
