"""All benchmarks with the table of ratios: what ``aeromag bench`` runs.

Run: ``python benchmarks/bench_all.py [--quick] [--out results/bench]`` (from anywhere: the
checkout's packages are used); writes ``OUT/bench.json``.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aeromag_env.jobs.bench import bench
from aeromag_env.quick import add_quick_option


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_quick_option(parser, "small sizes (about a minute)")
    parser.add_argument("--out", type=Path, default=Path("results/bench"), help="output folder")
    args = parser.parse_args(argv)
    print(bench(args.out, quick=args.quick).table)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
