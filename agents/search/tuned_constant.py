"""The ``tuned_constant`` baseline: the best constant Q and R scales, found offline on training
seeds by a grid search (log10 steps), stored in ``agents/policies/tuned_constants.json`` (read by
:mod:`agents.policies.tuned_table`).

Rebuild with ``python experiments/tune_constants.py --out agents/policies/tuned_constants.json``
(the file records the grid and seeds; without ``--out`` the table goes to ``results/``).
"""

from __future__ import annotations

from collections.abc import Sequence
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


def tune_constant(
    scenario: str,
    seeds: Sequence[int],
    log10_q: Sequence[float] = LOG10_Q_GRID,
    log10_r: Sequence[float] = LOG10_R_GRID,
) -> dict[str, Any]:
    """Grid search of the constant scales minimising the mean episode RMSE on ``seeds``."""
    if max(seeds) >= TRAIN_SEEDS.stop:
        raise AeromagError(f"tuning seeds must be training seeds (< {TRAIN_SEEDS.stop})")
    env = gym.make("AeroMagCompensation-v0", scenario=scenario)
    policy = TargetScalePolicy(env)
    scores = np.full((len(log10_q), len(log10_r)), np.nan)
    for i, q in enumerate(log10_q):
        for j, r in enumerate(log10_r):
            policy.log_q, policy.log_r = q * np.log(10.0), r * np.log(10.0)
            scores[i, j] = np.mean([run_episode(env, policy, s)["rmse_nt"] for s in seeds])
    i, j = (int(v) for v in np.unravel_index(np.nanargmin(scores), scores.shape))
    return {
        "log10_q": log10_q[i],
        "log10_r": log10_r[j],
        "rmse_nt": float(scores[i, j]),
        "seeds": list(seeds),
        "grid_log10_q": list(log10_q),
        "grid_log10_r": list(log10_r),
    }
