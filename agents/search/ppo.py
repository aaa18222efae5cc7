"""Search PPO hyperparameters with Ray Tune (``aeromag tune``): random samples of a search
space (:mod:`agents.search.space`), each a trial that trains PPO as ``aeromag train`` does
(:mod:`agents.training.ppo`), with ASHA stopping the trials that validate badly early.

A trial trains in :data:`REPORTS` chunks of ``timesteps / REPORTS`` environment steps and, after
each, validates the policy so far on the first ``eval_episodes`` seeds of the validation range
(``[50 000, 100 000)``; never a test seed) and reports the mean RMSE [nT] to Tune; ASHA
(``ray.tune.schedulers.ASHAScheduler``, counted in reports) compares the trials at its rungs and
stops the worse half. Every trial trains with the same seed (the same training flights: the
trials differ by their hyperparameters only), deterministically, on one CPU (no prefetching
worker). The search itself is seeded (the samples are the same for the same ``--seed``).

The outputs, written as a set: ``ppo.json``, a hyperparameter file (the schema of
``agents/training/hyperparams/ppo.json``, validated after writing) whose entry for the scenario is
the base entry with the tuned keys of the best trial (lowest validation RMSE reported), ready for
``aeromag train --hyperparams``; and ``tune.json``, every trial (its configuration, last and
best validation RMSE, reports, whether ASHA stopped it). The search machinery (:func:`ray_session`,
:func:`run_search`, :func:`best_trial`, :func:`write_outputs`) serves the other learners' search
too (:mod:`agents.search.learners`). Ray is imported here and there only (extra ray).
"""

from __future__ import annotations

import contextlib
import io
import json
import logging
import math
import tempfile
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from aeromag_env.atomic import check_output_set, output_set, write_text
from aeromag_env.errors import AeromagError
from aeromag_env.parallel.tasks import one_line
from aeromag_env.threads import cores
from agents.search.space import plain, read_space, recorded_path, tune_domains
from agents.training.hyperparameters import PPOHyperparams
from agents.training.hyperparams_file import read_hyperparams
from agents.training.ppo import HYPERPARAMS, load_hyperparams, training_torch
from agents.training.quick import QUICK, quick_hyperparams, sized
from agents.training.validation import validation_seeds

#: The outputs in ``--out``, written as a set.
OUTPUTS = ("ppo.json", "tune.json")
#: What Tune minimises: the mean validation RMSE of the policy so far [nT].
METRIC = "validation_rmse_nt"
#: Validations per trial (``--quick``: ``QUICK.tune_reports``); ASHA's time unit.
REPORTS = 8
#: Trials and environment steps per trial by default (``--quick``: ``QUICK``'s).
SAMPLES, TIMESTEPS = 16, 500_000
#: ASHA's rungs: first after this many reports, then every ``REDUCTION``-fold; it keeps the
#: best ``1 / REDUCTION`` of the trials at each rung.
GRACE, REDUCTION = 1, 2


@dataclass(frozen=True, kw_only=True)
class TuneJob:
    """What every trial shares: the scenario, the base hyperparameters (the sampled keys
    replace theirs), the training seed, the environment steps and validations per trial."""

    scenario: str
    hp: PPOHyperparams
    seed: int
    timesteps: int
    reports: int


def tune_ppo(
    scenario: str,
    space_path: Path,
    samples: int | None,
    timesteps: int | None,
    out: Path,
    *,
    seed: int = 0,
    quick: bool = False,
    ray_address: str | None = None,
    hyperparams: Path = HYPERPARAMS,
) -> dict[str, Any]:
    """Run the search; write ``out/ppo.json`` and ``out/tune.json``; return the summary.

    Parameters
    ----------
    scenario : str
        The scenario whose entry of ``hyperparams`` is tuned (and validated on).
    space_path : Path
        The search space (:func:`agents.search.space.read_space`).
    samples : int or None
        Trials (configurations drawn); None: :data:`SAMPLES` (``quick``: ``QUICK``'s).
    timesteps : int or None
        Environment steps per trial (ASHA stops bad trials earlier); None: :data:`TIMESTEPS`
        (``quick``: ``QUICK``'s).
    out : Path
        Output folder.
    seed : int
        Seed of the sampling and of every trial's training.
    quick : bool
        The sizes of :data:`agents.training.quick.QUICK` (about a minute): its samples and timesteps
        unless given, tiny rollouts, a few validations on 2 flights each.
    ray_address : str or None
        A Ray cluster to join (``host:port`` or ``ray://…``); None: the Ray session of this
        process if there is one, else a local Ray with this machine's cores.
    hyperparams : Path
        The hyperparameter file of the base entry.

    Returns
    -------
    dict
        The content of ``tune.json``.
    """
    check_output_set(out, OUTPUTS, [space_path, hyperparams])
    samples = sized(samples, SAMPLES, quick, QUICK.tune_samples)
    timesteps = sized(timesteps, TIMESTEPS, quick, QUICK.tune_timesteps)
    space = read_space(space_path)
    job = _job(scenario, hyperparams, seed, timesteps, quick)
    t0 = time.perf_counter()
    with ray_session(ray_address) as ray:
        trials = run_search(
            run_trial,
            job,
            space,
            samples=samples,
            seed=seed,
            metric=METRIC,
            max_t=job.reports,
            grace=GRACE,
            record=lambda result: _record(result, list(space), job),
        )
        cpus = int(ray.cluster_resources().get("CPU", 1))
    best = best_trial(trials, "best_validation_rmse_nt")
    summary = {
        "scenario": scenario,
        "samples": samples,
        "timesteps": timesteps,
        "seed": seed,
        "quick": quick,
        "reports_per_trial": job.reports,
        "metric": METRIC,
        "validation_episodes": job.hp.eval_episodes,
        "space_file": recorded_path(space_path),
        "space": space,
        "hyperparams": recorded_path(hyperparams),
        "cpus": cpus,
        "seconds": time.perf_counter() - t0,
        "best": best,
        "trials": trials,
    }
    entry = {**read_hyperparams(hyperparams)["scenarios"][scenario], **best["config"]}
    table = _tuned_table(entry, summary, Path(hyperparams))
    write_outputs(out, OUTPUTS, [space_path, hyperparams], table, read_hyperparams, summary)
    return summary


def _job(scenario: str, hyperparams: Path, seed: int, timesteps: int, quick: bool) -> TuneJob:
    hp = load_hyperparams(scenario, hyperparams).with_values(prefetch=False)  # a CPU a trial
    if quick:
        hp = quick_hyperparams(hp)
    reports = min(REPORTS, QUICK.tune_reports) if quick else REPORTS
    return TuneJob(scenario=scenario, hp=hp, seed=seed, timesteps=timesteps, reports=reports)


@contextlib.contextmanager
def ray_session(address: str | None) -> Iterator[Any]:
    """Yield the ``ray`` module, initialised: the session already running in this process (left
    running), else one joining ``address`` or, for None, a local one with this machine's cores
    (shut down on exit)."""
    try:
        import ray
    except ImportError:
        raise AeromagError(
            "aeromag tune needs the ray extra: pip install 'aeromag-env[ray]'"
        ) from None
    started = False
    if not ray.is_initialized():
        kwargs: dict[str, Any] = {
            "include_dashboard": False,
            "log_to_driver": False,
            "logging_level": logging.ERROR,
        }
        if address is None:  # "local": a new Ray, not another process's found in /tmp/ray
            kwargs["num_cpus"] = cores()
        try:
            ray.init(address=address or "local", **kwargs)
        except (ConnectionError, RuntimeError, ValueError) as e:
            where = address or "this machine"
            raise AeromagError(f"cannot start or join Ray at {where}: {one_line(e)}") from None
        started = True
    try:
        yield ray
    finally:
        if started:
            ray.shutdown()


def run_search(
    trial: Callable[[dict[str, Any], Any], None],
    job: Any,
    space: dict[str, Any],
    *,
    samples: int,
    seed: int,
    metric: str,
    max_t: int,
    grace: int,
    record: Callable[[Any], dict[str, Any]],
) -> list[dict[str, Any]]:
    """Run ``samples`` trials ``trial(config, job)`` on Ray Tune, each on one CPU, ``config``
    drawn from ``space`` (:func:`agents.search.space.tune_domains`; seeded by ``seed``), ``metric``
    minimised, ASHA counting reports (first rung after ``grace``, at most ``max_t``); one
    ``record(result)`` per trial, in the order they were drawn."""
    from ray import tune
    from ray.tune.schedulers import ASHAScheduler
    from ray.tune.search.basic_variant import BasicVariantGenerator

    trainable = tune.with_resources(tune.with_parameters(trial, job=job), {"cpu": 1})
    scheduler = ASHAScheduler(max_t=max_t, grace_period=grace, reduction_factor=REDUCTION)
    with tempfile.TemporaryDirectory(prefix="aeromag-tune-") as storage:
        search = BasicVariantGenerator(random_state=seed)
        config = tune.TuneConfig(
            metric=metric, mode="min", num_samples=samples, scheduler=scheduler, search_alg=search
        )
        run = tune.RunConfig(name="aeromag-tune", storage_path=storage, verbose=0)
        tuner = tune.Tuner(
            trainable, param_space=tune_domains(space), tune_config=config, run_config=run
        )
        with contextlib.redirect_stdout(io.StringIO()):  # Tune's banner prints even at verbose 0
            grid = tuner.fit()
        return [record(grid[i]) for i in range(len(grid))]  # the error files are in storage


def trial_fields(result: Any, keys: list[str]) -> tuple[dict[str, Any], dict[str, Any]]:
    """A trial's first fields of ``tune.json`` (its id, the sampled ``keys``, its reports and
    its error as one line, or None) and its last reported metrics."""
    metrics = result.metrics or {}
    error = None if result.error is None else one_line(result.error)
    fields = {
        "trial": metrics.get("trial_id", Path(result.path).name),
        "config": plain({k: result.config[k] for k in keys}),
        "reports": int(metrics.get("training_iteration", 0)),
        "error": error,
    }
    return fields, metrics


def _record(result: Any, keys: list[str], job: TuneJob) -> dict[str, Any]:
    """A trial's line of ``tune.json``."""
    fields, metrics = trial_fields(result, keys)
    error = fields.pop("error")
    return {
        **fields,
        "timesteps": int(metrics.get("timesteps", 0)),
        "last_validation_rmse_nt": metrics.get(METRIC),  # None: no validation (an error)
        "best_validation_rmse_nt": metrics.get("best_validation_rmse_nt"),
        "validation_seeds": metrics.get("validation_seeds"),
        "stopped_by_asha": error is None and fields["reports"] < job.reports,
        "error": error,
    }


def best_trial(trials: list[dict[str, Any]], key: str) -> dict[str, Any]:
    """The trial with the lowest ``key`` (the best score it reported)."""
    done = [t for t in trials if t[key] is not None]
    if not done:
        errors = [t["error"] for t in trials if t["error"]]
        raise AeromagError(
            "no trial of aeromag tune finished a validation" + (f": {errors[0]}" if errors else "")
        )
    return min(done, key=lambda t: t[key])


def run_trial(config: dict[str, Any], job: TuneJob) -> None:
    """One Tune trial: PPO with ``job.hp`` and the sampled ``config``, validated and reported
    to Tune :data:`REPORTS` times (pretrained first when the entry says so, as in training)."""
    from ray import tune

    from agents.training.imitation import behaviour_clone
    from agents.training.ppo import make_ppo, make_training_env

    hp = job.hp.with_values(**plain(config))
    best = math.inf
    with training_torch(), tempfile.TemporaryDirectory(prefix="aeromag-trial-") as tmp:
        venv = make_training_env(job.scenario, hp, job.seed)
        try:
            model = make_ppo(venv, hp, job.seed)
            if hp.pretrain is not None:
                behaviour_clone(model, venv, hp, job.scenario, job.seed)
            for i in range(1, job.reports + 1):
                target = job.timesteps * i // job.reports
                model.learn(max(1, target - model.num_timesteps), reset_num_timesteps=False)
                rmse = _validate(model, venv, hp, job, Path(tmp))
                best = min(best, rmse)
                seeds = validation_seeds(hp.eval_episodes)
                tune.report(
                    {
                        METRIC: rmse,
                        "best_validation_rmse_nt": best,
                        "timesteps": int(model.num_timesteps),
                        "validation_seeds": [seeds[0], seeds[-1]],
                    }
                )
        finally:
            venv.close()


def _validate(model: Any, venv: Any, hp: PPOHyperparams, job: TuneJob, tmp: Path) -> float:
    """Mean RMSE [nT] of the policy so far on the validation flights, through its numpy export
    (the policy ``aeromag train`` would keep)."""
    from agents.policies.numpy_policy import NumpyPPOPolicy
    from agents.policies.policy_file import export_policy
    from agents.training.validation import validation_rmse

    meta = {
        "scenario": job.scenario,
        "env_kwargs": dict(hp.env_kwargs),
        "seed": job.seed,
        "timesteps": int(model.num_timesteps),
        "hyperparams_version": hp.version,
    }
    policy = NumpyPPOPolicy.load(export_policy(model, venv, tmp / "candidate.npz", meta))
    return float(validation_rmse(policy, job.scenario, hp.eval_episodes).mean())


def _tuned_table(
    entry: dict[str, Any], summary: dict[str, Any], hyperparams: Path
) -> dict[str, Any]:
    """The hyperparameter file of the tuned entry (the base file ``hyperparams``'s version)."""
    best = summary["best"]
    comment = (
        f"Tuned by aeromag tune on {summary['scenario']}: {', '.join(best['config'])} of trial "
        f"{best['trial']} (best validation RMSE {best['best_validation_rmse_nt']:.4g} nT on "
        f"{summary['validation_episodes']} validation flights) among {len(summary['trials'])}, "
        f"{summary['timesteps']} timesteps each, seed {summary['seed']}; the other keys from "
        f"{summary['hyperparams']}. tune.json beside this file has every trial."
    )
    version = read_hyperparams(hyperparams)["version"]
    return {"version": version, "comment": comment, "scenarios": {summary["scenario"]: entry}}


def write_outputs(
    out: Path,
    outputs: tuple[str, str],
    inputs: list[Path],
    table: dict[str, Any],
    check: Callable[[Path], Any],
    summary: dict[str, Any],
) -> None:
    """The hyperparameter file ``outputs[0]`` (``table``, read back with ``check`` as training
    will read it) and ``outputs[1]`` (``summary``), as a set."""
    with output_set(out, outputs, inputs) as stage:
        write_text(stage / outputs[0], json.dumps(table, indent=2) + "\n")
        check(stage / outputs[0])
        write_text(stage / outputs[1], json.dumps(summary, indent=2) + "\n")
