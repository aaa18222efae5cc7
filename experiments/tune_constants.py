"""Find the ``tuned_constant`` baseline: the best constant Q and R scales per scenario.

``python experiments/tune_constants.py [--seeds 8] [--scenarios paper,nominal,...]`` grid-searches
log10 scales of Q (−10…6) and R (−2…6), steps of 1, on training seeds 0…N−1, minimising the mean
episode RMSE, and writes ``agents/policies/tuned_constants.json`` (which ``agents`` ships and
loads).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Sequence

from aeromag_env.atomic import write_text
from aeromag_env.environment.scenarios import SCENARIOS
from agents.policies.tuned_table import TABLE
from agents.search.tuned_constant import tune_constant


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=8, help="training seeds 0…N−1 (default 8)")
    parser.add_argument("--scenarios", default=",".join(SCENARIOS))
    args = parser.parse_args(argv)
    table = json.loads(TABLE.read_text()) if TABLE.exists() else {}
    for scenario in args.scenarios.split(","):
        t0 = time.perf_counter()
        table[scenario] = tune_constant(scenario, range(args.seeds))
        row = table[scenario]
        took = time.perf_counter() - t0
        print(
            f"{scenario}: log10 Q ×{row['log10_q']:+.1f}, log10 R ×{row['log10_r']:+.1f}, "
            f"RMSE {row['rmse_nt']:.3g} nT ({took:.0f} s)",
            flush=True,
        )
    write_text(TABLE, json.dumps(table, indent=2, sort_keys=True) + "\n")
    print(f"wrote {TABLE}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
