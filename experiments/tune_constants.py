"""Find the ``tuned_constant`` baselines: the best constant Q and R scales per scenario, or one
pair for the whole suite (``--suite``).

``python experiments/tune_constants.py [--seeds 8] [--scenarios paper,nominal,...] [--out PATH]``
grid-searches log10 scales of Q (−10…6) and R (−2…6), steps of 1, on training seeds 0…N−1,
minimising the mean episode RMSE (:func:`agents.search.tuned_constant.tune_constant`), and
writes the table — ``--out``'s, or when it does not exist yet the shipped one, with the
searched scenarios' rows replaced — to ``--out`` (default ``results/tuned_constants.json``).
The shipped table, which ``agents`` loads, is replaced only when named: ``--out
agents/policies/tuned_constants.json``.

``--suite``: one constant pair for every scenario of ``--scenarios`` (default: the suite,
``aeromag_env.environment.ids.SUITE``, the scenarios the ``general`` policy trains on), the cell
of the same grid with the lowest mean over the scenarios of ln(mean RMSE)
(:func:`agents.search.tuned_constant.tune_constant_suite`); writes it with every scenario's grid,
the command, the date and the seeds to ``--out`` (default
``results/tuned_constant_suite.json``; the shipped one, which the ``tuned_constant_suite``
policy loads, is ``agents/policies/tuned_constant_suite.json``).

``--suite --choose-from FILE``: choose again from the grids a suite file holds (after a change of
the rule, :func:`agents.search.tuned_constant.choose_suite`), without flying; the record keeps
the command that flew them and adds this one as ``chosen_by``.

``--quick``: the first scenario (two with ``--suite``) on 2 seeds over every fourth grid point.
"""

from __future__ import annotations

import argparse
import datetime
import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import aeromag_env
from aeromag_env.atomic import write_text
from aeromag_env.environment.ids import SUITE
from aeromag_env.environment.scenarios import SCENARIOS
from aeromag_env.quick import add_quick_option
from agents.policies.tuned_table import TABLE
from agents.search.tuned_constant import (
    LOG10_Q_GRID,
    LOG10_R_GRID,
    choose_suite,
    reach_log10,
    tune_constant,
    tune_constant_suite,
)
from agents.training.quick import QUICK

Grids = tuple[Sequence[float], Sequence[float]]


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--seeds", type=int, default=8, help="training seeds 0…N−1 (default 8)")
    parser.add_argument(
        "--scenarios", default=None, help="comma-separated (default: all; --suite: the suite)"
    )
    parser.add_argument("--suite", action="store_true", help="one constant for all scenarios")
    parser.add_argument("--out", type=Path, default=None, help="the table")
    parser.add_argument(
        "--choose-from", type=Path, default=None, help="--suite: choose from this file's grids"
    )
    add_quick_option(parser, "one scenario, 2 seeds, coarse")
    args = parser.parse_args(argv)
    default = SUITE if args.suite else SCENARIOS
    scenarios = args.scenarios.split(",") if args.scenarios else list(default)
    grids: Grids = (LOG10_Q_GRID, LOG10_R_GRID)
    seeds = range(args.seeds)
    if args.quick:
        keep = 2 if args.suite else 1
        scenarios, seeds, grids = (
            scenarios[:keep],
            range(QUICK.seeds),
            (grids[0][::4], grids[1][::4]),
        )
    if args.suite and args.choose_from:
        return _choose_again(args, argv)
    if args.suite:
        return _suite(args, argv, scenarios, seeds, grids)
    out = args.out or Path("results/tuned_constants.json")
    table = json.loads((out if out.exists() else TABLE).read_text())
    for scenario in scenarios:
        t0 = time.perf_counter()
        table[scenario] = row = tune_constant(scenario, seeds, *grids)
        print(
            f"{scenario}: log10 Q ×{row['log10_q']:+.1f}, log10 R ×{row['log10_r']:+.1f}, "
            f"RMSE {row['rmse_nt']:.3g} nT ({time.perf_counter() - t0:.0f} s)",
            flush=True,
        )
    write_text(out, json.dumps(table, indent=2, sort_keys=True) + "\n")
    print(f"wrote {out}")
    return 0


def _suite(
    args: argparse.Namespace,
    argv: Sequence[str] | None,
    scenarios: Sequence[str],
    seeds: Sequence[int],
    grids: Grids,
) -> int:
    """``--suite``: the one constant, written with its provenance."""
    out = args.out or Path("results/tuned_constant_suite.json")
    t0, cells = time.perf_counter(), len(grids[0]) * len(grids[1])
    done: dict[str, int] = {}

    def progress(scenario: str, k: int) -> None:
        done[scenario] = done.get(scenario, 0) + k
        if done[scenario] == cells:
            print(f"{scenario}: {cells} cells ({time.perf_counter() - t0:.0f} s)", flush=True)

    row = tune_constant_suite(scenarios, list(seeds), *grids, progress=progress)
    record = {
        "command": _command(argv),
        "date": datetime.date.today().isoformat(),
        "package_version": aeromag_env.__version__,
        "seconds": round(time.perf_counter() - t0),
        **row,
    }
    return _write_suite(out, record)


def _command(argv: Sequence[str] | None) -> str:
    words = sys.argv[1:] if argv is None else list(argv)
    return " ".join(["python experiments/tune_constants.py", *words])


def _choose_again(args: argparse.Namespace, argv: Sequence[str] | None) -> int:
    """``--suite --choose-from FILE``: the choice again from the file's grids."""
    old = json.loads(args.choose_from.read_text())
    grids = {s: np.asarray(g, dtype=float) for s, g in old["grid_rmse_nt"].items()}
    row = choose_suite(grids, old["grid_log10_q"], old["grid_log10_r"], reach_log10())
    chosen_by = {"command": _command(argv), "date": datetime.date.today().isoformat()}
    record = {**old, **row, "chosen_by": chosen_by}
    return _write_suite(args.out or Path("results/tuned_constant_suite.json"), record)


def _write_suite(out: Path, record: dict) -> int:
    """Write the suite's record to ``out`` and say what it chose."""
    write_text(out, json.dumps(record, indent=2, sort_keys=True) + "\n")
    ratios = ", ".join(f"{s} ×{r:.2f}" for s, r in record["ratio_to_own_best"].items())
    print(
        f"suite: log10 Q ×{record['log10_q']:+.1f}, log10 R ×{record['log10_r']:+.1f}; RMSE over "
        "each "
        f"scenario's own best constant: {ratios}"
    )
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
