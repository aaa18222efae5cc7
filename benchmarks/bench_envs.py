"""Benchmark: environment steps per second, one env and 64 batched, K = 10 (same code as
``aeromag bench``).

Run: ``.venv/bin/python benchmarks/bench_envs.py [--quick]``
"""

from __future__ import annotations

import json
import sys

from aeromag_env.jobs.bench.envs import bench_env

if __name__ == "__main__":
    print(json.dumps(bench_env(3 if "--quick" in sys.argv[1:] else 7), indent=2))
