"""Reproduce Zhang, Zhao & Chang (2014) §4 and compare with its claims.

A thin wrapper over ``aeromag reproduce-paper``: ``python experiments/reproduce_paper.py
[--quick] [--seed S] [--out results/paper]`` writes ``report.json``, ``fig3_field.png``,
``fig4_states.png`` and ``fig5_compensation.png`` to ``--out`` (default ``results/paper``; the
committed report is ``--out docs/paper``). ``--sweep 10`` instead repeats the setting on seeds
1–10 and prints the spread of each figure (min / median / max), writing nothing.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aeromag_env.cli.main import main as aeromag
from aeromag_env.compensation.paper import seed_sweep
from aeromag_env.quick import add_quick_option


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--sweep", type=int, metavar="N", help="run seeds 1…N, print the spread")
    add_quick_option(parser, "one calibration box, not 30 min")
    parser.add_argument("--out", default="results/paper", help="output folder")
    parser.add_argument("--seed", type=int, help="random seed (aeromag reproduce-paper's default)")
    args = parser.parse_args(argv)
    if args.sweep is not None:
        summary = seed_sweep(list(range(1, args.sweep + 1)), quick=args.quick)
        for key, v in summary.items():
            print(
                f"{key:34s} min {v['min']:10.4g}  median {v['median']:10.4g}  max {v['max']:10.4g}"
            )
        return 0
    command = ["reproduce-paper", "--out", args.out, *(["--quick"] if args.quick else [])]
    return aeromag(command + ([] if args.seed is None else ["--seed", str(args.seed)]))


if __name__ == "__main__":
    raise SystemExit(main())
