"""Search the hyperparameters of the other learners (``aeromag tune --learner sac``): random
samples of the learner's space in ``agents/search/spaces/tune_space_learners.json``
(:func:`agents.search.space.read_learner_space`), each a Ray Tune trial that trains the learner as
``aeromag train --learner`` does (:func:`agents.training.learners.run_learner`), with ASHA stopping
the trials that validate badly early.

A trial trains with the learner's settings of ``learners.json`` (the suite, the ``general``
preset, its ``n_envs``, ``eval_every`` and ``eval_episodes``), the sampled values replacing the
keys of its ``algo``, on one training seed (the same for every trial: they differ by their
hyperparameters only) and one CPU (no prefetching worker). After each validation of the run
(the points of :class:`agents.training.learners.Curve`: at step 0, every ``eval_every`` steps, at
the end) it reports the point's selection score (``select_by``: the worst scenario's mean ratio of
the validation RMSE to the tuned constant's; lower is better) to Tune; ASHA counts reports, its
first rung after the first validation of a trained policy (the report at step 0 is the
untrained policy's, alike for every trial). The search is seeded (the same ``--seed`` draws the
same samples).

The outputs, written as a set: ``learners.json``, the base learners file with the learner's
``algo`` updated by the best trial's values (the lowest score any trial reported for a
trained policy: the step-0 point, alike in every trial, ranks none) and its
``comment`` saying so, ready for ``aeromag train --learner L --hyperparams``; and
``tune.json``, every trial. Ray is imported by :mod:`agents.search.ppo` only (extra ray).
"""

from __future__ import annotations

import json
import math
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from aeromag_env.atomic import check_output_set
from aeromag_env.errors import AeromagError
from agents.search.ppo import (
    REDUCTION,
    SAMPLES,
    best_trial,
    ray_session,
    run_search,
    trial_fields,
    write_outputs,
)
from agents.search.space import LEARNER_SPACES, plain, read_learner_space, recorded_path
from agents.training.learner_hyperparameters import LearnerHyperparams
from agents.training.learners import (
    HYPERPARAMS,
    learner_hyperparams,
    learner_settings,
    run_learner,
    selection_score,
)
from agents.training.quick import QUICK, sized

#: The learners ``aeromag tune --learner`` searches (``ppo``: :func:`agents.search.ppo.tune_ppo`).
SEARCHED = ("recurrent_ppo", "sac", "tqc")
#: The outputs in ``--out``, written as a set.
OUTPUTS = ("learners.json", "tune.json")
#: What Tune minimises: the validation point's selection score (``select_by``).
METRIC = "validation_score"
#: ASHA's first rung, in reports: the second validation, the first of a trained policy.
GRACE = 2


@dataclass(frozen=True, kw_only=True)
class LearnerTuneJob:
    """What every trial shares: the learner, its settings (of
    :func:`agents.training.learners.learner_settings`; the sampled keys replace those of ``algo``)
    and
    the training seed."""

    learner: str
    hp: LearnerHyperparams
    seed: int


def tune_learner(
    learner: str,
    out: Path,
    *,
    space_path: Path = LEARNER_SPACES,
    samples: int | None = None,
    timesteps: int | None = None,
    seed: int = 0,
    quick: bool = False,
    ray_address: str | None = None,
    hyperparams: Path = HYPERPARAMS,
) -> dict[str, Any]:
    """Run the search; write ``out/learners.json`` and ``out/tune.json``; return the summary.

    Parameters
    ----------
    learner : str
        One of :data:`SEARCHED`.
    out : Path
        Output folder.
    space_path : Path
        The learners' search spaces (:func:`agents.search.space.read_learner_space`).
    samples : int or None
        Trials (configurations drawn); None: :data:`agents.search.ppo.SAMPLES` (``quick``:
        ``QUICK``'s).
    timesteps : int or None
        Environment steps per trial (ASHA stops bad trials earlier); None: the learner's
        ``timesteps`` in ``hyperparams`` (``quick``: :data:`agents.training.quick.QUICK`'s).
    seed : int
        Seed of the sampling and of every trial's training.
    quick : bool
        The sizes of :data:`agents.training.quick.QUICK` (a test's: two environments, a few
        thousand steps, one validation flight per scenario) and ``QUICK.tune_samples`` trials.
    ray_address : str or None
        A Ray cluster to join (``host:port`` or ``ray://…``); None: the Ray session of this
        process if there is one, else a local Ray with this machine's cores.
    hyperparams : Path
        The learners' hyperparameter file of the base entry
        (``agents/training/hyperparams/learners.json``).

    Returns
    -------
    dict
        The content of ``tune.json``.
    """
    if learner not in SEARCHED:
        raise AeromagError(_refusal(learner))
    check_output_set(out, OUTPUTS, [space_path, hyperparams])
    samples = sized(samples, SAMPLES, quick, QUICK.tune_samples)
    space = read_learner_space(learner, space_path)
    hp = learner_settings(learner, hyperparams, quick=quick, timesteps=timesteps)
    hp = hp.with_values(prefetch=False)  # a CPU a trial
    job = LearnerTuneJob(learner=learner, hp=hp, seed=seed)
    t0 = time.perf_counter()
    with ray_session(ray_address) as ray:
        trials = run_search(
            run_learner_trial,
            job,
            space,
            samples=samples,
            seed=seed,
            metric=METRIC,
            max_t=max_reports(hp),
            grace=GRACE,
            record=lambda result: _record(result, list(space), hp.timesteps),
        )
        cpus = int(ray.cluster_resources().get("CPU", 1))
    best = best_trial(trials, "best_validation_score")
    summary = {
        "learner": learner,
        "samples": samples,
        "timesteps": hp.timesteps,
        "seed": seed,
        "quick": quick,
        "metric": METRIC,
        "select_by": hp.select_by,
        "eval_every": hp.eval_every,
        "validation_episodes": hp.eval_episodes,
        "reduction_factor": REDUCTION,
        "space_file": recorded_path(space_path),
        "space": space,
        "hyperparams": recorded_path(hyperparams),
        "cpus": cpus,
        "seconds": time.perf_counter() - t0,
        "best": best,
        "trials": trials,
    }
    table = _tuned_table(Path(hyperparams), learner, summary)
    write_outputs(
        out,
        OUTPUTS,
        [space_path, hyperparams],
        table,
        lambda path: learner_hyperparams(learner, path),
        summary,
    )
    return summary


def _refusal(learner: str) -> str:
    if learner == "cmaes":
        return (
            "aeromag tune does not search cmaes: CMA-ES is itself a search, with no "
            "stable-baselines3 constructor parameters to sample; --learner takes ppo, "
            f"{', '.join(SEARCHED)}"
        )
    if learner == "ppo":
        return (
            "tune_learner searches the other learners; PPO's search is agents.search.ppo.tune_ppo"
        )
    return f"unknown learner {learner!r}; aeromag tune --learner searches {', '.join(SEARCHED)}"


def max_reports(hp: LearnerHyperparams) -> int:
    """The most validations a run of ``hp`` reports, ASHA's ``max_t``: one at step 0, one every
    ``eval_every`` steps, one at the end (an on-policy learner's last rollout may overshoot
    ``timesteps``, past one more ``eval_every``)."""
    return 2 + math.ceil(hp.timesteps / hp.eval_every)


def run_learner_trial(config: dict[str, Any], job: LearnerTuneJob) -> None:
    """One Tune trial: ``job.learner`` trained with ``job.hp``, the sampled ``config``
    replacing keys of its ``algo``, reporting each validation point's selection score."""
    from ray import tune

    hp = job.hp.with_values(algo=plain(config))
    best = math.inf

    def report(point: dict[str, Any]) -> None:
        nonlocal best
        score = selection_score(point)
        if point["timesteps"] > 0:  # step 0 is the untrained policy, alike in every trial
            best = min(best, score)
        tune.report(
            {
                METRIC: score,
                "best_validation_score": best if best < math.inf else None,  # none trained yet
                "validation_rmse_nt": point["validation_rmse_nt"],
                "timesteps": point["timesteps"],
            }
        )

    with tempfile.TemporaryDirectory(prefix="aeromag-trial-") as tmp:
        run_learner(job.learner, hp, job.seed, Path(tmp), on_validation=report)


def _record(result: Any, keys: list[str], timesteps: int) -> dict[str, Any]:
    """A trial's line of ``tune.json``."""
    fields, metrics = trial_fields(result, keys)
    error = fields.pop("error")
    reached = int(metrics.get("timesteps", 0))
    return {
        **fields,
        "timesteps": reached,
        "last_validation_score": metrics.get(METRIC),  # None: no validation (an error)
        "best_validation_score": metrics.get("best_validation_score"),
        "last_validation_rmse_nt": metrics.get("validation_rmse_nt"),
        "stopped_by_asha": error is None and reached < timesteps,
        "error": error,
    }


def _tuned_table(hyperparams: Path, learner: str, summary: dict[str, Any]) -> dict[str, Any]:
    """The base learners file with ``learner``'s ``algo`` the best trial's values over the base
    (the entry's algo under the file's ``common``) and its ``comment`` saying how."""
    best = summary["best"]
    table = json.loads(hyperparams.read_text(encoding="utf-8"))
    entry = table["learners"][learner]
    algo = learner_hyperparams(learner, hyperparams).algo.model_dump(exclude_unset=True)
    entry["algo"] = {**algo, **best["config"]}
    quick = ", quick sizes" if summary["quick"] else ""
    note = (
        f"Tuned by aeromag tune --learner {learner}: {', '.join(best['config'])} of trial "
        f"{best['trial']} (best validation score {best['best_validation_score']:.4g}, "
        f"{summary['select_by']}, on {summary['validation_episodes']} validation flights) among "
        f"{len(summary['trials'])} trials of {summary['timesteps']} timesteps each, seed "
        f"{summary['seed']}{quick}; the other keys from {summary['hyperparams']}. tune.json "
        f"beside this file has every trial."
    )
    entry["comment"] = f"{note} {entry['comment']}" if "comment" in entry else note
    return dict(table)
