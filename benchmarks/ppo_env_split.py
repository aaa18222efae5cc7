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

Run: ``python benchmarks/ppo_env_split.py [repeats] [--quick]`` (default 3)
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aeromag_env.environment import kernels
from aeromag_env.jobs.bench.envs import timed
from aeromag_env.quick import add_quick_option

TIMESTEPS = 49_152


def split(repeats: int, timesteps: int = TIMESTEPS) -> dict[str, float]:
    """µs per environment step in ``step_wait``, in the compiled step, in the resets, and the
    rest, over ``timesteps`` timed steps per repeat."""
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
                model.learn(timesteps, reset_num_timesteps=False)
                waits.append(1e6 * wait[0] / timesteps)
                steps.append(1e6 * compiled[0] / timesteps)
                loads.append(1e6 * resets[0] / timesteps)
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


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("repeats", type=int, nargs="?", default=3, help="repeats (medians)")
    add_quick_option(parser, "one repeat of 4 096 steps")
    args = parser.parse_args(argv)
    repeats, steps = (1, 4096) if args.quick else (args.repeats, TIMESTEPS)
    for name, value in split(repeats, steps).items():
        print(f"{name:32s} {value:6.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
