"""Benchmark: compiled, batched (64 flights), numpy and filterpy filters on the same samples of
a simulated 1-hour flight (same code as ``aeromag bench``).

Run: ``.venv/bin/python benchmarks/bench_filters.py [--quick]``
"""

from __future__ import annotations

import json
import sys

from aeromag_env.jobs.bench import FILTER_SAMPLES
from aeromag_env.jobs.bench.filters import bench_filter_figures
from aeromag_env.jobs.bench.workflows import hour_flight

if __name__ == "__main__":
    quick = "--quick" in sys.argv[1:]
    figures = bench_filter_figures(
        hour_flight(), 1000 if quick else FILTER_SAMPLES, 3 if quick else 7
    )
    print(json.dumps(figures, indent=2))
