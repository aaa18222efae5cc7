"""The README's tuner table: every policy on every scenario, same test flights, paired CIs.

``python experiments/evaluate_all.py [--episodes 30] [--quick] [--out results/evaluate_all]``
runs ``aeromag evaluate`` per scenario (test seeds from 100 000) and writes ``table.md``, one
``results.json`` per scenario, ``matrix.md`` (policies × scenarios, RMSE and normalized score)
and ``headroom.md``: per scenario, the privileged policy against the untuned ``constant`` (the
headroom bar: at least 15 % better with 95 % intervals apart) and against ``tuned_constant``
(where the normalized score is defined).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aeromag_env.atomic import write_text
from aeromag_env.environment.scenarios import SCENARIOS
from aeromag_env.jobs.evaluate import evaluate, evaluation_table
from aeromag_env.quick import add_quick_option
from agents.policies import available_policies
from agents.training.quick import QUICK


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=30)
    add_quick_option(parser, "2 episodes of 2 scenarios (tests)")
    parser.add_argument("--out", default="results/evaluate_all")
    args = parser.parse_args(argv)
    scenarios = SCENARIOS[: QUICK.scenarios] if args.quick else SCENARIOS
    episodes = QUICK.episodes if args.quick else args.episodes
    out, t0 = Path(args.out), time.perf_counter()
    tables, results = [], {}
    for scenario in scenarios:
        res = evaluate(
            scenario, available_policies(), episodes=episodes, out=out / scenario
        ).results[scenario]
        tables.append(evaluation_table(res))
        results[scenario] = res
    write_text(out / "table.md", "\n".join(tables))
    write_text(out / "matrix.md", matrix(results))
    write_text(out / "headroom.md", headroom(results))
    print(matrix(results))
    print(headroom(results))
    minutes = (time.perf_counter() - t0) / 60
    print(f"wrote {out}/table.md, matrix.md, headroom.md ({minutes:.1f} min)")
    return 0


def matrix(results: dict) -> str:
    """Policies × scenarios: mean RMSE [nT], marked ▲/▼ where the paired 95 % interval of the
    difference to ``fis`` lies entirely above/below zero (worse/better than the paper's rules)."""
    scenarios = list(results)
    lines = ["| policy | " + " | ".join(scenarios) + " |", "|---|" + "---|" * len(scenarios)]
    for name in results[scenarios[0]]["policies"]:
        cells = []
        for sc in scenarios:
            r = results[sc]["policies"][name]
            lo, hi = r.get("diff_vs_fis_ci95", [0.0, 0.0])
            mark = "" if name == "fis" else (" ▼" if hi < 0 else " ▲" if lo > 0 else " =")
            cells.append(f"{r['rmse_nt_mean']:.3g}{mark}")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    about = "Normalized score (0 = tuned_constant, 1 = privileged; paired bootstrap 95 % CI):"
    lines += ["", about, "", lines[0], lines[1]]
    for name in results[scenarios[0]]["policies"]:
        cells = [_score(results[sc], name) for sc in scenarios]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


#: The bar for a scenario with headroom: the privileged policy at least this much better
#: than the untuned constant, with the two policies' 95 % intervals apart.
HEADROOM_BAR = 0.15


def headroom(results: dict) -> str:
    """Per scenario: ``constant`` and ``privileged`` mean RMSE with their 95 % intervals, how
    much better the latter is, whether the intervals are apart and the bar is met, and the
    headroom over ``tuned_constant`` that defines the normalized score."""
    lines = [
        "| scenario | constant [nT] (95 % CI) | privileged [nT] (95 % CI) | better by | "
        "intervals apart | bar met | tuned_constant [nT] | score defined |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for sc, res in results.items():
        pol = res["policies"]
        if not {"constant", "privileged", "tuned_constant"} <= set(pol):
            continue
        c, p = pol["constant"], pol["privileged"]
        better = 1.0 - p["rmse_nt_mean"] / c["rmse_nt_mean"]
        apart = p["rmse_nt_ci95"][1] < c["rmse_nt_ci95"][0]
        met = apart and better >= HEADROOM_BAR
        anchors = res.get("normalized_score") or {}
        defined = "yes" if anchors and not anchors.get("note") else "no"
        lines.append(
            f"| {sc} | {_ci(c)} | {_ci(p)} | {100 * better:.0f} % | {'yes' if apart else 'no'} | "
            f"{'yes' if met else 'no'} | {pol['tuned_constant']['rmse_nt_mean']:.3g} | {defined} |"
        )
    return "\n".join(lines) + "\n"


def _ci(row: dict) -> str:
    lo, hi = row["rmse_nt_ci95"]
    return f"{row['rmse_nt_mean']:.3g} [{lo:.3g}, {hi:.3g}]"


def _score(result: dict, name: str) -> str:
    """``0.77 [0.61, 0.9]``, or why there is none on this scenario."""
    anchors = result.get("normalized_score")
    if anchors is None:
        return "–"
    if anchors["note"]:
        return "n/a (no headroom)"
    r = result["policies"][name]
    lo, hi = r["normalized_score_ci95"]
    return f"{r['normalized_score']:.2g} [{lo:.2g}, {hi:.2g}]"


if __name__ == "__main__":
    sys.exit(main())
