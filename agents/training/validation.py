"""How a training run scores its validation points: a hyperparameter entry's ``select_by``.

* ``rmse`` (the default): the mean validation RMSE over ``eval_episodes`` flights of the
  entry's scenario.
* ``ratio_to_privileged``: the mean over those flights of the RMSE over the privileged
  policy's on the same flight (each flight counts, not only the loud ones).
* ``worst_ratio_to_tuned_constant``: the validation flights split evenly over the scenarios of
  the suite (:data:`aeromag_env.environment.ids.SUITE`, each on its own validation seeds); per
  scenario the mean ratio of the RMSE to the tuned constant's on the same flights; the score is
  the worst scenario's. The bar for a general policy is "never worse than ``tuned_constant``
  on any scenario", which a mean over flights trades away (a policy chosen by
  ``ratio_to_privileged`` can be far better than the paper's rules on the mean and still worse
  than the tuned constant on one scenario; the lab notebook has the case).

Every reference policy is run once per training run, on the same flights as each candidate.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from aeromag_env.environment.ids import SUITE
from aeromag_env.errors import AeromagError
from agents.evaluation.episodes import run_episode
from agents.evaluation.seeds import VALIDATION_SEEDS

SELECT_BY = ("rmse", "ratio_to_privileged", "worst_ratio_to_tuned_constant")


def validation_rmse(
    policy: Any, scenario: str, episodes: int, env_kwargs: dict[str, Any] | None = None
) -> np.ndarray:
    """Each episode's RMSE on the first ``episodes`` validation seeds [nT]; ``policy`` a
    policy object or a name of :func:`agents.policies.make_policy` (then in ``env_kwargs``)."""
    from agents.policies import make_policy

    kwargs = policy.env_kwargs if env_kwargs is None else env_kwargs
    env = gym.make("AeroMagCompensation-v0", scenario=scenario, **kwargs)
    if isinstance(policy, str):
        policy = make_policy(policy, env)
    return np.array([run_episode(env, policy, s)["rmse_nt"] for s in validation_seeds(episodes)])


def validation_seeds(episodes: int) -> range:
    """The first ``episodes`` seeds of the validation range (never a test seed)."""
    if not 1 <= episodes <= len(VALIDATION_SEEDS):
        n = len(VALIDATION_SEEDS)
        raise AeromagError(f"validation takes 1 to {n} episodes, got {episodes}")
    return range(VALIDATION_SEEDS.start, VALIDATION_SEEDS.start + episodes)


class Validator:
    """Scores candidate policies of one training run by ``select_by`` (module docstring).

    Parameters
    ----------
    select_by : str
        One of :data:`SELECT_BY`.
    scenario : str
        The entry's scenario (its validation flights, except for the per-scenario score).
    episodes : int
        Validation flights in all (split over the suite's scenarios for the per-scenario score,
        at least one each).
    """

    def __init__(self, select_by: str, scenario: str, episodes: int) -> None:
        if select_by not in SELECT_BY:
            raise ValueError(f"select_by must be one of {', '.join(SELECT_BY)}, got {select_by!r}")
        self.select_by, self.scenario, self.episodes = select_by, scenario, episodes
        self._reference: dict[str, np.ndarray] = {}

    def flights(self) -> dict[str, int]:
        """Validation flights per scenario."""
        if self.select_by == "worst_ratio_to_tuned_constant":
            return dict.fromkeys(SUITE, max(self.episodes // len(SUITE), 1))
        return {self.scenario: self.episodes}

    def __call__(self, policy: Any) -> dict[str, Any]:
        """The validation point's fields: ``validation_rmse_nt`` (mean over every flight),
        ``validation_rmse_by_scenario`` (the mean per scenario: a learning curve's normalized
        score is made from it), ``validation_score`` (when ``select_by`` is not ``rmse``) and,
        per scenario, the mean ratio to the reference (``validation_ratio``)."""
        each = {s: validation_rmse(policy, s, n) for s, n in self.flights().items()}
        point: dict[str, Any] = {
            "validation_rmse_nt": float(np.mean(np.concatenate(list(each.values())))),
            "validation_rmse_by_scenario": {s: float(np.mean(r)) for s, r in each.items()},
        }
        if self.select_by == "rmse":
            return point
        ratio = {s: float(np.mean(r / self.reference(s))) for s, r in each.items()}
        if self.select_by == "ratio_to_privileged":
            point["validation_score"] = ratio[self.scenario]
        else:
            point["validation_score"] = max(ratio.values())
            point["validation_ratio"] = ratio
        return point

    def reference(self, scenario: str) -> np.ndarray:
        """The reference policy's RMSE on ``scenario``'s validation flights (computed once)."""
        if scenario not in self._reference:
            from agents.policies import policy_env_kwargs

            name = "privileged" if self.select_by == "ratio_to_privileged" else "tuned_constant"
            n = self.flights()[scenario]
            self._reference[scenario] = validation_rmse(name, scenario, n, policy_env_kwargs(name))
        return self._reference[scenario]
