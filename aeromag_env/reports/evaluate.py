"""The page of ``aeromag evaluate``: every tuning policy on the same flights.

Shown: a table per policy (mean RMSE with its 95 % interval, the paired difference to ``fis``,
the normalized score with its interval, divergences); each flight's RMSE across the policies
(paired lines: one line per flight); the normalized score with its interval; and, when given,
one flight's Q and R scales over time as each policy set them.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from aeromag_env.reports import html as h
from aeromag_env.reports.html import COLOURS
from aeromag_env.reports.plots import finish_legend, lines, new_figure


@h.page_builder
def evaluate_page(
    results: dict[str, Any], traces: dict[str, dict[str, np.ndarray]] | None = None
) -> str:
    """The HTML page of one scenario's evaluation.

    Parameters
    ----------
    results : dict
        What ``results.json`` holds (``scenario``, ``seeds``, ``policies``, optional
        ``normalized_score``).
    traces : dict, optional
        Policy → ``t`` (k,) [s], ``q_scale`` and ``r_scale`` (k,) [-]: one flight's
        cumulative Q and R scales after each decision, for every policy (``seed`` (1,) names
        the flight).

    Returns
    -------
    str
        A self-contained HTML document.
    """
    names = list(results["policies"])
    seeds = results["seeds"]
    blocks: list[Any] = [h.heading("Policies"), h.card(_table(results))]
    anchors = results.get("normalized_score")
    if anchors:
        blocks.append(
            f"<p>normalized score: 0 = {h.esc(anchors.get('zero'))}, "
            f"1 = {h.esc(anchors.get('one'))}"
            + (f"; {h.esc(anchors['note'])}" if anchors.get("note") else "")
            + "</p>"
        )
    blocks += [h.heading("RMSE of each flight across the policies"), _paired(results, names)]
    if anchors:
        blocks += [h.heading("Normalized score (95 % interval)"), _scores(results, names)]
    if traces:
        seed = next(iter(traces.values())).get("seed")
        which = f" (seed {int(seed[0])})" if seed is not None else ""
        blocks.append(h.heading(f"Q and R scales over one flight{which}"))
        blocks += _traces(traces)
    subtitle = (
        f"scenario {results['scenario']} · {len(seeds)} flights (seeds {seeds[0]}–{seeds[-1]})"
    )
    return h.render_page(f"Evaluation: {results['scenario']}", subtitle, blocks)


def _table(results: dict[str, Any]) -> str:
    rows = []
    for name, r in results["policies"].items():
        base = f"policies.{name}"
        ci = r.get("rmse_nt_ci95") or [None, None]
        diff = r.get("diff_vs_fis_ci95") or [None, None]
        score_ci = r.get("normalized_score_ci95") or [None, None]
        rows.append(
            [
                name,
                h.Headline("RMSE", f"{base}.rmse_nt_mean", r.get("rmse_nt_mean")),
                ci[0],
                ci[1],
                r.get("diff_vs_fis_nt_mean") if name != "fis" else None,
                diff[0] if name != "fis" else None,
                diff[1] if name != "fis" else None,
                h.Headline("score", f"{base}.normalized_score", r.get("normalized_score")),
                score_ci[0],
                score_ci[1],
                h.Headline("divergences", f"{base}.divergences", r.get("divergences")),
            ]
        )
    header = [
        "policy",
        "RMSE [nT]",
        "CI low",
        "CI high",
        "− fis [nT]",
        "CI low",
        "CI high",
        "normalized score",
        "CI low",
        "CI high",
        "divergences",
    ]
    return h.table(header, rows)


def _paired(results: dict[str, Any], names: list[str]) -> Any:
    """One grey line per flight through its RMSE under each policy; dots coloured by policy."""
    from bokeh.models import ColumnDataSource, Whisker

    fig = new_figure(
        "RMSE per flight (one line per flight; mean and 95 % interval in black)",
        "policy",
        "RMSE [nT]",
        height=380,
        x_range=names,
        y_log=True,
        tools="pan,wheel_zoom,box_zoom,reset,save,hover",
        tooltips=[("policy", "@policy"), ("seed", "@seed"), ("RMSE", "@rmse{0.000} nT")],
    )
    per = np.array([results["policies"][n]["rmse_nt"] for n in names], dtype=float)
    seeds = results["seeds"]
    xs = [names] * per.shape[1]
    fig.multi_line(
        xs, [list(per[:, j]) for j in range(per.shape[1])], color="#9aa3b2", alpha=0.5, line_width=1
    )
    for i, name in enumerate(names):
        source = ColumnDataSource({"policy": [name] * per.shape[1], "rmse": per[i], "seed": seeds})
        fig.scatter(
            "policy", "rmse", source=source, size=6, color=COLOURS[i % len(COLOURS)], alpha=0.8
        )
    means = [results["policies"][n]["rmse_nt_mean"] for n in names]
    ci = [results["policies"][n].get("rmse_nt_ci95") or [None, None] for n in names]
    floor = float(np.nanmin(per)) / 2  # a log axis: an interval reaching 0 is cut here
    ok = [i for i, c in enumerate(ci) if c[0] is not None and c[1] is not None]
    fig.scatter(names, means, marker="diamond", size=13, color="black")
    if ok:
        band = ColumnDataSource(
            {
                "p": [names[i] for i in ok],
                "lo": [max(ci[i][0], floor) for i in ok],
                "hi": [ci[i][1] for i in ok],
            }
        )
        fig.add_layout(Whisker(base="p", lower="lo", upper="hi", source=band, line_width=2))
    fig.xaxis.major_label_orientation = 0.5 if len(names) > 5 else 0
    return fig


def _scores(results: dict[str, Any], names: list[str]) -> Any:
    """The normalized score per policy with its paired-bootstrap interval."""
    from bokeh.models import ColumnDataSource, Whisker

    rows = [
        (n, r["normalized_score"], *(r.get("normalized_score_ci95") or [None, None]))
        for n in names
        if (r := results["policies"][n]).get("normalized_score") is not None
    ]
    fig = new_figure(
        f"normalized score, {results['scenario']} (1 = the better anchor; 95 % interval)",
        "normalized score",
        "policy",
        height=max(160, 40 * len(rows) + 80),
        y_range=[r[0] for r in reversed(rows)],
        tools="save",
    )
    source = ColumnDataSource(
        {
            "p": [r[0] for r in rows],
            "s": [r[1] for r in rows],
            "lo": [r[2] if r[2] is not None else r[1] for r in rows],
            "hi": [r[3] if r[3] is not None else r[1] for r in rows],
        }
    )
    fig.add_layout(
        Whisker(base="p", lower="lo", upper="hi", source=source, dimension="width", line_width=2)
    )
    fig.scatter("s", "p", source=source, size=10, color="#0072B2")
    for x in (0.0, 1.0):
        from bokeh.models import Span

        fig.add_layout(
            Span(location=x, dimension="height", line_dash="dashed", line_color="#888888")
        )
    return fig


def _traces(traces: dict[str, dict[str, np.ndarray]]) -> list[Any]:
    """The Q scale and the R scale over the flight, a line per policy (log axis)."""
    figs = []
    first = None
    for key, label in (("q_scale", "Q scale"), ("r_scale", "R scale")):
        fig = new_figure(
            f"cumulative {label} (1 = the initial {label[0]})",
            "time [s]",
            f"{label} [-]",
            y_log=True,
            x_range=first.x_range if first is not None else None,
        )
        for i, (name, tr) in enumerate(traces.items()):
            lines(
                fig, tr["t"], [(name, tr[key])], colours=(COLOURS[i % len(COLOURS)],), positive=True
            )
        finish_legend(fig)
        first = first or fig
        figs.append(fig)
    return figs
