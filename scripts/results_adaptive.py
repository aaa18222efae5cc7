"""The adaptive filters' results page (``docs/results/adaptive.md``) from
``docs/results/adaptive_benchmark.json`` as ``experiments/adaptive_benchmark.py`` writes it (the
tables are :func:`agents.comparison.adaptive.summarize`'s, stored in the file; the page reads
them and says what they show). Run by ``scripts/results_pages.py``."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from results_common import num, read, source_line, table

from agents.comparison.adaptive import BENCHMARK_POLICIES, FILTERS

#: The page's results file, under ``docs/``.
DATA = "results/adaptive_benchmark.json"
#: The policies the closing table holds against ``tuned_constant``.
AGAINST_TUNED = ("imm", "tuned_constant_suite", "general")
MARK = {"better": " ▼", "worse": " ▲", "same": " ="}


def _order(d: dict[str, Any]) -> list[str]:
    flown = d["policies"]
    return [p for p in BENCHMARK_POLICIES if p in flown] + [
        p for p in flown if p not in BENCHMARK_POLICIES
    ]


def _cells(d: dict[str, Any], fmt: Any) -> list[list[str]]:
    """One row per policy, one cell per scenario, ``fmt(row)`` of each."""
    return [
        [f"`{p}`", *(fmt(d["tables"][s]["policies"].get(p)) for s in d["scenarios"])]
        for p in _order(d)
    ]


def _header(d: dict[str, Any]) -> list[str]:
    return ["policy", *(f"`{s}`" for s in d["scenarios"])]


def _rmse(row: dict[str, Any] | None) -> str:
    if row is None:
        return "–"
    return num(row["rmse_nt_mean"]) + MARK.get(row.get("vs_tuned_constant", ""), "")


def _score(row: dict[str, Any] | None) -> str:
    if row is None or row.get("normalized_score") is None:
        return "n/a"
    lo, hi = row["normalized_score_ci95"]
    return f"{row['normalized_score']:.2f} [{lo:.2f}, {hi:.2f}]"


def _diff(row: dict[str, Any], ref: str) -> str:
    lo, hi = row[f"diff_vs_{ref}_ci95"]
    return f"{row[f'diff_vs_{ref}_nt_mean']:+.3g} [{lo:+.3g}, {hi:+.3g}]"


def _tables(d: dict[str, Any]) -> list[str]:
    n = len(d["seeds"])
    first = d["tables"][d["scenarios"][0]]["policies"]
    worst = next(iter(first.values()))["worst_flights"]
    return [
        "## Mean RMSE [nT]",
        "",
        "The mean over the test flights of each flight's RMSE of the interference estimate "
        "against the simulator's truth (second half of the flight). ▼ / ▲: better / worse than "
        "`tuned_constant` beyond the paired 95 % t interval over the flights; =: within it.",
        "",
        *table(_header(d), _cells(d, _rmse)),
        "",
        "## The worst 10 % of the flights [nT]",
        "",
        f"The mean RMSE of the worst {worst} of the {n} flights of each scenario (CVaR 10 %).",
        "",
        *table(_header(d), _cells(d, lambda r: "–" if r is None else num(r["worst10_rmse_nt"]))),
        "",
        "## Normalized score",
        "",
        "0 = `tuned_constant`, 1 = `privileged`, on the mean RMSE over the same flights, with a "
        "paired 95 % bootstrap interval; n/a where `privileged` is not better than "
        "`tuned_constant` beyond the paired interval (no headroom).",
        "",
        *table(_header(d), _cells(d, _score)),
        "",
        "## Divergences",
        "",
        "Flights on which the filter diverged (the episode then ends; its RMSE is over the part "
        "flown), of the flights flown per scenario.",
        "",
        *table(
            _header(d),
            _cells(d, lambda r: "–" if r is None else f"{r['diverged_flights']}/{n}"),
        ),
        "",
    ]


def _against_general(d: dict[str, Any]) -> tuple[list[str], list[str]]:
    """The table of the best adaptive filter against ``general`` per scenario, and the
    scenarios where one beats it beyond the interval."""
    rows, beaten = [], []
    for s in d["scenarios"]:
        pol = d["tables"][s]["policies"]
        if "general" not in pol:
            continue
        winners = [f for f in FILTERS if f in pol and pol[f].get("vs_general") == "better"]
        flown = [f for f in FILTERS if f in pol]
        if not flown:
            continue
        best = min(flown, key=lambda f: pol[f]["rmse_nt_mean"])
        if winners:
            beaten.append(f"`{s}` ({', '.join(f'`{w}`' for w in winners)})")
        verdict = pol[best]["vs_general"]
        rows.append(
            [
                f"`{s}`",
                f"`{best}`",
                num(pol[best]["rmse_nt_mean"]),
                num(pol["general"]["rmse_nt_mean"]),
                _diff(pol[best], "general"),
                {"better": "**filter better**", "worse": "general better"}.get(verdict, "same"),
            ]
        )
    header = [
        "scenario",
        "best adaptive filter",
        "its RMSE [nT]",
        "`general` [nT]",
        "filter − general [nT] (paired 95 % CI)",
        "verdict",
    ]
    return table(header, rows), beaten


def _against_tuned(d: dict[str, Any]) -> list[str]:
    """Per scenario and policy of :data:`AGAINST_TUNED`: the paired difference to
    ``tuned_constant`` and the worst-10 % means."""
    rows = []
    for s in d["scenarios"]:
        pol = d["tables"][s]["policies"]
        if "tuned_constant" not in pol:
            continue
        tc = pol["tuned_constant"]
        for p in AGAINST_TUNED:
            if p not in pol:
                continue
            r = pol[p]
            verdict = {"better": "better", "worse": "**worse**"}.get(
                r["vs_tuned_constant"], "within"
            )
            tail = "no higher" if r["worst10_rmse_nt"] <= tc["worst10_rmse_nt"] else "**higher**"
            rows.append(
                [
                    f"`{s}`",
                    f"`{p}`",
                    _diff(r, "tuned_constant"),
                    verdict,
                    f"{num(r['worst10_rmse_nt'])} vs {num(tc['worst10_rmse_nt'])} ({tail})",
                ]
            )
    header = [
        "scenario",
        "policy",
        "− tuned_constant [nT] (paired 95 % CI)",
        "against the interval",
        "worst 10 % vs tuned_constant's [nT]",
    ]
    return table(header, rows)


def _findings(d: dict[str, Any], beaten: list[str]) -> list[str]:
    t = d["tables"]
    out = []
    if "nominal" in t:
        div = {p: r["diverged_flights"] for p, r in t["nominal"]["policies"].items()}
        bad = [f"`{p}` ({k})" for p, k in div.items() if k]
        out.append(
            "* `nominal`: "
            + ("no policy diverged on any flight." if not bad else f"diverged: {', '.join(bad)}.")
        )
    if "noise_bursts" in t and {"vbakf", "constant"} <= set(t["noise_bursts"]["policies"]):
        r = t["noise_bursts"]["policies"]["vbakf"]
        said = {"better": "better than", "worse": "worse than", "same": "not distinguishable from"}
        out.append(
            f"* `noise_bursts` (R moves): `vbakf` is {said[r['vs_constant']]} `constant` "
            f"beyond the paired interval: {_diff(r, 'constant')} nT."
        )
    for p in ("tuned_constant_suite", "general"):
        worse = [s for s in t if t[s]["policies"].get(p, {}).get("vs_tuned_constant") == "worse"]
        flown = [s for s in t if p in t[s]["policies"] and "tuned_constant" in t[s]["policies"]]
        if flown:
            where = f": {', '.join(f'`{s}`' for s in worse)}" if worse else ""
            out.append(
                f"* `{p}` is worse than the per-scenario `tuned_constant` beyond the paired "
                f"interval on {len(worse)} of {len(flown)} scenarios{where}."
            )
    if beaten:
        out.append(
            "* **A classical adaptive filter beats the learned `general` tuner** beyond the paired "
            "interval on " + ", ".join(beaten) + "."
        )
    elif any("general" in t[s]["policies"] for s in t):
        out.append("* No adaptive filter beats `general` beyond the paired interval anywhere.")
    return out


def adaptive_page(docs: Path) -> str:
    """``adaptive.md``: the adaptive filters, the constants and the tuners on fresh flights."""
    d = read(docs, DATA)
    seeds, runs = d["seeds"], d["runs"]
    commands = " then ".join(f"`{r['command']}`" for r in runs)
    vs_general, beaten = _against_general(d)
    lines = [
        "# Adaptive filters and tuners on fresh test flights",
        "",
        source_line(docs, [(DATA, " then ".join(r["command"] for r in runs))]),
        "",
        "The classical adaptive filters (`sage_husa`, `ding`), the variational ones (`vbakf`, "
        "`vbakf_pr`) and the model bank (`imm`), each run by the environment with its own "
        "adaptation while the policy holds Q and R, beside the constants (`constant`, the "
        "per-scenario `tuned_constant`, the scenario-blind `tuned_constant_suite`), the paper's "
        "rules (`fis`), the shipped learned tuner `general` and the `privileged` anchor, on the "
        f"same test flights: {len(seeds)} per scenario, seeds {seeds[0]:,}–{seeds[-1]:,} "
        "(`agents.evaluation.seeds.ADAPTIVE_BENCHMARK_FIRST_SEED`, a range no earlier table "
        f"flew), flown once ({runs[0]['date']}; {commands}). How the scores are defined: "
        "[benchmark methodology](../background/benchmark-methodology.md); the filters' "
        "equations: [adaptive filters](../background/adaptive-filters.md); which to use: "
        "[which method for my flight?](../howto/which-method.md).",
        "",
        "## What it shows",
        "",
        *_findings(d, beaten),
        "",
        *_tables(d),
        "## The best adaptive filter against the learned `general` tuner",
        "",
        "Per scenario, the adaptive filter with the lowest mean RMSE, and the paired difference "
        "to `general` on the same flights (negative: the filter is better).",
        "",
        *vs_general,
        "",
        "## Against `tuned_constant`",
        "",
        "The bar a general tuner must clear: no worse than the per-scenario tuned constant beyond "
        "the paired 95 % t interval, and a worst 10 % no higher than its.",
        "",
        *_against_tuned(d),
    ]
    return "\n".join(lines) + "\n"
