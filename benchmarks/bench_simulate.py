"""Benchmark: seconds to simulate one flight-hour (same code as ``aeromag bench``).

Run: ``.venv/bin/python benchmarks/bench_simulate.py [--quick]``
"""

from __future__ import annotations

import json
import sys

from aeromag_env.jobs.bench.workflows import bench_simulate

if __name__ == "__main__":
    print(json.dumps(bench_simulate(3 if "--quick" in sys.argv[1:] else 7), indent=2))
