"""The hidden-effect suite run and written down: its cases in processes, and from their rows
(``aeromag_env.discovery.suite.run_case``) and ``aeromag_env.discovery.power.summarise``'s
summary the files the documentation shows.

``write_suite`` writes, as one output set: ``results.json`` (every case's row),
``summary.json`` (the summary), ``summary.md`` (``summary_markdown``: the claims, the power
per effect and against flight duration), ``confusion.png``, ``power.png`` and, when the rows hold
``duration`` cases, ``power_duration.png``. ``experiments/hidden_effects.py`` is its command
line; the committed set is ``docs/discovery/``.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable, Iterator, Sequence
from multiprocessing import Pool
from pathlib import Path
from typing import Any

import numpy as np

from aeromag_env.atomic import output_set
from aeromag_env.discovery.power import NULL_KINDS, summarise
from aeromag_env.discovery.suite import DURATIONS_S, SNRS, Case, run_case

#: The files of a run of the suite, but the duration figure (:data:`DURATION_FIGURE`).
SUITE_FILES = ("results.json", "summary.json", "summary.md", "confusion.png", "power.png")
#: The figure of the ``duration`` cases, written when the rows hold some.
DURATION_FIGURE = "power_duration.png"
#: Resolution of the figures [dots per inch].
DPI = 110


def run_cases(
    cases: Sequence[Case], jobs: int, progress: Callable[[int], None] | None = None
) -> list[dict[str, Any]]:
    """Every case's row, in the cases' order: in this process with one job, else in a pool of
    ``jobs`` processes; ``progress(k)`` is called with the count of rows done after each."""
    rows: list[dict[str, Any]] = []
    for row in _rows(cases, jobs):
        rows.append(row)
        if progress is not None:
            progress(len(rows))
    return rows


def _rows(cases: Sequence[Case], jobs: int) -> Iterator[dict[str, Any]]:
    if jobs == 1:
        yield from map(run_case, cases)
        return
    with Pool(jobs) as pool:
        yield from pool.imap(run_case, cases, chunksize=4)


def in_subset(
    kind: str, effects: Iterable[str], kinds: Sequence[str], names: Sequence[str] | None = None
) -> bool:
    """Whether a case (or a row) of ``kind`` injecting ``effects`` belongs to a re-run of the
    case kinds ``kinds``, restricted, when ``names`` are given, to the cases injecting one of
    those effects (a null flight always matches them)."""
    hit = not names or kind in NULL_KINDS or bool(set(effects) & set(names))
    return kind in kinds and hit


def _pct(r: dict[str, Any]) -> str:
    lo, hi = (max(100 * v, 0.0) for v in r["ci95"])  # no "-0" from round-off
    return f"{100 * r['rate']:.0f} % ({r['k']}/{r['n']}; 95 % CI {lo:.0f}–{hi:.0f} %)"


def duration_markdown(d: dict[str, Any]) -> list[str]:
    """The power-against-duration tables of ``summary["power_duration"]``, one per SNR (rate,
    k/n and the 95 % interval per effect and duration)."""
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


def _claims(s: dict[str, Any]) -> list[str]:
    one, fa, pct = s["single_snr_ge_2"], s["false_alarm"], _pct
    return [
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
    ]


def summary_markdown(s: dict[str, Any], seconds: float, jobs: int, ran: int | None = None) -> str:
    """``summary.md`` from the summary ``s``: the claims, the power per effect and SNR, the
    power against flight duration (when there are ``duration`` cases) and the cases, with the
    run's ``seconds`` [s] on ``jobs`` processes; ``ran`` is the number of cases the run
    simulated when that was a subset of the rows."""
    lines = [
        *_claims(s),
        "",
        "| effect (SNR ≥ 2) | exact set | median gap shrink | power at SNR 0.5 / 1 / 2 / 4 |",
        "|---|---|---|---|",
    ]
    for nm, e in s["single_snr_ge_2"]["per_effect"].items():
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


def confusion_figure(s: dict[str, Any], path: Path) -> None:
    """The confusion of the named effects (counts; rows the injected effect at SNR ≥ 2 and the
    null flights, columns what was named) as a PNG at ``path``."""
    from aeromag_env.flight.plot import pyplot

    plt = pyplot()
    conf = s["confusion"]
    rows, cols = list(conf), list(next(iter(conf.values())))
    m = np.array([[conf[r][c] for c in cols] for r in rows], float)
    frac = m / np.maximum(m.sum(axis=1, keepdims=True), 1)
    fig, ax = plt.subplots(figsize=(8, 5.5))
    ax.imshow(frac, cmap="Blues", vmin=0, vmax=1)
    for i, j in zip(*np.nonzero(m), strict=True):
        colour = "white" if frac[i, j] > 0.5 else "black"
        ax.text(j, i, f"{int(m[i, j])}", ha="center", va="center", fontsize=8, color=colour)
    ax.set_xticks(range(len(cols)), cols, rotation=40, ha="right", fontsize=8)
    ax.set_yticks(range(len(rows)), rows, fontsize=8)
    ax.set_xlabel("named by aeromag discover")
    ax.set_ylabel("injected (SNR ≥ 2)")
    ax.set_title("Hidden-effect suite: confusion (counts of named effects)")
    fig.tight_layout()
    fig.savefig(path, dpi=DPI, format="png")
    plt.close(fig)


def power_figure(s: dict[str, Any], path: Path) -> None:
    """Detection rate against the identifiable SNR, one line per effect, as a PNG at ``path``."""
    from aeromag_env.flight.plot import pyplot

    plt = pyplot()
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
    fig.savefig(path, dpi=DPI, format="png")
    plt.close(fig)


def duration_figure(d: dict[str, Any], path: Path) -> None:
    """Detection rate against flight duration [min], one panel per SNR, from
    ``summary["power_duration"]``, as a PNG at ``path``."""
    from aeromag_env.flight.plot import pyplot

    plt = pyplot()
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
    fig.savefig(path, dpi=DPI, format="png")
    plt.close(fig)


def write_suite(
    rows: list[dict[str, Any]], out: Path, seconds: float, jobs: int, ran: int | None = None
) -> str:
    """Summarise ``rows`` and write the suite's files into ``out`` as one set (module
    docstring); ``seconds``, ``jobs`` and ``ran`` as :func:`summary_markdown`'s. Returns
    ``summary.md``'s text."""
    s = summarise(rows)
    text = summary_markdown(s, seconds, jobs, ran)
    with_duration = bool(s["power_duration"]["flights"])
    names = (*SUITE_FILES, DURATION_FIGURE) if with_duration else SUITE_FILES
    with output_set(out, names) as stage:
        (stage / "results.json").write_text(json.dumps(rows, indent=1), encoding="utf-8")
        (stage / "summary.json").write_text(json.dumps(s, indent=2), encoding="utf-8")
        (stage / "summary.md").write_text(text, encoding="utf-8")
        confusion_figure(s, stage / "confusion.png")
        power_figure(s, stage / "power.png")
        if with_duration:
            duration_figure(s["power_duration"], stage / DURATION_FIGURE)
    return text
