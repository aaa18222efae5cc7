"""Do two runs of the hidden-effect suite name the same effects? (A check after a speed change.)

Compares two ``results.json`` files of :mod:`experiments.hidden_effects` case by case (kind and
seed): the named effects with their channels must be equal; the held-out gaps are compared as
the largest relative change. Cases in only one file are counted, not compared.

Run, after re-running the suite at the committed sizes into a scratch folder::

    python experiments/hidden_effects.py --single 10 --null 40 --coloured 20 --absorbed 5 \\
        --pairs 5 --durations 4 --out /tmp/rerun
    python experiments/same_verdicts.py docs/discovery/results.json /tmp/rerun/results.json

Exit status 1 when any named list differs. It measures nothing itself (no ``--quick``: it takes
a second).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any


def compare(old: list[dict[str, Any]], new: list[dict[str, Any]]) -> dict[str, Any]:
    """Case-by-case comparison: differing cases, compared and unmatched counts, gap change."""
    by_key = {(r["kind"], r["seed"]): r for r in old}
    differ, compared, worst = [], 0, 0.0
    for row in new:
        ref = by_key.get((row["kind"], row["seed"]))
        if ref is None:
            continue
        compared += 1
        if sorted(map(tuple, ref["named"])) != sorted(map(tuple, row["named"])):
            differ.append(
                {"kind": row["kind"], "seed": row["seed"], "was": ref["named"], "now": row["named"]}
            )
        for key in ("gap_before_nt", "gap_after_nt"):
            worst = max(worst, abs(row[key] - ref[key]) / max(abs(ref[key]), 1e-12))
    return {
        "compared": compared,
        "unmatched": len(new) - compared,
        "differ": differ,
        "max_relative_gap_change": worst,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("old", type=Path, help="the reference run's results.json")
    parser.add_argument("new", type=Path, help="the new run's results.json")
    args = parser.parse_args(argv)
    old, new = (json.loads(p.read_text()) for p in (args.old, args.new))
    out = compare(old, new)
    for d in out["differ"]:
        print(f"{d['kind']} seed {d['seed']}: {d['was']} -> {d['now']}")
    print(
        f"{out['compared']} cases compared ({out['unmatched']} unmatched): "
        f"{len(out['differ'])} name different effects; held-out gaps change by at most "
        f"{out['max_relative_gap_change']:.1e} (relative)"
    )
    return 1 if out["differ"] else 0


if __name__ == "__main__":
    raise SystemExit(main())
