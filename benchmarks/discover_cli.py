"""Benchmark: ``aeromag discover`` as a user runs it, a fresh process per run on simulated 1- and
4-flight-hour files, figures and report included: seconds per flight-hour and peak memory [MB]
(:func:`aeromag_env.jobs.bench.discover_cli.bench_discover_cli`).

Run: ``.venv/bin/python benchmarks/discover_cli.py [--quick] [--hours 1 2 4] [--repeats 3]
[--out FILE.json]``; ``--quick``: one 30-min flight, one measured run (about a minute).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aeromag_env.atomic import write_text
from aeromag_env.jobs.bench.discover_cli import HOURS, QUICK_HOURS, REPEATS, bench_discover_cli
from aeromag_env.quick import add_quick_option


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_quick_option(parser, "one 30-min flight, one run")
    parser.add_argument("--hours", type=float, nargs="+", help=f"flight lengths (default {HOURS})")
    parser.add_argument("--repeats", type=int, help=f"measured runs per length (default {REPEATS})")
    parser.add_argument("--out", type=Path, help="also write the figures to this JSON file")
    args = parser.parse_args(argv)
    hours = args.hours or (QUICK_HOURS if args.quick else HOURS)
    repeats = args.repeats or (1 if args.quick else REPEATS)
    figures = bench_discover_cli(hours, repeats)
    text = json.dumps(figures, indent=2)
    print(text)
    if args.out is not None:
        write_text(args.out, text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
