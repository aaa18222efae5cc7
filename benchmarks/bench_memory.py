"""Benchmark: peak memory of ``aeromag compensate --method kf`` on a 10-hour 10 Hz flight
(same code as ``aeromag bench``).

Run: ``python benchmarks/bench_memory.py [--hours 10]``
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aeromag_env.jobs.bench.workflows import bench_memory
from aeromag_env.quick import add_quick_option


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hours", type=float, default=10.0, help="the flight's length [h]")
    add_quick_option(parser, "a 1-hour flight")
    args = parser.parse_args(argv)
    print(json.dumps(bench_memory(1.0 if args.quick else args.hours), indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
