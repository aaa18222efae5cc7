"""What every tuning policy is: stable-baselines3's ``predict`` shape.

One evaluation loop (:func:`agents.evaluation.episodes.run_episode`) serves every policy, learned or
hand-written, and a stable-baselines3 model fits it as it is.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import numpy as np

#: What a policy keeps between calls in stable-baselines3's ``state`` slot (None: nothing).
State = Any


@runtime_checkable
class TuningPolicy(Protocol):
    """A policy that tunes the compensator's Q and R from the environment's observations."""

    def predict(
        self,
        obs: np.ndarray,
        state: State = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, State]:
        """Actions for observations.

        Parameters
        ----------
        obs : (n_obs,) one observation, or (N, n_obs) one per environment
        state : what the previous call returned (None at the start)
        episode_start : (N,) bool, True where an episode has just started (None: no news)
        deterministic : the mean action (learned policies; the others are deterministic)

        Returns
        -------
        actions : (n_act,) or (N, n_act) float32 in [-1, 1]
        state : to pass to the next call
        """
        ...
