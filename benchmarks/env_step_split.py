"""Benchmark: the training environments' step split into its parts, without PPO.

PPO's training environments (``agents/training/hyperparams/ppo.json``'s ``nonstationary`` entry,
batched, flights prefetched) stepped with random actions, ``steps`` steps per repeat; per
environment
step, medians over the repeats: ``step_wait`` (everything a step costs), of it the compiled step
(``kernels.env_step_batch``), the resets and the info dicts, and beside them the bare compiled
filter (:class:`aeromag_env.jobs.bench.envs.BareFilter`) advancing the same number of the first
reset's flights by K samples, interleaved with the steps. PPO's own work is left out, so its
caches stay warm: ``aeromag bench`` measures the same step inside PPO
(``ppo_env_to_filter_ratio``), ``benchmarks/ppo_env_split.py`` splits that one.

Run: ``python benchmarks/env_step_split.py [num_envs] [repeats] [--quick]`` (default 8, 5)
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aeromag_env.environment import vec_env
from aeromag_env.jobs.bench.envs import BareFilter, timed
from aeromag_env.quick import add_quick_option

STEPS = 3000
#: Environment steps of the bare filter per turn (it takes its turn every this many steps).
TURN = 256


def split(num_envs: int, repeats: int, steps: int = STEPS) -> dict[str, float]:
    """µs per environment step of ``step_wait``, the compiled step, the resets, the info dicts
    and the bare filter, over ``steps`` steps per repeat."""
    from agents.training import ppo

    hp = ppo.load_hyperparams("nonstationary").with_values(n_envs=num_envs)
    parts = {name: [0.0] for name in ("step_wait", "compiled", "resets", "infos")}
    original = (vec_env.kernels.env_step_batch, vec_env.info_rows)
    vec_env.kernels.env_step_batch = timed(original[0], parts["compiled"])
    vec_env.info_rows = timed(original[1], parts["infos"])
    try:
        venv = ppo.make_training_env("nonstationary", hp, seed=0)
        inner = venv.venv
        inner.step_wait = timed(inner.step_wait, parts["step_wait"])
        inner.venv.reset = timed(inner.venv.reset, parts["resets"])
        venv.reset()
        bare = BareFilter(inner.venv.filters, int(inner.venv.config.decision_window))
        actions = np.random.default_rng(0).uniform(-1, 1, (steps, num_envs, 3))
        time.sleep(2.0)  # the prefetching worker starts up
        rows: list[list[float]] = []
        for _ in range(repeats):
            for total in (*parts.values(), bare.seconds):
                total[0] = 0.0
            for s in range(steps):
                venv.step_async(actions[s].astype(np.float32))
                venv.step_wait()
                if s % TURN == 0:
                    bare(TURN * num_envs)
            env_steps, bare_steps = steps * num_envs, -(-steps // TURN) * TURN * num_envs
            row = [1e6 * total[0] / env_steps for total in parts.values()]
            rows.append([*row, 1e6 * bare.seconds[0] / bare_steps])
        venv.close()
    finally:
        vec_env.kernels.env_step_batch, vec_env.info_rows = original
    names = [*parts, "bare_filter"]
    columns = zip(*rows, strict=True)
    return {
        f"{n}_us_per_env_step": statistics.median(c) for n, c in zip(names, columns, strict=True)
    }


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("num_envs", type=int, nargs="?", default=8, help="batched environments")
    parser.add_argument("repeats", type=int, nargs="?", default=5, help="repeats (medians)")
    add_quick_option(parser, f"{TURN} steps per repeat")
    args = parser.parse_args(argv)
    for name, value in split(args.num_envs, args.repeats, TURN if args.quick else STEPS).items():
        print(f"{name:32s} {value:6.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
