"""Benchmark: compiled, batched (64 flights), numpy and filterpy filters on the same samples of
a simulated 1-hour flight (same code as ``aeromag bench``).

Run: ``python benchmarks/bench_filters.py [--quick]``
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aeromag_env.jobs.bench import FILTER_SAMPLES
from aeromag_env.jobs.bench.filters import bench_filter_figures
from aeromag_env.jobs.bench.workflows import hour_flight
from aeromag_env.quick import add_quick_option


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_quick_option(parser, "1000 samples, 3 repeats")
    args = parser.parse_args(argv)
    samples, repeats = (1000, 3) if args.quick else (FILTER_SAMPLES, 7)
    print(json.dumps(bench_filter_figures(hour_flight(), samples, repeats), indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
