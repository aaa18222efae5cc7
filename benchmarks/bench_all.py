"""All benchmarks with the table of ratios: what ``aeromag bench`` runs.

Run: ``.venv/bin/python benchmarks/bench_all.py [--quick] [--out DIR]``
"""

from __future__ import annotations

import sys
from pathlib import Path

from aeromag_env.jobs.bench import bench

if __name__ == "__main__":
    args = sys.argv[1:]
    out = Path(args[args.index("--out") + 1]) if "--out" in args else Path("results/bench")
    print(bench(out, quick="--quick" in args).table)
