"""The ``tuned_constant`` baselines: the best constant Q and R scales, found offline on training
seeds by a grid search (log10 steps).

* Per scenario (:func:`tune_constant`): the scales minimising the scenario's mean episode RMSE,
  stored in ``agents/policies/tuned_constants.json`` (read by :mod:`agents.policies.tuned_table`
  for the ``tuned_constant`` policy, which looks the scenario up by name). Rebuild with
  ``python experiments/tune_constants.py --out agents/policies/tuned_constants.json``.
* One for the whole suite (:func:`tune_constant_suite`): the scales minimising
  :func:`suite_objective` over every scenario's grid at once, stored in
  ``agents/policies/tuned_constant_suite.json`` for the scenario-blind
  ``tuned_constant_suite`` policy. Rebuild with ``python experiments/tune_constants.py --suite
  --out agents/policies/tuned_constant_suite.json``.

Both files record the grid and the seeds; the suite's records every scenario's grid of mean
RMSEs, so that another objective can be read from it without flying again.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np

from aeromag_env.environment.ids import register_all
from aeromag_env.errors import AeromagError
from agents.evaluation.episodes import run_episode
from agents.evaluation.seeds import TRAIN_SEEDS
from agents.policies.baselines import TargetScalePolicy

register_all()  # the environment ids gym.make reads (a second call does nothing)

#: Wide enough for the paper's R(0), 2e5× too small, and Q(0), far too large.
LOG10_Q_GRID = tuple(float(v) for v in np.arange(-10.0, 6.01, 1.0))
LOG10_R_GRID = tuple(float(v) for v in np.arange(-2.0, 6.01, 1.0))
#: How the suite's constant is scored over the scenarios (:func:`suite_objective`).
SUITE_OBJECTIVE = (
    "mean over the scenarios of ln(mean episode RMSE); equivalently the geometric mean over the "
    "scenarios of the RMSE ratio to the scenario's own best cell of the same grid"
)


def _check_training(seeds: Sequence[int]) -> None:
    if not seeds:
        raise AeromagError("tuning needs at least one training seed")
    if min(seeds) < TRAIN_SEEDS.start or max(seeds) >= TRAIN_SEEDS.stop:
        raise AeromagError(
            f"tuning seeds must be training seeds ({TRAIN_SEEDS.start} ≤ seed < {TRAIN_SEEDS.stop})"
        )


def grid_rmse(
    scenario: str,
    seeds: Sequence[int],
    log10_q: Sequence[float] = LOG10_Q_GRID,
    log10_r: Sequence[float] = LOG10_R_GRID,
    progress: Callable[[int], None] | None = None,
) -> np.ndarray:
    """The mean episode RMSE [nT] on ``seeds`` of ``scenario`` of every constant scale pair:
    shape ``(len(log10_q), len(log10_r))``, the scales held from the first step on
    (:class:`~agents.policies.baselines.TargetScalePolicy`). ``progress(k)`` counts cells."""
    _check_training(seeds)
    env = gym.make("AeroMagCompensation-v0", scenario=scenario)
    policy = TargetScalePolicy(env)
    scores = np.full((len(log10_q), len(log10_r)), np.nan)
    for i, q in enumerate(log10_q):
        for j, r in enumerate(log10_r):
            policy.log_q, policy.log_r = q * np.log(10.0), r * np.log(10.0)
            scores[i, j] = np.mean([run_episode(env, policy, s)["rmse_nt"] for s in seeds])
            if progress is not None:
                progress(1)
    env.close()
    return scores


def tune_constant(
    scenario: str,
    seeds: Sequence[int],
    log10_q: Sequence[float] = LOG10_Q_GRID,
    log10_r: Sequence[float] = LOG10_R_GRID,
) -> dict[str, Any]:
    """Grid search of the constant scales minimising the mean episode RMSE on ``seeds``."""
    scores = grid_rmse(scenario, seeds, log10_q, log10_r)
    i, j = (int(v) for v in np.unravel_index(np.nanargmin(scores), scores.shape))
    return {
        "log10_q": log10_q[i],
        "log10_r": log10_r[j],
        "rmse_nt": float(scores[i, j]),
        "seeds": list(seeds),
        "grid_log10_q": list(log10_q),
        "grid_log10_r": list(log10_r),
    }


def suite_objective(grids: dict[str, np.ndarray]) -> np.ndarray:
    """The suite's score of every cell (lower is better): the mean over the scenarios of
    ``ln(mean RMSE)`` (:data:`SUITE_OBJECTIVE`).

    Every scenario weighs the same in relative terms: losing 10 % on ``paper`` (errors of
    ~1–20 nT) counts as much as losing 10 % on ``nominal`` (~1.7 nT), where a mean of RMSEs
    would let the scenarios with the largest errors choose alone. Subtracting each scenario's
    own best ``ln RMSE`` (a constant per scenario) does not move the minimum, so the chosen
    cell also minimises the geometric mean of the ratios to each scenario's own best constant.
    A cell that is not finite on some scenario (a diverged run) scores ``inf``.
    """
    logs = np.stack([np.log(g) for g in grids.values()])
    with np.errstate(invalid="ignore"):
        total = logs.mean(axis=0)
    return np.where(np.isfinite(total), total, np.inf)


def reach_log10(scenario: str = "nominal") -> float:
    """How far, in decades, the tuning environment's default action layout lets a constant move
    Q and R from Q(0) and R(0): ``log10(action.scale_limit)``. A cell of the grid beyond it
    is flown at the limit (the environment clamps the scales), so it is the limit's cell."""
    env = gym.make("AeroMagCompensation-v0", scenario=scenario)
    inner: Any = env.unwrapped
    limit = float(np.log10(inner.config.action.scale_limit))
    env.close()
    return limit


def tune_constant_suite(
    scenarios: Sequence[str],
    seeds: Sequence[int],
    log10_q: Sequence[float] = LOG10_Q_GRID,
    log10_r: Sequence[float] = LOG10_R_GRID,
    progress: Callable[[str, int], None] | None = None,
) -> dict[str, Any]:
    """One constant Q and R scale pair for every scenario of ``scenarios``: the grid cell with
    the lowest :func:`suite_objective` over the mean episode RMSEs on ``seeds`` of each, among
    the cells the environment reaches (:func:`choose_suite`).

    Returns
    -------
    dict
        :func:`choose_suite`'s record, with ``seeds``.
    """
    if not scenarios:
        raise AeromagError("the suite's constant needs at least one scenario")
    _check_training(seeds)
    grids = {}
    for s in scenarios:
        step = None if progress is None else (lambda k, s=s: progress(s, k))
        grids[s] = grid_rmse(s, seeds, log10_q, log10_r, step)
    return {**choose_suite(grids, log10_q, log10_r, reach_log10()), "seeds": list(seeds)}


def choose_suite(
    grids: dict[str, np.ndarray],
    log10_q: Sequence[float],
    log10_r: Sequence[float],
    reach: float,
) -> dict[str, Any]:
    """The suite's constant from every scenario's grid of mean RMSEs (rows Q, columns R): the
    cell with the lowest :func:`suite_objective` among those within ``reach`` decades of Q(0)
    and R(0) (the environment clamps the scales beyond it: such a cell repeats the limit's,
    and a policy could not hold it); the first such cell on a tie.

    Returns
    -------
    dict
        ``log10_q``, ``log10_r`` (the choice), ``objective`` (its score and
        :data:`SUITE_OBJECTIVE`), ``reach_log10``, ``rmse_nt`` (scenario → the choice's mean
        RMSE [nT]), ``ratio_to_own_best`` (scenario → that over the scenario's best cell [-]),
        ``worst_ratio`` (the largest of those), ``scenarios``, the grids, and ``grid_rmse_nt``
        (scenario → the whole grid).
    """
    score = suite_objective(grids)
    inside = np.abs(np.asarray(log10_q))[:, None] <= reach
    inside = inside & (np.abs(np.asarray(log10_r))[None, :] <= reach)
    score = np.where(inside, score, np.inf)
    if not np.isfinite(score).any():
        raise AeromagError("no cell of the grid is within reach and finite on every scenario")
    i, j = (int(v) for v in np.unravel_index(np.argmin(score), score.shape))
    ratios = {s: float(g[i, j] / np.nanmin(g)) for s, g in grids.items()}
    return {
        "log10_q": float(log10_q[i]),
        "log10_r": float(log10_r[j]),
        "objective": {"value": float(score[i, j]), "definition": SUITE_OBJECTIVE},
        "reach_log10": reach,
        "rmse_nt": {s: float(g[i, j]) for s, g in grids.items()},
        "ratio_to_own_best": ratios,
        "worst_ratio": max(ratios.values()),
        "scenarios": list(grids),
        "grid_log10_q": list(log10_q),
        "grid_log10_r": list(log10_r),
        "grid_rmse_nt": {s: np.asarray(g).tolist() for s, g in grids.items()},
    }
