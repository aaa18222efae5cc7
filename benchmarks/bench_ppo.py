"""Benchmark: PPO training throughput with the batched environments against SB3's DummyVecEnv,
same hyperparameters (``agents/hyperparams/ppo.json``; same code as ``aeromag bench``).

Run: ``.venv/bin/python benchmarks/bench_ppo.py [--quick]``
"""

from __future__ import annotations

import json
import sys

from aeromag_env.bench_envs import bench_ppo

if __name__ == "__main__":
    quick = "--quick" in sys.argv[1:]
    print(json.dumps(bench_ppo(4096 if quick else 16384, 1 if quick else 3), indent=2))
