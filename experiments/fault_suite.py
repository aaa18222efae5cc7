"""The fault-injection suite: bad input of every class through every command.

The cases, their runner and checker live with the tests (:mod:`tests.faults`), which run every
case; this script runs them outside pytest and prints the README table "What bad input gets"
(per class: cases, outcomes, failures) and the failing cases grouped by failure and command.

Usage::

    python experiments/fault_suite.py [--only TEXT] [--quick] [--list]
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
from pathlib import Path

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout (``tests.faults``)
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aeromag_env.quick import add_quick_option
from tests.faults.suite import failure_groups, generate, run_case, table


def main(argv: list[str] | None = None) -> int:
    """Run the cases; print the table and the failures; 1 if any case failed."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", default="", help="run only the cases whose id contains this")
    parser.add_argument("--list", action="store_true", help="list the cases, run none")
    add_quick_option(parser, "one case per class and command")
    args = parser.parse_args(argv)
    cases = [c for c in generate() if args.only in c.id]
    if args.quick:
        cases = list({(c.fault_class, c.argv[0]): c for c in reversed(cases)}.values())[::-1]
    if args.list:
        print("\n".join(f"{c.id}: aeromag {' '.join(c.argv)} [{c.expect}]" for c in cases))
        return 0
    results, t0 = [], time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        for k, case in enumerate(cases):
            results.append(run_case(case, Path(tmp, str(k))))
            shutil.rmtree(Path(tmp, str(k)), ignore_errors=True)
    print(f"{table(results)}\n\n{len(cases)} cases in {time.perf_counter() - t0:.0f} s\n")
    print(failure_groups(results))
    return 1 if any(r.failures for r in results) else 0


if __name__ == "__main__":
    raise SystemExit(main())
