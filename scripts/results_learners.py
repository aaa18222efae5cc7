"""The learners' results page (``docs/results/learners.md``) and the files beside it (two figures
and the learning curves' table), from ``docs/learners/`` as ``experiments/compare_learners.py
evaluate`` writes it; the statistics are :mod:`agents.comparison.statistics`'s. Run by
``scripts/results_pages.py``."""

from __future__ import annotations

import csv
import functools
import io
import math
import statistics
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from results_common import LEARNERS_DATA, num, read, source_line, table

from agents.comparison import statistics as bm

#: The files written beside the page.
CURVES_PNG = "learners_curves.png"
PROFILES_PNG = "learners_profiles.png"
CURVES_CSV = "learners_curves.csv"
#: The performance profiles' thresholds on the figure, and those the page tables.
PROFILE_GRID = np.round(np.linspace(-1.0, 1.5, 251), 10)
PROFILE_TAUS = (0.0, 0.25, 0.5, 0.75, 1.0)


@dataclass(frozen=True)
class Learners:
    """Everything the page shows: ``runs.json``, the per-seed statistics and rliable's
    aggregates (per learner ``(point, low, high)`` rows; empty without a scored scenario), the
    bar per learner and the learning curves."""

    runs: dict[str, Any]
    result: bm.Benchmark
    aggregates: dict[str, np.ndarray]
    improvement: dict[str, np.ndarray]
    profiles: dict[str, np.ndarray]
    bars: dict[str, bm.BarCheck]
    curves: dict[str, bm.Curve]


def _rows(docs: Path, name: str) -> list[dict[str, str]]:
    with (docs / name).open(newline="") as f:
        return list(csv.DictReader(f))


@functools.cache
def learners(docs: Path) -> Learners:
    """The page's numbers from the data under ``docs``, computed once per folder."""
    runs = read(docs, "learners/runs.json")
    flights = bm.flight_table(_rows(docs, "learners/flights.csv"))
    expected = runs["test_flights"]["per_scenario"]
    if flights.flights.shape[1] != expected:
        raise ValueError(
            f"flights.csv has {flights.flights.shape[1]} test flights per scenario, runs.json "
            f"says {expected}"
        )
    result = bm.benchmark(flights)
    scores = result.scores()
    scored = bool(result.headroom.any())
    agg = bm.aggregates(scores) if scored else {}
    no_iqm = np.full(3, np.nan)
    return Learners(
        runs=runs,
        result=result,
        aggregates=agg,
        improvement=bm.improvement(scores) if scored else {},
        profiles=bm.profiles(scores, PROFILE_GRID) if scored else {},
        bars={n: bm.bar(result, n, agg[n][:, 0] if scored else no_iqm) for n in result.learners},
        curves=bm.learning_curves(_rows(docs, "learners/curves.csv"), runs["validation_anchors"]),
    )


def _ci(x: np.ndarray, fmt: str = ".3g") -> str:
    """``point [low, high]`` of ``x = (point, low, high)``; the point alone without an interval;
    ``–`` without a point."""
    point, low, high = (float(v) for v in x)
    if not math.isfinite(point):
        return "–"
    if not (math.isfinite(low) and math.isfinite(high)):
        return f"{point:{fmt}}"
    return f"{point:{fmt}} [{low:{fmt}}, {high:{fmt}}]"


def _score(x: float) -> str:
    return f"{x:.2f}" if math.isfinite(x) else "–"


def _minutes(runs: list[dict[str, Any]], learner: str) -> str:
    m = [r["minutes"] for r in runs if r["learner"] == learner]
    if not m:
        return "–"
    return f"{statistics.fmean(m):.1f} ({min(m):.1f}–{max(m):.1f})"


def _rmse_table(d: Learners) -> list[str]:
    result, names = d.result, d.result.flights.scenarios
    rows = []
    for name, r in result.learners.items():
        cells = np.stack(bm.over_seeds(r.rmse))  # (3, scenarios)
        rows.append(
            [
                f"`{name}`",
                *(_ci(cells[:, k]) for k in range(len(names))),
                _ci(np.stack(bm.over_seeds(r.rmse.mean(axis=1)))),
                _minutes(d.runs["runs"], name),
            ]
        )
    for name, rmse in result.reference_rmse.items():
        rows.append([f"`{name}`", *(num(x) for x in rmse), num(rmse.mean()), "–"])
    return [
        "### Mean RMSE [nT]",
        "",
        "Each training seed's mean RMSE over the test flights; the mean over seeds and its 95 % "
        "t interval over seeds. The reference policies flew the same flights once. Last column: "
        "wall-clock minutes of training per seed, validation included (mean, range).",
        "",
        *table(
            ["policy", *(f"`{s}`" for s in names), "mean over scenarios", "minutes per seed"],
            rows,
        ),
        "",
    ]


def _score_table(d: Learners) -> list[str]:
    result = d.result
    left_out = [s for s in result.flights.scenarios if s not in result.scored]
    intro = (
        "Each seed's score on its mean RMSE over the test flights: 0 = `tuned_constant`, "
        "1 = `privileged`, on the same flights; the mean over seeds and its 95 % t interval over "
        "seeds."
    )
    if left_out:
        intro += (
            " Left out, without headroom (`privileged` not better than `tuned_constant` beyond "
            "the paired 95 % t interval over flights): "
            + ", ".join(f"`{s}`" for s in left_out)
            + "."
        )
    lines = ["### Normalized score", "", intro, ""]
    if not result.scored:
        return [*lines, "No scenario has headroom: there are no scores.", ""]
    rows = []
    for name, s in result.scores().items():
        cells = np.stack(bm.over_seeds(s))
        rows.append(
            [
                f"`{name}`",
                *(_ci(cells[:, k], ".2f") for k in range(s.shape[1])),
                _ci(np.stack(bm.over_seeds(s.mean(axis=1))), ".2f"),
            ]
        )
    refs = result.reference_rmse
    for name in (n for n in refs if n not in (bm.SCORE_ZERO, bm.SCORE_ONE)):
        score = bm.normalized_score(refs[name], refs[bm.SCORE_ZERO], refs[bm.SCORE_ONE])
        score = score[result.headroom]
        rows.append([f"`{name}`", *(_score(x) for x in score), _score(score.mean())])
    header = ["policy", *(f"`{s}`" for s in result.scored), "mean over scenarios"]
    return [*lines, *table(header, rows), ""]


def _tail_table(d: Learners) -> list[str]:
    result, names = d.result, d.result.flights.scenarios
    n = result.flights.flights.shape[1]
    worst = bm.tail_size(n)
    rows = [[f"`{bm.SCORE_ZERO}`", *(num(x) for x in result.reference_cvar[bm.SCORE_ZERO])]]
    rows += [[f"`{k}`", *(num(x) for x in r.cvar.mean(axis=0))] for k, r in result.learners.items()]
    return [
        "## The tail",
        "",
        f"The mean RMSE of the worst {100 * bm.CVAR_FRACTION:.0f} % of the test flights (CVaR: "
        f"the worst {worst} of {n} in each scenario) [nT]: per learner the mean over seeds of "
        "each seed's, and the tuned constant's on the same flights.",
        "",
        *table(["policy", *(f"`{s}`" for s in names)], rows),
        "",
    ]


def _aggregate_tables(d: Learners) -> list[str]:
    lines = ["## Over seeds × scenarios (rliable)", ""]
    if not d.aggregates:
        return [*lines, "No scenario has headroom: there are no scores to aggregate.", ""]
    base = bm.BASELINE
    rows = []
    for name, r in d.result.learners.items():
        a = d.aggregates[name]
        row = [f"`{name}`", str(len(r.seeds)), *(_ci(a[:, j], ".2f") for j in range(a.shape[1]))]
        row.append(_ci(d.improvement[name], ".2f") if name in d.improvement else "–")
        rows.append(row)
    picks = [int(np.flatnonzero(np.isclose(PROFILE_GRID, t))[0]) for t in PROFILE_TAUS]
    profile_rows = [
        [f"`{name}`", *(_ci(p[:, j], ".2f") for j in picks)] for name, p in d.profiles.items()
    ]
    versus = (
        f"The probability of improvement over `{base}`: the chance that a seed of the learner "
        f"scores above a seed of `{base}` on a scenario, averaged over the scenarios (0.5: no "
        "difference)."
        if d.improvement
        else f"Without `{base}` runs there is no probability of improvement over it."
    )
    return [
        *lines,
        f"The normalized scores of each learner's seeds × the {len(d.result.scored)} scenarios "
        "with headroom, aggregated as rliable does (Agarwal et al. 2021): the interquartile mean "
        "(IQM), the mean, the optimality gap (the mean shortfall below 1; lower is better), each "
        "with a stratified-bootstrap 95 % interval (seeds resampled within each scenario, "
        f"{bm.BOOTSTRAP_RESAMPLES} resamples, a fixed seed). " + versus,
        "",
        *table(["learner", "seeds", *bm.AGGREGATES, f"P(better than `{base}`)"], rows),
        "",
        "### Performance profiles",
        "",
        "The fraction of a learner's seed × scenario scores above a threshold τ, with its "
        "stratified-bootstrap 95 % interval.",
        "",
        *table(["learner", *(f"τ = {t:g}" for t in PROFILE_TAUS)], profile_rows),
        "",
        f"![Performance profiles of the learners]({PROFILES_PNG})",
        "",
    ]


def _met(ok: bool, text: str) -> str:
    return f"met: {text}" if ok else f"**not met**: {text}"


def _worse(b: bm.BarCheck) -> str:
    """(a)'s cell: per scenario the seeds worse than the tuned constant, with their excess."""
    by: dict[str, list[str]] = {}
    for seed, scenario, excess in b.worse:
        by.setdefault(scenario, []).append(f"{seed} (+{excess:.2g} nT)")
    return "; ".join(f"`{s}` seed {', '.join(v)}" for s, v in by.items()) or "no seed worse"


def _bar_table(d: Learners) -> list[str]:
    rows = []
    for name, b in d.bars.items():
        met = b.met
        tail = ", ".join(f"`{s}` {num(x)} vs {num(y)} nT" for s, x, y in b.tail)
        rows.append(
            [
                f"`{name}`",
                _met(met[0], _worse(b)),
                _met(met[1], tail or "no scenario higher"),
                _met(met[2], f"{num(b.nonstationary[0])} vs {num(b.nonstationary[1])} nT"),
                _met(met[3], _ci(b.iqm, ".2f")),
                f"{sum(met)} of 4",
            ]
        )
    return [
        "## The bar for a shipped general policy",
        "",
        "Issue 41's bar, per learner: (a) on the test flights of every scenario, no seed worse "
        "than `tuned_constant` beyond the paired 95 % t interval over flights; (b) in every "
        "scenario the worst-10 % mean (the tail above, mean over seeds) no higher than "
        f"`tuned_constant`'s; (c) on `{bm.BAR_SCENARIO}` the mean RMSE over seeds at most "
        "`tuned_constant`'s; (d) the IQM of the normalized score over seeds × scenarios at "
        f"least {bm.BAR_IQM} (shown with its interval).",
        "",
        *table(
            [
                "learner",
                "(a) seeds worse than `tuned_constant`",
                "(b) worst-10 % mean against `tuned_constant`'s",
                f"(c) `{bm.BAR_SCENARIO}` against `tuned_constant`",
                "(d) IQM",
                "criteria met",
            ],
            rows,
        ),
        "",
    ]


def _verdict(d: Learners) -> list[str]:
    lines = []
    if d.aggregates:
        best = max(d.aggregates, key=lambda n: d.aggregates[n][0, 0])
        lines.append(
            "* Best by the IQM of the normalized score over seeds × scenarios: "
            f"**`{best}`**, {_ci(d.aggregates[best][:, 0], '.2f')}."
        )
    else:
        rmse = {n: r.rmse.mean() for n, r in d.result.learners.items()}
        best = min(rmse, key=lambda n: rmse[n])
        lines.append(
            "* No scenario has headroom, so there are no scores; the lowest mean RMSE over "
            f"seeds × scenarios: **`{best}`**, {num(rmse[best])} nT."
        )
    passed = [n for n, b in d.bars.items() if all(b.met)]
    if passed:
        names = ", ".join(f"**`{n}`**" for n in passed)
        lines.append(f"* The bar for a shipped general policy is met by {names}.")
    else:
        near = bm.closest(d.bars)
        b = d.bars[near]
        missed = ", ".join(f"({c})" for c, ok in zip("abcd", b.met, strict=True) if not ok)
        lines.append(
            "* No learner meets the bar for a shipped general policy. The closest (most criteria "
            f"met, then the highest IQM): **`{near}`**, {sum(b.met)} of 4; not met: {missed}."
        )
    return lines


def _curve_table(d: Learners) -> list[str]:
    rows = []
    for name, c in d.curves.items():
        best = int(np.argmax(c.score))
        rows.append(
            [
                f"`{name}`",
                str(len(c.score)),
                f"{c.timesteps[-1]:,.0f}",
                f"{c.minutes[-1]:.1f}",
                _ci(np.array([c.score[-1], c.low[-1], c.high[-1]]), ".2f"),
                f"{c.score[best]:.2f} at {c.timesteps[best]:,.0f} steps",
            ]
        )
    return [
        "## Learning curves",
        "",
        "The normalized score on the validation flights (never test flights) at each validation "
        "point of training: per scenario against the anchors' mean RMSE on the same validation "
        "flights, averaged over the scenarios whose validation headroom is positive; the mean "
        "over seeds with its 95 % t interval. The seeds' k-th points are matched (their steps "
        "agree but where training ended or a CMA-ES generation overshot) and placed at the mean "
        "of their steps and of their training minutes (validation excluded).",
        "",
        f"![Learning curves of the learners]({CURVES_PNG})",
        "",
        *table(
            [
                "learner",
                "validation points",
                "steps at the end",
                "minutes at the end",
                "score at the end",
                "best mean score",
            ],
            rows,
        ),
        "",
        f"Every point of the curves: {{download}}`{CURVES_CSV}`.",
        "",
    ]


def _runs_table(d: Learners) -> list[str]:
    runs = d.runs["runs"]
    rows = []
    for name in d.result.learners:
        mine = sorted((r for r in runs if r["learner"] == name), key=lambda r: r["seed"])
        if not mine:
            continue
        best = [r["best_validation_score"] for r in mine if r["best_validation_score"] is not None]
        rows.append(
            [
                f"`{name}`",
                ", ".join(str(r["seed"]) for r in mine),
                " / ".join(f"{s:,}" for s in sorted({r["timesteps"] for r in mine})),
                _minutes(runs, name),
                ", ".join(f"{r['kept_timesteps']:,}" for r in mine),
                num(statistics.fmean(best)) if best else "–",
            ]
        )
    return [
        "## The training runs",
        "",
        "Per learner its runs (`runs.json` also holds each run's hyperparameters): environment "
        "steps, wall-clock minutes per seed (validation included; mean and range), the steps of "
        "the kept checkpoint (the best on validation) per seed, and the best validation score "
        "(the worst scenario's mean RMSE ratio to `tuned_constant`, lower is better; mean over "
        "seeds).",
        "",
        *table(
            [
                "learner",
                "seeds",
                "steps",
                "minutes per seed",
                "kept checkpoint [steps]",
                "best validation score",
            ],
            rows,
        ),
    ]


def _selection(docs: Path, d: Learners) -> list[str]:
    """The policy chosen to ship (``selection.json``: validation flights only) and how that one
    seed did on the test flights, scenario by scenario, against the tuned constant."""
    path = docs / "learners" / "selection.json"
    if not path.exists():
        return []
    sel = read(docs, "learners/selection.json")
    learner, seed = sel["chosen"]["learner"], int(sel["chosen"]["seed"])
    means = sel["learner_mean_score"]
    rows = [
        [f"`{n}`", num(means[n]), str(sum(1 for k in sel["runs"] if k.startswith(f"{n}/")))]
        for n in sorted(means, key=means.__getitem__)
    ]
    lines = [
        "## The policy chosen to ship",
        "",
        source_line(docs, [("learners/selection.json", writing_docs(sel["command"]))]),
        "",
        f"Chosen on validation flights only ({sel['validation_flights_per_scenario']} per "
        "scenario, the same for every seed of every learner; the score is the worst scenario's "
        "mean RMSE ratio to `tuned_constant`, lower is better): the learner with the lowest mean "
        "score over its seeds, and of it the seed with the lowest score.",
        "",
        *table(["learner", "mean validation score over seeds", "seeds"], rows),
        "",
        f"Chosen: **`{learner}`, training seed {seed}**.",
    ]
    r = d.result.learners.get(learner)
    if r is None or seed not in r.seeds:
        return [*lines, ""]
    i = r.seeds.index(seed)
    tc = d.result.reference_rmse["tuned_constant"]
    tc_cvar = d.result.reference_cvar["tuned_constant"]
    test = [
        [
            f"`{s}`",
            num(r.rmse[i, k]),
            num(tc[k]),
            num(r.cvar[i, k]),
            num(tc_cvar[k]),
            "yes" if r.worse[i, k] else "no",
        ]
        for k, s in enumerate(d.result.flights.scenarios)
    ]
    return [
        *lines,
        "",
        "Its test flights, flown once (the same flights as the tables above):",
        "",
        *table(
            [
                "scenario",
                "RMSE [nT]",
                "tuned_constant [nT]",
                "worst 10 % [nT]",
                "tuned_constant's worst 10 % [nT]",
                "worse beyond the paired 95 % CI",
            ],
            test,
        ),
        "",
    ]


def writing_docs(command: str) -> str:
    """A recorded command of ``experiments/compare_learners.py`` as it writes into
    ``docs/learners/``: with ``--data docs/learners`` when it names no data folder (the
    script's default folder is under ``results/``)."""
    return command if "--data" in command.split() else f"{command} --data docs/learners"


def learners_page(docs: Path) -> str:
    """``learners.md``: the learners for the general tuner on the same test flights."""
    d = learners(docs)
    test = d.runs["test_flights"]
    first, n = test["first_seed"], test["per_scenario"]
    seeds = ", ".join(f"`{name}` {len(r.seeds)}" for name, r in d.result.learners.items())
    command = writing_docs(d.runs["command"])
    lines = [
        "# Learners for the general tuner",
        "",
        source_line(docs, [(name, command) for name in LEARNERS_DATA]),
        "",
        "One policy for every scenario of the suite, trained by each learner of "
        "`agents/training/learners.py` over several training seeds; each run keeps its best "
        "checkpoint on validation flights, and every seed's policy then flies the same fresh test "
        f"flights beside the reference policies. Evaluated on {d.runs['date']}: {n} test flights "
        f"per scenario (seeds {first:,}–{first + n - 1:,}, never flown for a choice); training "
        f"seeds per learner: {seeds}. How the scores are defined: "
        "[benchmark methodology](../background/benchmark-methodology.md).",
        "",
        "## Verdict",
        "",
        *_verdict(d),
        "",
        "## The benchmark",
        "",
        *_rmse_table(d),
        *_score_table(d),
        *_tail_table(d),
        *_aggregate_tables(d),
        *_bar_table(d),
        *_selection(docs, d),
        *_curve_table(d),
        *_runs_table(d),
    ]
    return "\n".join(lines) + "\n"


# --- the files beside the page ----------------------------------------------------------------


def _color(name: str) -> str:
    """A learner's colour, the same in every figure: its place in ``LEARNERS``."""
    return f"C{bm.LEARNERS.index(name)}" if name in bm.LEARNERS else "0.3"


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _png(fig: Any) -> bytes:
    """A figure as PNG bytes, the same for the same data (no software stamp)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100, metadata={"Software": None})
    _pyplot().close(fig)
    return buf.getvalue()


def _curves_figure(curves: dict[str, bm.Curve]) -> bytes:
    fig, axes = _pyplot().subplots(1, 2, figsize=(12, 4.5), constrained_layout=True)
    lowest = 0.0
    for name, c in curves.items():
        for ax, x in zip(axes, (c.timesteps, c.minutes), strict=True):
            ax.plot(x, c.score, marker=".", label=name, color=_color(name))
            ok = np.isfinite(c.low)
            ax.fill_between(x[ok], c.low[ok], c.high[ok], color=_color(name), alpha=0.2)
        lowest = min(lowest, float(np.min(np.where(np.isfinite(c.low), c.low, c.score))))
    bottom = max(-1.0, lowest - 0.05)
    for ax, label in zip(axes, ("environment steps", "training minutes (wall clock)"), strict=True):
        ax.axhline(0, color="0.5", lw=0.8)
        ax.axhline(1, color="0.5", lw=0.8, ls="--")
        ax.set(xlabel=label, ylabel="normalized score (validation)", ylim=(bottom, 1.1))
        ax.grid(alpha=0.3)
    axes[0].set_xscale("log")
    axes[0].legend(loc="lower right")
    clipped = " (clipped at -1)" if lowest < -1.0 else ""
    fig.suptitle(f"Validation score, mean over seeds with its 95 % interval{clipped}")
    return _png(fig)


def _profiles_figure(profiles: dict[str, np.ndarray]) -> bytes:
    fig, ax = _pyplot().subplots(figsize=(6.5, 4.5), constrained_layout=True)
    for name, p in profiles.items():
        ax.step(PROFILE_GRID, p[0], where="post", label=name, color=_color(name))
        ax.fill_between(PROFILE_GRID, p[1], p[2], step="post", color=_color(name), alpha=0.2)
    ax.set(
        xlabel="normalized score τ",
        ylabel="fraction of seed × scenario scores > τ",
        ylim=(-0.02, 1.02),
        title="Performance profiles, 95 % intervals",
    )
    ax.grid(alpha=0.3)
    ax.legend(loc="lower left")
    return _png(fig)


def _curves_csv(curves: dict[str, bm.Curve]) -> str:
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(["learner", "point", "seeds", "timesteps", "minutes", "score", "low", "high"])
    for name, c in curves.items():
        for k in range(len(c.score)):
            w.writerow(
                [
                    name,
                    k,
                    int(c.seeds[k]),
                    f"{c.timesteps[k]:.0f}",
                    f"{c.minutes[k]:.3f}",
                    *(f"{x:.6g}" for x in (c.score[k], c.low[k], c.high[k])),
                ]
            )
    return out.getvalue()


def learners_files(docs: Path) -> dict[str, str | bytes]:
    """The files beside ``learners.md``: the two figures and the learning curves' table."""
    d = learners(docs)
    files: dict[str, str | bytes] = {
        CURVES_PNG: _curves_figure(d.curves),
        CURVES_CSV: _curves_csv(d.curves),
    }
    if d.profiles:
        files[PROFILES_PNG] = _profiles_figure(d.profiles)
    return files
