"""How late may a tuner know the noise? The privileged policy one decision window late.

``python -m experiments.lagged_privileged [--scenario manoeuvre_heavy] [--windows 10,5]
[--episodes 12] [--floors 1,2]`` flies the ``privileged`` policy (R from the largest true noise
variance of the coming window) and the same policy one window late (R from the largest true
noise variance of the window just flown: the best a tuner that learns the noise from what it has
seen can do, with everything else it knows unchanged) on the first validation flights of a
scenario, at each decision window K, beside ``tuned_constant``. Where the late policy loses to
the tuned constant, no policy that reads the noise from past windows and lets R follow it can
pass issue 21's bar there at that K.
With ``--floors``, also the late policy that never sets R below ``10^f R(0)`` for each ``f``
(its ``r_floor``: a tuner that cannot see a burst coming keeps R up in case). Prints one row
per K.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

if __package__ in (None, ""):  # run as a script: the checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aeromag_env.environment.spaces import ACT_R
from agents.evaluation.episodes import run_episode
from agents.policies.baselines import PrivilegedPolicy
from agents.training.validation import validation_rmse, validation_seeds


class LatePrivileged(PrivilegedPolicy):
    """``privileged`` with R set from the window just flown instead of the coming one."""

    name = "privileged_late"

    def predict(
        self,
        obs: np.ndarray,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        action, state = super().predict(obs, state, episode_start, deterministic)
        truth = self.truth()
        k, width = truth.sample, self.config.decision_window
        if k >= width:  # the first window keeps the cautious start
            action = action.copy()
            action[..., ACT_R] = self.r_action(truth.noise_var[k - width : k], truth)
        return action, state


def _fly(
    policy_class: type, scenario: str, window: int, episodes: int, floor: float | None = None
) -> float:
    """Mean RMSE [nT] of ``policy_class`` (a privileged kind) over the validation flights, with
    R held at or above ``10^floor R(0)`` when ``floor`` is given."""
    kwargs = dict(PrivilegedPolicy.ENV_KWARGS, extras=True, decision_window=window)
    env = gym.make("AeroMagCompensation-v0", scenario=scenario, **kwargs)
    r_floor = None if floor is None else {scenario: floor}
    policy = policy_class(env, cautious_start=True, r_floor=r_floor)
    rmse = [run_episode(env, policy, seed)["rmse_nt"] for seed in validation_seeds(episodes)]
    return float(np.mean(rmse))


def main(argv: Sequence[str] | None = None) -> list[dict[str, Any]]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="manoeuvre_heavy")
    parser.add_argument("--windows", default="10,5", help="decision windows K [samples]")
    parser.add_argument("--episodes", type=int, default=12)
    parser.add_argument("--floors", default="", help="log10 R floors f for the late policy")
    args = parser.parse_args(argv)
    try:
        floors = [float(f) for f in args.floors.split(",") if f.strip()]
    except ValueError:
        parser.error(f"--floors {args.floors!r}: comma-separated numbers, e.g. 1,2")
    tuned = float(np.mean(validation_rmse("tuned_constant", args.scenario, args.episodes, {})))
    print(f"{args.scenario}, {args.episodes} validation flights; tuned_constant {tuned:.3g} nT\n")
    heads = [
        "K [samples]",
        "privileged [nT]",
        "privileged one window late [nT]",
        "late − tuned [nT]",
        *(f"late, R ≥ 10^{f:g} R(0) [nT]" for f in floors),
    ]
    print("| " + " | ".join(heads) + " |\n" + "|---" * len(heads) + "|")
    rows = []
    for window in (int(w) for w in args.windows.split(",")):
        now = _fly(PrivilegedPolicy, args.scenario, window, args.episodes)
        late = _fly(LatePrivileged, args.scenario, window, args.episodes)
        held = {f: _fly(LatePrivileged, args.scenario, window, args.episodes, f) for f in floors}
        cells = [
            str(window),
            f"{now:.3g}",
            f"{late:.3g}",
            f"{late - tuned:+.2g}",
            *(f"{v:.3g}" for v in held.values()),
        ]
        print("| " + " | ".join(cells) + " |")
        rows.append(
            {
                "window": window,
                "privileged": now,
                "late": late,
                "tuned": tuned,
                "late_floored": held,
            }
        )
    return rows


if __name__ == "__main__":
    main()
