"""``aeromag evaluate``: every tuning policy on the same flights, with paired intervals.

The policies live in the ``agents`` package, imported here lazily (``aeromag_env`` never
imports ``agents`` at module level).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from aeromag_env.atomic import check_output_set, output_set, write_text
from aeromag_env.cli.compensate import _jsonable
from aeromag_env.environment.scenarios import check_scenario
from aeromag_env.errors import AeromagError

#: The output set of ``aeromag evaluate``, in the folder ``--out``.
OUTPUTS = ("results.json", "evaluation.png")


def run_evaluate(scenario: str, policies: list[str], episodes: int, seed_start: int, out: Path,
                 quiet: bool = False) -> dict[str, Any]:  # fmt: skip
    """Evaluate, write ``results.json`` and ``evaluation.png``, print a table; return results."""
    from tqdm import tqdm

    from agents import POLICIES
    from agents.evaluate import evaluate

    check_scenario(scenario)
    unknown = [p for p in policies if p not in POLICIES and not p.startswith("ppo:")]
    if unknown or not policies:
        raise AeromagError(f"unknown policy {unknown[0] if unknown else ''!r}; valid policies: "
                           f"{', '.join(POLICIES)}")  # fmt: skip
    if episodes < 1:
        raise AeromagError(f"--episodes must be ≥ 1, got {episodes}")
    policy_files = [Path(p[4:]) for p in policies if p.startswith("ppo:")]
    check_output_set(out, OUTPUTS, policy_files)
    seeds = list(range(seed_start, seed_start + episodes))
    with tqdm(total=episodes * len(policies), desc=scenario, unit="episode",
              disable=quiet or None, leave=False) as bar:  # fmt: skip
        results = evaluate(scenario, policies, seeds, progress=bar.update)
    from aeromag_env.cli.plots import plot_evaluation

    with output_set(out, OUTPUTS, policy_files) as stage:
        write_text(stage / "results.json", json.dumps(_jsonable(results), indent=2))
        plot_evaluation(results, stage / "evaluation.png")
    print(evaluation_table(results))
    print(f"wrote {out}/results.json, evaluation.png")
    return results


def evaluation_table(results: dict[str, Any]) -> str:
    """Markdown: mean RMSE [95 % CI], paired difference vs fis [95 % CI], normalized score
    [paired bootstrap 95 % CI] when tuned_constant and oracle were evaluated, divergences."""
    anchors = results.get("normalized_score")
    lines = [
        f"{results['scenario']}: {len(results['seeds'])} flights (seeds {results['seeds'][0]}–"
        f"{results['seeds'][-1]})",
        "",
        "| policy | RMSE [nT] (95 % CI) | − fis [nT] (paired 95 % CI) | median abs log10 ROR "
        "| divergences |" + (" normalized score (95 % CI) |" if anchors else ""),
        "|---|---|---|---|---|" + ("---|" if anchors else ""),
    ]
    for name, r in results["policies"].items():
        diff = ""
        if "diff_vs_fis_nt_mean" in r and name != "fis":
            diff = f"{r['diff_vs_fis_nt_mean']:+.3g} {_interval(r['diff_vs_fis_ci95'], '+.3g')}"
        mean = f"{r['rmse_nt_mean']:.3g} {_interval(r['rmse_nt_ci95'], '.3g')}"
        score = ""
        if anchors and r.get("normalized_score") is not None:
            score = f" {r['normalized_score']:.3g} {_interval(r['normalized_score_ci95'], '.3g')} |"
        elif anchors:
            score = " n/a |"
        lines.append(f"| {name} | {mean} | {diff} | {r['log_ror_abs_median']:.2g} | "
                     f"{r['divergences']} |{score}")  # fmt: skip
    if len(results["seeds"]) < 2:
        lines += ["", "n/a: an interval needs at least 2 flights (--episodes ≥ 2)"]
    if anchors:
        headroom = _interval(anchors["headroom_nt_ci95"], ".3g")
        lines += ["", f"normalized score: 0 = {anchors['zero']}, 1 = {anchors['one']} "
                  f"(headroom {anchors['headroom_nt_mean']:.3g} nT {headroom})"
                  + (f"; {anchors['note']}" if anchors["note"] else "")]  # fmt: skip
    return "\n".join(lines) + "\n"


def _interval(ci: Any, fmt: str) -> str:
    """``[lo, hi]``, or ``[n/a]`` when it could not be computed (a single flight)."""
    lo, hi = (float("nan") if v is None else float(v) for v in ci)
    return f"[{lo:{fmt}}, {hi:{fmt}}]" if math.isfinite(lo) and math.isfinite(hi) else "[n/a]"
