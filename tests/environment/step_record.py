"""Record what the tuning environment returns on fixed flights and actions, to hold later code to.

Each case of :data:`CASES` is one episode of the single environment: a configuration, a reset
seed and an action sequence drawn from a seeded generator (bounded random actions, or actions
that swing Q and R by tens of decades from one step to the next). :func:`record` returns, per
step, the observation; and digests of what the step returns besides (the rewards, the end flags
and every info value of every step), of the flight's inputs and of the filter's outputs at the
end (estimates, innovations, ROR, QOQ).
``tests/environment/test_step_outputs.py`` holds the current code to the file this module's
``main`` wrote with an earlier one (``data/step_outputs_v0.npz``: the environment before its
observation statistics became running sums): bitwise for everything the statistics do not
enter, within a stated tolerance for the observations they do.

Run: ``python -m tests.environment.step_record [out.npz]``
"""

from __future__ import annotations

import hashlib
import sys
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import aeromag_env  # noqa: F401  (registers the environment)

#: The file the tests read.
RECORD = Path(__file__).parent / "data" / "step_outputs_v0.npz"
#: The swings of the hostile case: the absolute mode over ±100 decades of Q and R.
HOSTILE = {
    "preset": "general",
    "action": {
        "q_log10": (-100.0, 100.0),
        "r_log10": (-100.0, 100.0),
        "qp_log10": (-100.0, 100.0),
        "scale_limit": 1e100,
    },
}
#: name → (configuration, reset seed, actions: "random" in [-1.2, 1.2], "zero" or "swing").
CASES: dict[str, tuple[dict[str, Any], int, str]] = {
    "paper_nominal": ({"preset": "paper", "scenario": "nominal"}, 100_000, "random"),
    "detector_dense": (
        {"preset": "nonstationary", "scenario": "nonstationary_dense"},
        7,
        "random",
    ),
    "general_nonstationary": (
        {"preset": "general", "scenario": "nonstationary"},
        100_003,
        "random",
    ),
    "general_misspecified": ({"preset": "general", "scenario": "misspecified"}, 11, "zero"),
    "general_bursts_recent": (
        {"preset": "general", "scenario": "noise_bursts", "recent_samples": 20},
        5,
        "random",
    ),
    "general_long_window": (
        {"preset": "general", "scenario": "degradation", "decision_window": 60},
        3,
        "random",
    ),
    "hostile_swings": ({**HOSTILE, "scenario": "calibration_then_survey"}, 24, "swing"),
}
#: Steps recorded per case (from the reset on; an episode that ends earlier stops there).
STEPS = 120


def _digest(*arrays: np.ndarray) -> str:
    h = hashlib.sha256()
    for a in arrays:
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def _actions(kind: str, steps: int, size: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    if kind == "zero":
        return np.zeros((steps, size))
    if kind == "random":
        return rng.uniform(-1.2, 1.2, (steps, size))
    return rng.choice([-1.0, 1.0, 0.0, 0.3], (steps, size))  # "swing": decades per step


def record(name: str) -> dict[str, np.ndarray]:
    """Case ``name`` of :data:`CASES` stepped: its arrays (see the module docstring)."""
    config, seed, kind = CASES[name]
    config = dict(config)
    preset = config.pop("preset")
    env = gym.make("AeroMagCompensation-v0", config={"preset": preset, **config})
    env.reset(seed=seed)
    u = env.unwrapped
    ep, f = u.episode, u.filter
    actions = _actions(kind, STEPS, env.action_space.shape[0], seed)
    rows: dict[str, list] = {"reward": [], "flags": [], "info": [], "obs": []}
    keys: list[str] = []
    for a in actions:
        obs, reward, terminated, truncated, info = env.step(a)
        keys = list(info)
        rows["reward"].append(reward)
        rows["flags"].append((terminated, truncated))
        rows["info"].append([float(v) for v in info.values()])
        rows["obs"].append(obs)
        if truncated or (terminated and kind != "swing"):  # the swings go on through restarts
            break
    k = f.k
    rewards = np.array(rows["reward"], np.float64)
    flags, infos = np.array(rows["flags"], bool), np.array(rows["info"], np.float64)
    return {
        "steps": np.array(len(rewards)),
        "returns": np.array(_digest(rewards, flags, infos, np.array(keys))),
        "obs": np.array(rows["obs"], np.float32),
        "obs_names": np.array(u.config.observations),
        "inputs": np.array(_digest(ep.y, ep.t_b, ep.tdot_b, ep.truth_interf)),
        "outputs": np.array(_digest(f.est[:k], f.innov[:k], f.ror[:k], f.qoq[:k])),
    }


def main(argv: list[str]) -> None:
    out = Path(argv[0]) if argv else RECORD
    arrays = {f"{name}/{key}": v for name in CASES for key, v in record(name).items()}
    out.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(out, **arrays)
    print(f"wrote {out} ({out.stat().st_size} bytes)")


if __name__ == "__main__":
    main(sys.argv[1:])
