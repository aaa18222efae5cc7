"""Find the ``tuned_constant`` baseline: the best constant Q and R scales per scenario.

``python experiments/tune_constants.py [--seeds 8] [--scenarios paper,nominal,...] [--out PATH]``
grid-searches log10 scales of Q (−10…6) and R (−2…6), steps of 1, on training seeds 0…N−1,
minimising the mean episode RMSE (:func:`agents.search.tuned_constant.tune_constant`), and
writes the table — ``--out``'s, or when it does not exist yet the shipped one, with the
searched scenarios' rows replaced — to ``--out`` (default ``results/tuned_constants.json``).
The shipped table, which ``agents`` loads, is replaced only when named: ``--out
agents/policies/tuned_constants.json``. ``--quick``: the first scenario on 2 seeds over every
fourth grid point.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aeromag_env.atomic import write_text
from aeromag_env.environment.scenarios import SCENARIOS
from aeromag_env.quick import add_quick_option
from agents.policies.tuned_table import TABLE
from agents.search.tuned_constant import LOG10_Q_GRID, LOG10_R_GRID, tune_constant
from agents.training.quick import QUICK


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--seeds", type=int, default=8, help="training seeds 0…N−1 (default 8)")
    parser.add_argument("--scenarios", default=",".join(SCENARIOS), help="comma-separated")
    parser.add_argument(
        "--out", type=Path, default=Path("results/tuned_constants.json"), help="the table"
    )
    add_quick_option(parser, "one scenario, 2 seeds, coarse")
    args = parser.parse_args(argv)
    scenarios = args.scenarios.split(",")
    grids: tuple[Sequence[float], Sequence[float]] = (LOG10_Q_GRID, LOG10_R_GRID)
    seeds = range(args.seeds)
    if args.quick:
        scenarios, seeds, grids = scenarios[:1], range(QUICK.seeds), (grids[0][::4], grids[1][::4])
    table = json.loads((args.out if args.out.exists() else TABLE).read_text())
    for scenario in scenarios:
        t0 = time.perf_counter()
        table[scenario] = row = tune_constant(scenario, seeds, *grids)
        print(
            f"{scenario}: log10 Q ×{row['log10_q']:+.1f}, log10 R ×{row['log10_r']:+.1f}, "
            f"RMSE {row['rmse_nt']:.3g} nT ({time.perf_counter() - t0:.0f} s)",
            flush=True,
        )
    write_text(args.out, json.dumps(table, indent=2, sort_keys=True) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
