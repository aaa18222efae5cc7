"""Benchmark: inside PPO training, how much of the environments' time is the compiled step.

``aeromag bench`` times the environments' ``step_wait`` inside PPO's ``learn``; this splits that
time once more. PPO as in ``aeromag train`` (``agents/training/hyperparams/ppo.json``'s
``nonstationary``
entry: 8 batched environments, flights prefetched, torch as in training) learns for one untimed
rollout, then for 49 152 timed steps per repeat; per environment step, medians over the repeats:
``step_wait`` (everything the environments cost PPO's loop), of it the compiled step of all
environments (``kernels.env_step_batch``: the filter over the decision window, the score and the
observation), the resets at episode ends (loading the next flight, prefetched by the worker
process), and the rest (the Python around the step: action check, flags, info dicts, copies).
``aeromag bench`` holds the
``step_wait`` time against the filter alone (``ppo_env_to_filter_ratio``); this says how much of
the gap is the compiled step's scoring and observation and how much the Python around it.

Run: ``.venv/bin/python benchmarks/ppo_env_split.py [repeats]`` (default 3)
"""

from __future__ import annotations

import statistics
import sys
import time
from typing import Any

from aeromag_env.environment import kernels
from aeromag_env.jobs.bench.envs import timed

TIMESTEPS = 49_152


def split(repeats: int) -> dict[str, float]:
    """µs per environment step in ``step_wait``, in the compiled step, in the resets, and the
    rest."""
    from agents.training import ppo

    hp = ppo.load_hyperparams("nonstationary")
    wait, compiled, resets = [0.0], [0.0], [0.0]
    original = kernels.env_step_batch
    kernels.env_step_batch = timed(original, compiled)
    try:
        with ppo.training_torch():
            venv = ppo.make_training_env("nonstationary", hp, seed=0)
            venv.venv.step_wait = timed(venv.venv.step_wait, wait)
            batched = venv.venv.venv  # the adapter resets the ended environments through it
            batched.reset = timed(batched.reset, resets)
            model: Any = ppo.make_ppo(venv, hp, seed=0)
            time.sleep(2.0)  # the prefetching worker starts up
            model.learn(hp.n_steps * hp.n_envs)
            waits, steps, loads = [], [], []
            for _ in range(repeats):
                wait[0] = compiled[0] = resets[0] = 0.0
                model.learn(TIMESTEPS, reset_num_timesteps=False)
                waits.append(1e6 * wait[0] / TIMESTEPS)
                steps.append(1e6 * compiled[0] / TIMESTEPS)
                loads.append(1e6 * resets[0] / TIMESTEPS)
            venv.close()
    finally:
        kernels.env_step_batch = original
    return {
        "step_wait_us_per_env_step": statistics.median(waits),
        "compiled_step_us_per_env_step": statistics.median(steps),
        "resets_us_per_env_step": statistics.median(loads),
        "rest_us_per_env_step": statistics.median(
            w - c - r for w, c, r in zip(waits, steps, loads, strict=True)
        ),
    }


if __name__ == "__main__":
    for name, value in split(int(sys.argv[1]) if len(sys.argv) > 1 else 3).items():
        print(f"{name:32s} {value:6.1f}")
