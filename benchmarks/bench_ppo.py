"""Benchmark: PPO training throughput with the batched environments (with and without flight
prefetching) against SB3's DummyVecEnv, same hyperparameters
(``agents/training/hyperparams/ppo.json``: 8 envs, and again with 64; same code as ``aeromag
bench``), and against a zero-cost environment (PPO alone: the ceiling of any environment's
speed-up).

Run: ``python benchmarks/bench_ppo.py [--quick]``
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aeromag_env.jobs.bench.envs import bench_ppo
from aeromag_env.quick import add_quick_option


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_quick_option(parser, "fewer steps, one repeat")
    args = parser.parse_args(argv)
    repeats = 1 if args.quick else 3
    figures = bench_ppo(16384 if args.quick else 49152, repeats)
    figures |= bench_ppo(32768 if args.quick else 163840, repeats, n_envs=64, prefix="ppo64")
    print(json.dumps(figures, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
