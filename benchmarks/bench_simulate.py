"""Benchmark: seconds to simulate one flight-hour (same code as ``aeromag bench``).

Run: ``.venv/bin/python benchmarks/bench_simulate.py [--quick]``
"""

from __future__ import annotations

import sys
from pathlib import Path

from aeromag_env.bench import run_benchmarks

if __name__ == "__main__":
    run_benchmarks(Path("results/bench"), quick="--quick" in sys.argv[1:])
