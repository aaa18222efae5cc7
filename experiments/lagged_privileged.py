"""How late may a tuner know the noise? The privileged policy one decision window late.

``python -m experiments.lagged_privileged [--scenario manoeuvre_heavy] [--windows 10,5]
[--episodes 12]`` flies the ``privileged`` policy (R from the largest true noise variance of the
coming window) and the same policy one window late (R from the largest true noise variance of
the window just flown: the best a tuner that learns the noise from what it has seen can do,
with everything else it knows unchanged) on the first validation flights of a scenario, at each
decision window K, beside ``tuned_constant``. Where the late policy loses to the tuned constant,
no policy that reads the noise from past windows can pass issue 21's bar there at that K.
Prints one row per K.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

if __package__ in (None, ""):  # run as a script: the checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aeromag_env.environment.spaces import ACT_R
from agents.evaluate import run_episode
from agents.policies import PrivilegedPolicy
from agents.validation import validation_rmse, validation_seeds


class LatePrivileged(PrivilegedPolicy):
    """``privileged`` with R set from the window just flown instead of the coming one."""

    name = "privileged_late"

    def predict(self, obs: np.ndarray, state: Any = None, episode_start: Any = None,
                deterministic: bool = True) -> tuple[np.ndarray, Any]:  # fmt: skip
        action, state = super().predict(obs, state, episode_start, deterministic)
        env, c = self.env, self.env.config
        k, width = env.filter.k, c.decision_window
        if k >= width:  # the first window keeps the cautious start
            past = env.episode.noise_var[k - width : k]
            r0 = float(np.mean(np.diag(env.filter.r0)))
            lo, hi = c.absolute_r_log10
            action = action.copy()
            action[..., ACT_R] = 2.0 * (math.log10(past.max() / r0) - lo) / (hi - lo) - 1.0
        return action, state


def _fly(policy_class: type, scenario: str, window: int, episodes: int) -> float:
    """Mean RMSE [nT] of ``policy_class`` (a privileged kind) over the validation flights."""
    kwargs = dict(PrivilegedPolicy.ENV_KWARGS, extras=True, decision_window=window)
    env = gym.make("AeroMagCompensation-v0", scenario=scenario, **kwargs)
    policy = policy_class(env, cautious_start=True)
    rmse = [run_episode(env, policy, seed)["rmse_nt"] for seed in validation_seeds(episodes)]
    return float(np.mean(rmse))


def main(argv: Sequence[str] | None = None) -> list[dict[str, float]]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="manoeuvre_heavy")
    parser.add_argument("--windows", default="10,5", help="decision windows K [samples]")
    parser.add_argument("--episodes", type=int, default=12)
    args = parser.parse_args(argv)
    tuned = float(np.mean(validation_rmse("tuned_constant", args.scenario, args.episodes, {})))
    print(f"{args.scenario}, {args.episodes} validation flights; tuned_constant {tuned:.3g} nT\n")
    print("| K [samples] | privileged [nT] | privileged one window late [nT] | late − tuned [nT] |")
    print("|---|---|---|---|")
    rows = []
    for window in (int(w) for w in args.windows.split(",")):
        now = _fly(PrivilegedPolicy, args.scenario, window, args.episodes)
        late = _fly(LatePrivileged, args.scenario, window, args.episodes)
        print(f"| {window} | {now:.3g} | {late:.3g} | {late - tuned:+.2g} |")
        rows.append({"window": window, "privileged": now, "late": late, "tuned": tuned})
    return rows


if __name__ == "__main__":
    main()
