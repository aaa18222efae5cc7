"""Hidden-effect suite for ``aeromag discover``: identification, false alarms, gap shrink.

Simulates every case of :func:`aeromag_env.discovery.suite.suite_cases` (null flights, coloured-
noise nulls, each identifiable effect at SNR 0.5/1/2/4, absorbed effects, pairs, and each effect
at SNR 0.1/0.25/0.5 on 20- to 60-min flights; decoy channels in every flight), runs the discrepancy
workflow on each and writes to ``--out`` (default ``docs/discovery``): ``results.json`` (every
case), ``summary.json`` and ``summary.md`` (the README tables), ``confusion.png``, ``power.png``
and ``power_duration.png``.

Run: ``.venv/bin/python experiments/hidden_effects.py [--single N] [--null N] [--jobs 2]``
(the defaults: 720 flights, about 20 minutes on these 2-core machines, plus the 420 ``duration``
cases of ``--durations 5``, about as long again). Run it as a module from the checkout
(``python -m experiments.hidden_effects``) to test that checkout's package. A subset:
``--only KIND... [--effects NAME...]`` re-runs the cases of those kinds (injecting one of those
effects; null flights always match) and replaces them in ``OUT/results.json``; ``--jobs 1`` runs
in this process.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Iterable, Iterator
from multiprocessing import Pool
from pathlib import Path
from typing import Any

import numpy as np

from aeromag_env.atomic import write_text
from aeromag_env.discovery.power import NULL_KINDS, summarise
from aeromag_env.discovery.suite import (
    DURATIONS_S,
    SNRS,
    Case,
    run_case,
    suite_cases,
)


def _pct(r: dict[str, Any]) -> str:
    lo, hi = (max(100 * v, 0.0) for v in r["ci95"])  # no "-0" from round-off
    return f"{100 * r['rate']:.0f} % ({r['k']}/{r['n']}; 95 % CI {lo:.0f}–{hi:.0f} %)"


def duration_markdown(d: dict[str, Any]) -> list[str]:
    """The power-against-duration tables, one per SNR (rate, k/n and the 95 % interval)."""
    heads = " | ".join(f"{d_s / 60:.0f} min" for d_s in DURATIONS_S)
    lines = [
        "",
        f"Power against flight duration ({d['flights']} flights; detected = the effect with its "
        "channel among the named ones, as in the power column above; decoy channels named on "
        f"these flights: {d['decoy_named']}):",
    ]
    for snr, table in d["power"].items():
        lines += ["", f"| effect (SNR {snr}) | {heads} |", "|---|" + "---|" * len(DURATIONS_S)]
        for nm, cells in table.items():
            row = [_pct(c) if c["n"] else "–" for c in cells.values()]
            lines.append(f"| `{nm}` | " + " | ".join(row) + " |")
    return lines


def markdown(s: dict[str, Any], seconds: float, jobs: int, ran: int | None = None) -> str:
    """``summary.md``; ``ran`` is the number of cases this run simulated when that was a subset."""
    one = s["single_snr_ge_2"]
    fa = s["false_alarm"]
    pct = _pct

    lines = [
        "| claim | target | result |",
        "|---|---|---|",
        f"| single effects at SNR ≥ 2, exact set named | ≥ 90 % | {pct(one['exact_set'])} |",
        f"| single effects at SNR ≥ 2, first named = truth | – | {pct(one['top1'])} |",
        "| false alarms on null flights (nominal + coloured noise) | ≤ 5 % | "
        f"{pct(fa['all_nulls'])} |",
        f"| … coloured-noise nulls only | – | {pct(fa['coloured_null'])} |",
        f"| absorbed effects named | 0 | {s['absorbed']['absorbed_effect_named']} |",
        f"| decoy channels named (all {s['cases_with_decoys']} flights) | 0 | {s['decoy_named']} |",
        f"| held-out gap shrink at SNR ≥ 2, median | ≥ 2× | {one['median_shrink']:.2f}× "
        f"(≥ 2× in {pct(one['shrink_at_least_2'])}) |",
        f"| pairs at SNR 4, exact set | – | {pct(s['pairs_exact_set'])} |",
        "",
        "| effect (SNR ≥ 2) | exact set | median gap shrink | power at SNR 0.5 / 1 / 2 / 4 |",
        "|---|---|---|---|",
    ]
    for nm, e in one["per_effect"].items():
        pw = " / ".join(f"{100 * s['power'][nm][str(x)]['rate']:.0f} %" for x in SNRS)
        lines.append(
            f"| `{nm}` | {100 * e['exact']['rate']:.0f} % | {e['median_shrink']:.1f}× | {pw} |"
        )
    if s["power_duration"]["flights"]:
        lines += duration_markdown(s["power_duration"])
    cases = ", ".join(f"{k} {v}" for k, v in s["cases"].items())
    these = f" for the {ran} cases of this run" if ran is not None else ""
    lines += [
        "",
        f"Cases: {cases}. {seconds / 60:.1f} min with {jobs} processes on this machine{these}.",
    ]
    return "\n".join(lines) + "\n"


def figures(s: dict[str, Any], out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from aeromag_env.atomic import atomic_path

    conf = s["confusion"]
    rows, cols = list(conf), list(next(iter(conf.values())))
    m = np.array([[conf[r][c] for c in cols] for r in rows], float)
    frac = m / np.maximum(m.sum(axis=1, keepdims=True), 1)
    fig, ax = plt.subplots(figsize=(8, 5.5))
    ax.imshow(frac, cmap="Blues", vmin=0, vmax=1)
    for i in range(len(rows)):
        for j in range(len(cols)):
            if m[i, j]:
                ax.text(
                    j,
                    i,
                    f"{int(m[i, j])}",
                    ha="center",
                    va="center",
                    fontsize=8,
                    color="white" if frac[i, j] > 0.5 else "black",
                )
    ax.set_xticks(range(len(cols)), cols, rotation=40, ha="right", fontsize=8)
    ax.set_yticks(range(len(rows)), rows, fontsize=8)
    ax.set_xlabel("named by aeromag discover")
    ax.set_ylabel("injected (SNR ≥ 2)")
    ax.set_title("Hidden-effect suite: confusion (counts of named effects)")
    fig.tight_layout()
    with atomic_path(out / "confusion.png") as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for nm, p in s["power"].items():
        ax.plot(SNRS, [p[str(x)]["rate"] for x in SNRS], "o-", label=nm)
    ax.axhline(0.9, color="k", lw=0.6, ls=":")
    ax.set_xscale("log", base=2)
    ax.set_xticks(SNRS, [str(x) for x in SNRS])
    ax.set_xlabel("identifiable SNR")
    ax.set_ylabel("detection rate (named among the effects)")
    ax.set_title("Detection power")
    ax.legend(fontsize=7)
    fig.tight_layout()
    with atomic_path(out / "power.png") as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)


def duration_figure(d: dict[str, Any], out: Path) -> None:
    """``power_duration.png``: detection rate against flight duration, one panel per SNR."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from aeromag_env.atomic import atomic_path

    minutes = [d_s / 60 for d_s in DURATIONS_S]
    fig, axes = plt.subplots(1, len(d["power"]), figsize=(11, 4.2), sharey=True, squeeze=False)
    for ax, (snr, table) in zip(axes[0], d["power"].items(), strict=True):
        for nm, cells in table.items():
            ax.plot(minutes, [c["rate"] for c in cells.values()], "o-", label=nm)
        ax.axhline(0.9, color="k", lw=0.6, ls=":")
        ax.set_xticks(minutes, [f"{m:.0f}" for m in minutes])
        ax.set_xlabel("flight duration [min]")
        ax.set_title(f"identifiable SNR {snr}")
    axes[0, 0].set_ylabel("detection rate (named among the effects)")
    axes[0, -1].legend(fontsize=7)
    fig.suptitle("Detection power against flight duration (box + descent: first 15 min)")
    fig.tight_layout()
    with atomic_path(out / "power_duration.png") as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)


def _run(cases: list[Case], jobs: int) -> Iterator[dict[str, Any]]:
    """Each case's row, in order: in this process with one job, else in a pool."""
    if jobs == 1:
        yield from map(run_case, cases)
        return
    with Pool(jobs) as pool:
        yield from pool.imap(run_case, cases, chunksize=4)


def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--single", type=int, default=20, help="flights per effect and SNR")
    ap.add_argument("--null", type=int, default=60, help="null flights (nominal noise)")
    ap.add_argument("--coloured", type=int, default=20, help="coloured-noise null flights")
    ap.add_argument("--absorbed", type=int, default=10, help="flights per absorbed effect")
    ap.add_argument("--pairs", type=int, default=10, help="flights per pair")
    ap.add_argument(
        "--durations",
        type=int,
        default=5,
        help="flights per effect, duration and SNR (kind duration)",
    )
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", type=Path, default=Path("docs/discovery"))
    ap.add_argument(
        "--only",
        nargs="+",
        metavar="KIND",
        help="run only these case kinds and replace them in OUT/results.json",
    )
    ap.add_argument(
        "--effects",
        nargs="+",
        metavar="NAME",
        help="with --only: only the cases injecting one of these effects (and the nulls)",
    )
    return ap


def main() -> None:
    ap = _parser()
    args = ap.parse_args()
    if args.effects and not args.only:
        ap.error("--effects needs --only (the subset replaces its cases in OUT/results.json)")
    cases = suite_cases(
        args.null, args.coloured, args.single, args.absorbed, args.pairs, args.durations
    )
    kept: list[dict[str, Any]] = []
    if args.only:

        def selected(kind: str, effects: Iterable[str]) -> bool:
            hit = not args.effects or kind in NULL_KINDS or bool(set(effects) & set(args.effects))
            return kind in args.only and hit

        cases = [c for c in cases if selected(c.kind, c.effects)]
        old = json.loads((args.out / "results.json").read_text())
        kept = [r for r in old if not selected(r["kind"], r["effects"])]
    t0 = time.perf_counter()
    rows = []
    for i, r in enumerate(_run(cases, args.jobs)):
        rows.append(r)
        if (i + 1) % 50 == 0:
            print(f"{i + 1}/{len(cases)} cases, {time.perf_counter() - t0:.0f} s", flush=True)
    seconds = time.perf_counter() - t0
    rows = kept + rows
    s = summarise(rows)
    args.out.mkdir(parents=True, exist_ok=True)
    write_text(args.out / "results.json", json.dumps(rows, indent=1))
    write_text(args.out / "summary.json", json.dumps(s, indent=2))
    ran = len(cases) if args.only else None
    write_text(args.out / "summary.md", markdown(s, seconds, args.jobs, ran))
    figures(s, args.out)
    if s["power_duration"]["flights"]:
        duration_figure(s["power_duration"], args.out)
    print(markdown(s, seconds, args.jobs, ran))


if __name__ == "__main__":
    main()
