"""``aeromag evaluate``: every tuning policy on the same flights, with paired intervals.

The policies live in the ``agents`` package, imported here lazily (``aeromag_env`` never
imports ``agents`` at module level).
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path
from typing import Any

from aeromag_env import reports
from aeromag_env.atomic import check_output_set, output_set, write_text
from aeromag_env.environment.scenarios import check_scenario
from aeromag_env.errors import AeromagError
from aeromag_env.jobs.reports import jsonable
from aeromag_env.parallel import retry_note, runner

#: The output set of ``aeromag evaluate``, in the folder ``--out``.
OUTPUTS = ("results.json", "evaluation.png", reports.PAGE)


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
    """Evaluate, write ``results.json`` and ``evaluation.png``, print a table; return results.

    ``scenario`` may name several, comma-separated: each gets its output set in
    ``out/<scenario>/`` and the returned dict maps scenario → results. ``ray`` is ``--ray``
    (None: this process; :func:`aeromag_env.parallel.runner`). ``html``: write
    ``report.html`` too (with the first flight's Q/R scales under each policy).
    """
    from tqdm import tqdm

    from agents import POLICIES
    from agents.evaluate import action_traces, evaluate_scenarios

    scenarios = [s.strip() for s in scenario.split(",") if s.strip()]
    if not scenarios or len(set(scenarios)) < len(scenarios):
        raise AeromagError(f"--scenario takes one or more distinct scenarios, got {scenario!r}")
    for s in scenarios:
        check_scenario(s)
    unknown = [p for p in policies if p not in POLICIES and not p.startswith("ppo:")]
    if unknown or not policies:
        raise AeromagError(
            f"unknown policy {unknown[0] if unknown else ''!r}; valid policies: "
            f"{', '.join(POLICIES)}"
        )
    if episodes < 1:
        raise AeromagError(f"--episodes must be ≥ 1, got {episodes}")
    policy_files = [Path(p[4:]) for p in policies if p.startswith("ppo:")]
    outs = {s: out if len(scenarios) == 1 else out / s for s in scenarios}
    outputs = OUTPUTS if html else tuple(n for n in OUTPUTS if n != reports.PAGE)
    for folder in outs.values():
        check_output_set(folder, outputs, policy_files)
    seeds = list(range(seed_start, seed_start + episodes))
    with (
        runner(ray) as tasks,
        tqdm(
            total=episodes * len(policies) * len(scenarios),
            desc=scenario,
            unit="episode",
            disable=quiet or None,
            leave=False,
        ) as bar,
    ):
        results = evaluate_scenarios(scenarios, policies, seeds, progress=bar.update, runner=tasks)
    if note := retry_note(tasks):
        print(f"aeromag evaluate: {note}", file=sys.stderr)
    from aeromag_env.cli.plots import plot_evaluation

    for s, folder in outs.items():
        with output_set(folder, outputs, policy_files) as stage:
            write_text(stage / "results.json", json.dumps(jsonable(results[s]), indent=2))
            plot_evaluation(results[s], stage / "evaluation.png")
            if html:
                traces = action_traces(s, policies, seeds[0])
                page = reports.evaluate_page(jsonable(results[s]), traces)
                write_text(stage / reports.PAGE, page)
        print(evaluation_table(results[s]))
        print(f"wrote {folder}/results.json, evaluation.png")
    return results[scenarios[0]] if len(scenarios) == 1 else results


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
