"""``aeromag evaluate``: the progress bar and the tables; the job itself is
:func:`agents.jobs.evaluate_policies` (``agents`` imported here lazily: ``aeromag_env`` never
imports it at module level).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Any


def run_evaluate(
    scenario: str,
    policies: list[str],
    episodes: int,
    seed_start: int,
    out: Path,
    quiet: bool = False,
    ray: str | None = None,
    html: bool = True,
) -> dict[str, Any]:
    """Evaluate, write the output sets, print a table per scenario; return the results.

    ``scenario`` may name several, comma-separated: each gets its output set in
    ``out/<scenario>/`` and the returned dict maps scenario → results
    (:func:`agents.jobs.evaluate_policies`).
    """
    from tqdm import tqdm

    from agents.jobs import evaluate_policies

    n_scenarios = len([s for s in scenario.split(",") if s.strip()])
    with tqdm(
        total=episodes * len(policies) * n_scenarios,
        desc=scenario,
        unit="episode",
        disable=quiet or None,
        leave=False,
    ) as bar:
        done = evaluate_policies(
            scenario, policies, episodes, seed_start, out, ray, html, progress=bar.update
        )
    if done.note:
        print(f"aeromag evaluate: {done.note}", file=sys.stderr)
    for name, results in done.results.items():
        folder = out if len(done.results) == 1 else out / name
        print(evaluation_table(results))
        print(f"wrote {folder}/results.json, evaluation.png")
    results = done.results
    return next(iter(results.values())) if len(results) == 1 else results


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
        lines.append(
            f"| {name} | {mean} | {diff} | {r['log_ror_abs_median']:.2g} | "
            f"{r['divergences']} |{score}"
        )
    if len(results["seeds"]) < 2:
        lines += ["", "n/a: an interval needs at least 2 flights (--episodes ≥ 2)"]
    if anchors:
        headroom = _interval(anchors["headroom_nt_ci95"], ".3g")
        lines += [
            "",
            f"normalized score: 0 = {anchors['zero']}, 1 = {anchors['one']} "
            f"(headroom {anchors['headroom_nt_mean']:.3g} nT {headroom})"
            + (f"; {anchors['note']}" if anchors["note"] else ""),
        ]
    return "\n".join(lines) + "\n"


def _interval(ci: Any, fmt: str) -> str:
    """``[lo, hi]``, or ``[n/a]`` when it could not be computed (a single flight)."""
    lo, hi = (float("nan") if v is None else float(v) for v in ci)
    return f"[{lo:{fmt}}, {hi:{fmt}}]" if math.isfinite(lo) and math.isfinite(hi) else "[n/a]"
