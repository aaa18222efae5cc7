"""Evaluate tuning policies on the same flights: one episode (:func:`run_episode`), every policy
on the same test seeds of each scenario (:func:`evaluate_scenarios`, here or as tasks of a
runner), and one flight's Q/R actions per policy (:func:`action_traces`). The statistics of the
results are :mod:`agents.evaluation.statistics`; the seed ranges :mod:`agents.evaluation.seeds`
(:func:`evaluate` refuses seeds below :data:`~agents.evaluation.seeds.TEST_SEED_START`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np

from aeromag_env.environment.ids import register_all
from aeromag_env.environment.scenarios import SCENARIOS, TRAINING_SCENARIOS, check_scenario
from aeromag_env.errors import AeromagError
from aeromag_env.parallel import Runner, SerialRunner, Task, failures
from agents.evaluation.seeds import TEST_SEED_START
from agents.evaluation.statistics import normalized_scores, policy_summaries
from agents.policies import make_policy, policy_env_kwargs
from agents.policies.baselines import BasePolicy
from agents.policies.protocol import TuningPolicy

register_all()  # the environment ids gym.make reads (a second call does nothing)

#: Flights per task when evaluation runs on Ray (one task per policy here).
CHUNK = 8


def run_episode(
    env: gym.Env, policy: TuningPolicy, seed: int, trace: list[dict[str, Any]] | None = None
) -> dict[str, float]:
    """One episode (reset with the policy's ``reset_options``, if it has any); returns ``rmse_nt``
    (truth, after ``score_from``), ``reward``, ``divergences``, ``outliers_rejected``
    (samples the filter's outlier gate skipped) and ``log_ror_abs_median`` (|log10 ROR| over
    the scored part). With ``trace``, each step's info dict is appended to it."""
    options = dict(policy.reset_options) if isinstance(policy, BasePolicy) else None
    obs, _ = env.reset(seed=seed, options=options or None)
    inner: Any = env.unwrapped
    state, start, done, total = None, np.array([True]), False, 0.0
    log_ror: list[float] = []
    score_from = inner.config.score_from
    while not done:
        action, state = policy.predict(obs, state=state, episode_start=start, deterministic=True)
        obs, reward, terminated, truncated, info = env.step(action)
        start = np.array([False])
        total += float(reward)
        done = terminated or truncated
        if trace is not None:
            trace.append(info)
        if info["sample"] >= score_from * inner.episode.n and np.isfinite(info["ror"]):
            log_ror.append(abs(np.log10(info["ror"])) if info["ror"] > 0 else np.inf)
    return {
        "rmse_nt": float(info["episode_rmse_nt"]),
        "reward": float(total),
        "divergences": int(info["divergences"]),
        "outliers_rejected": int(info["outliers_rejected"]),
        "log_ror_abs_median": float(np.median(log_ror)) if log_ror else float("nan"),
    }


def action_traces(
    scenario: str, policies: Sequence[str], seed: int
) -> dict[str, dict[str, np.ndarray]]:
    """One flight (``seed``) of ``scenario`` under each policy: ``t`` (k,) [s] after each
    decision, the cumulative ``q_scale`` and ``r_scale`` (k,) [-] the policy set, ``seed``
    (the Q/R actions of ``report.html``)."""
    from agents.policies import make_policy, policy_env_kwargs

    traces = {}
    for name in policies:
        env = gym.make("AeroMagCompensation-v0", scenario=scenario, **policy_env_kwargs(name))
        steps: list[dict[str, Any]] = []
        run_episode(env, make_policy(name, env), seed, trace=steps)
        inner: Any = env.unwrapped
        tt = inner.episode.flight.tt
        env.close()
        t = np.array([tt[min(info["sample"], tt.size - 1)] for info in steps], dtype=float)
        q = np.array([info["q_scale"] for info in steps], dtype=float)
        r = np.array([info["r_scale"] for info in steps], dtype=float)
        traces[name] = {"t": t, "q_scale": q, "r_scale": r, "seed": np.array([seed])}
    return traces


def evaluate(
    scenario: str,
    policies: Sequence[str],
    seeds: Sequence[int],
    env_kwargs: dict[str, Any] | None = None,
    progress: Any = None,
    runner: Runner | None = None,
) -> dict[str, Any]:
    """Every policy on the same seeds; ``results.json`` layout of ``aeromag evaluate``.

    ``scenario`` is one of :data:`~aeromag_env.environment.scenarios.SCENARIOS`; a training-only
    one (:data:`~aeromag_env.environment.scenarios.TRAINING_SCENARIOS`) is refused. See
    :func:`evaluate_scenarios` for ``runner`` and ``progress``.
    """
    return evaluate_scenarios([scenario], policies, seeds, env_kwargs, progress, runner)[scenario]


def evaluate_scenarios(
    scenarios: Sequence[str],
    policies: Sequence[str],
    seeds: Sequence[int],
    env_kwargs: dict[str, Any] | None = None,
    progress: Any = None,
    runner: Runner | None = None,
) -> dict[str, dict[str, Any]]:
    """:func:`evaluate` for each scenario, all episodes submitted together.

    The episodes run as tasks of ``runner`` (default: here, one task per scenario and policy;
    on Ray, chunks of at most :data:`CHUNK` flights); each episode depends only on its seed,
    scenario and policy, so the results are the same bit for bit whatever ran them.
    ``progress(k)`` counts episodes done.
    """
    for scenario in scenarios:
        check_scenario(scenario)
        if scenario in TRAINING_SCENARIOS:
            raise AeromagError(
                f"scenario {scenario!r} is for training only; evaluate one of "
                f"{', '.join(SCENARIOS)}"
            )
    if not seeds:
        raise AeromagError("evaluation needs at least one seed")
    if min(seeds) < TEST_SEED_START:
        raise AeromagError(
            f"evaluation seeds must be ≥ {TEST_SEED_START} (training and validation use the "
            f"seeds below); got {min(seeds)}"
        )
    per = _run_policies(scenarios, policies, seeds, env_kwargs or {}, progress, runner)
    return {scenario: _results(scenario, seeds, per[scenario]) for scenario in scenarios}


def _results(
    scenario: str, seeds: Sequence[int], per: dict[str, dict[str, np.ndarray]]
) -> dict[str, Any]:
    summaries = policy_summaries(per)
    results: dict[str, Any] = {"scenario": scenario, "seeds": list(seeds), "policies": summaries}
    score = normalized_scores(per)
    if score is not None:
        results["normalized_score"] = score.pop("anchors")
        for name, row in score.items():
            summaries[name].update(row)
    return results


def policy_rows(
    scenario: str, name: str, seeds: Sequence[int], env_kwargs: dict[str, Any]
) -> dict[str, list[float]]:
    """Policy ``name`` on ``seeds`` of ``scenario`` (one task): :func:`run_episode`'s figures,
    a list per figure in seed order. The same flights for every policy: the env settings a
    policy was trained with (PPO's observation layout and action mode) change only the
    interface, not the flight."""
    env = gym.make(
        "AeroMagCompensation-v0", scenario=scenario, **{**env_kwargs, **policy_env_kwargs(name)}
    )
    policy = make_policy(name, env)
    rows = [run_episode(env, policy, seed) for seed in seeds]
    env.close()
    return {k: [r[k] for r in rows] for k in rows[0]}


def _run_policies(
    scenarios: Sequence[str],
    policies: Sequence[str],
    seeds: Sequence[int],
    env_kwargs: dict[str, Any],
    progress: Any,
    runner: Runner | None,
) -> dict[str, dict[str, dict[str, np.ndarray]]]:
    """Every (scenario, policy, chunk of seeds) as a task of ``runner``; the figures per
    scenario and policy, in seed order."""
    runner = runner or SerialRunner()
    size = len(seeds) if isinstance(runner, SerialRunner) else CHUNK
    chunks = [list(seeds[i : i + size]) for i in range(0, len(seeds), size)]
    keys = [(s, name) for s in scenarios for name in policies]
    tasks = [
        Task(f"{s}/{name} seeds {c[0]}–{c[-1]}", policy_rows, (s, name, c, env_kwargs))
        for s, name in keys
        for c in chunks
    ]
    outcomes = runner.run(
        tasks,
        None if progress is None else lambda o: progress(len(o.value["rmse_nt"]) if o.ok else 0),
    )
    for o in failures(outcomes):  # the first failed task, after the others completed
        if isinstance(o.exception, AeromagError):  # an input error: one line, with its input
            raise type(o.exception)(f"{o.label}: {o.exception}") from None
        raise o.exception or AeromagError(f"{o.label}: {o.error}")  # a bug (exit 1), or lost
    per: dict[str, dict[str, dict[str, np.ndarray]]] = {s: {} for s in scenarios}
    for i, (s, name) in enumerate(keys):
        parts = [o.value for o in outcomes[i * len(chunks) : (i + 1) * len(chunks)]]
        per[s][name] = {
            k: np.array([v for p in parts for v in p[k]], dtype=float) for k in parts[0]
        }
    return per
