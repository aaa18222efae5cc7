"""Benchmark: PPO training throughput with the batched environments (with and without flight
prefetching) against SB3's DummyVecEnv, same hyperparameters
(``agents/training/hyperparams/ppo.json``:
8 envs, and again with 64; same code as ``aeromag bench``), and against a zero-cost environment
(PPO alone: the ceiling of any environment's speed-up).

Run: ``.venv/bin/python benchmarks/bench_ppo.py [--quick]``
"""

from __future__ import annotations

import json
import sys

from aeromag_env.jobs.bench.envs import bench_ppo

if __name__ == "__main__":
    quick = "--quick" in sys.argv[1:]
    repeats = 1 if quick else 3
    figures = bench_ppo(16384 if quick else 49152, repeats)
    figures |= bench_ppo(32768 if quick else 163840, repeats, n_envs=64, prefix="ppo64")
    print(json.dumps(figures, indent=2))
