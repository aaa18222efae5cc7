"""The README's tuner table: every policy on every scenario, same test flights, paired CIs.

``python experiments/evaluate_all.py [--episodes 30] [--quick] [--out results/evaluate_all]``
runs ``aeromag evaluate`` per scenario (test seeds from 100 000) and writes ``table.md`` and one
``results.json`` per scenario.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from aeromag_env.atomic import write_text
from aeromag_env.evaluate_run import evaluation_table, run_evaluate
from aeromag_env.scenarios import SCENARIOS
from agents import POLICIES


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=30)
    parser.add_argument("--quick", action="store_true", help="2 episodes of 2 scenarios (tests)")
    parser.add_argument("--out", default="results/evaluate_all")
    args = parser.parse_args(argv)
    scenarios = SCENARIOS[:2] if args.quick else SCENARIOS
    episodes = 2 if args.quick else args.episodes
    out = Path(args.out)
    tables = []
    for scenario in scenarios:
        res = run_evaluate(scenario, list(POLICIES), episodes, 100_000, out / scenario, quiet=True)
        tables.append(evaluation_table(res))
    write_text(out / "table.md", "\n".join(tables))
    print(f"wrote {out}/table.md")
    return 0


if __name__ == "__main__":
    sys.exit(main())
