"""Benchmark: seconds to simulate one flight-hour (same code as ``aeromag bench``).

Run: ``python benchmarks/bench_simulate.py [--quick]``
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aeromag_env.jobs.bench.workflows import bench_simulate
from aeromag_env.quick import add_quick_option


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_quick_option(parser, "3 repeats instead of 7")
    args = parser.parse_args(argv)
    print(json.dumps(bench_simulate(3 if args.quick else 7), indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
