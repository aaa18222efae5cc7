"""The README's import-time figure: ``import aeromag_env`` beside the imports it cannot avoid.

``python experiments/import_time.py [--repeats 15] [--quick]`` starts a fresh interpreter per
repeat (so nothing is cached in ``sys.modules``), times each import with ``time.perf_counter``
inside that interpreter, and prints the medians side by side: ``import gymnasium`` (needed to
register the environment ids), ``import numpy``, ``import aeromag_env``, and, for scale, the first
use of a heavy public name (``aeromag_env.compensate_vector``, which loads the compiled kernels).
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aeromag_env.quick import add_quick_option
from agents.training.quick import QUICK

STATEMENTS = {
    "import numpy": "import numpy",
    "import gymnasium": "import gymnasium",
    "import aeromag_env": "import aeromag_env",
    "aeromag_env.compensate_vector (first use)": (
        "import aeromag_env; aeromag_env.compensate_vector"
    ),
}


def time_statement(statement: str) -> float:
    """Seconds ``statement`` takes in a fresh interpreter."""
    code = f"import time; t = time.perf_counter(); {statement}; print(time.perf_counter() - t)"
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return float(run.stdout.strip().splitlines()[-1])


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=15)
    add_quick_option(parser, "3 repeats (tests)")
    args = parser.parse_args(argv)
    repeats = QUICK.bench_repeats if args.quick else args.repeats
    print(f"median of {repeats} fresh interpreters (interleaved)")
    times: dict[str, list[float]] = {name: [] for name in STATEMENTS}
    for _ in range(repeats):  # interleaved, so a slow minute of the host hits every row alike
        for name, statement in STATEMENTS.items():
            times[name].append(time_statement(statement))
    for name, values in times.items():
        print(f"{name:45s} {1e3 * statistics.median(values):8.0f} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
