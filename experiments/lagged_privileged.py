"""How late may a tuner know the noise? The privileged policy one decision window late.

``python experiments/lagged_privileged.py [--scenario manoeuvre_heavy] [--windows 10,5]
[--episodes 12] [--floors 1,2] [--quick]`` flies the ``privileged`` policy (R from the largest
true noise variance of the coming window) and the same policy one window late (R from the largest
true noise variance of the window just flown: the best a tuner that learns the noise from what
it has seen can do, with everything else it knows unchanged) on the first validation flights of a
scenario, at each decision window K, beside ``tuned_constant``. Where the late policy loses to
the tuned constant, no policy that reads the noise from past windows and lets R follow it can
pass the headroom bar there at that K.
With ``--floors``, also the late policy that never sets R below ``10^f R(0)`` for each ``f``
(its ``r_floor``: a tuner that cannot see a burst coming keeps R up in case). Prints one row
per K; writes nothing. ``--quick``: the first K on 2 flights.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aeromag_env.environment.observations import PAPER_OBSERVATIONS
from aeromag_env.environment.spaces import ACT_R
from aeromag_env.quick import add_quick_option
from agents.evaluation.episodes import run_episode
from agents.policies.baselines import PrivilegedPolicy
from agents.training.quick import QUICK
from agents.training.validation import validation_rmse, validation_seeds

#: The observation the policies fly with (they read the truth, not the observation): the
#: paper's two, the current Q and R scales, whiteness, progress, the recent ROR, T_p's Q scale.
OBSERVATIONS = [
    *PAPER_OBSERVATIONS,
    *("log_q_scale", "log_r_scale", "whiteness", "progress", "log_recent_ror", "log_qp_scale"),
]


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
    kwargs = {
        **PrivilegedPolicy.ENV_KWARGS,
        "observations": OBSERVATIONS,
        "decision_window": window,
    }
    env = gym.make("AeroMagCompensation-v0", scenario=scenario, **kwargs)
    r_floor = None if floor is None else {scenario: floor}
    policy = policy_class(env, cautious_start=True, r_floor=r_floor)
    rmse = [run_episode(env, policy, seed)["rmse_nt"] for seed in validation_seeds(episodes)]
    return float(np.mean(rmse))


def table(
    scenario: str, windows: Sequence[int], episodes: int, floors: Sequence[float]
) -> list[dict[str, Any]]:
    """Print the table (a row per decision window K) and return its rows: the privileged
    policy's, the late one's and (per floor) the floored late one's mean RMSE [nT] and the
    tuned constant's."""
    tuned = float(np.mean(validation_rmse("tuned_constant", scenario, episodes, {})))
    print(f"{scenario}, {episodes} validation flights; tuned_constant {tuned:.3g} nT\n")
    heads = [
        "K [samples]",
        "privileged [nT]",
        "privileged one window late [nT]",
        "late − tuned [nT]",
        *(f"late, R ≥ 10^{f:g} R(0) [nT]" for f in floors),
    ]
    print("| " + " | ".join(heads) + " |\n" + "|---" * len(heads) + "|")
    rows = []
    for window in windows:
        now = _fly(PrivilegedPolicy, scenario, window, episodes)
        late = _fly(LatePrivileged, scenario, window, episodes)
        held = {f: _fly(LatePrivileged, scenario, window, episodes, f) for f in floors}
        cells = [
            str(window),
            f"{now:.3g}",
            f"{late:.3g}",
            f"{late - tuned:+.2g}",
            *(f"{v:.3g}" for v in held.values()),
        ]
        print("| " + " | ".join(cells) + " |")
        row = {"window": window, "privileged": now, "late": late, "tuned": tuned}
        rows.append({**row, "late_floored": held})
    return rows


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="manoeuvre_heavy")
    parser.add_argument("--windows", default="10,5", help="decision windows K [samples]")
    parser.add_argument("--episodes", type=int, default=12, help="validation flights")
    parser.add_argument("--floors", default="", help="log10 R floors f for the late policy")
    add_quick_option(parser, "K = 10 on 2 flights")
    args = parser.parse_args(argv)
    try:
        floors = [float(f) for f in args.floors.split(",") if f.strip()]
        windows = [int(w) for w in args.windows.split(",")]
    except ValueError:
        parser.error(
            f"--floors {args.floors!r} / --windows {args.windows!r}: comma-separated numbers, "
            "e.g. 1,2"
        )
    if args.quick:
        windows, episodes = windows[:1], QUICK.episodes
    else:
        episodes = args.episodes
    table(args.scenario, windows, episodes, floors)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
