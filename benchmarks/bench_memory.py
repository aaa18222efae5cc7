"""Benchmark: peak memory of ``aeromag compensate --method kf`` on a 10-hour 10 Hz flight
(same code as ``aeromag bench``).

Run: ``.venv/bin/python benchmarks/bench_memory.py``
"""

from __future__ import annotations

import json

from aeromag_env.jobs.bench.workflows import bench_memory

if __name__ == "__main__":
    print(json.dumps(bench_memory(), indent=2))
