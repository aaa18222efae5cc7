"""The page of ``aeromag discover``: where simulation and measurement disagree, and what closes it.

Shown: the verdict and the held-out gap (headline figures); the caveats; the residual
(measured − simulated) per axis before and after the named effects, with the held-out part
shaded; the residual against each named effect's driving channel; the named effects' evidence
and every candidate's verdict.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from typing import Any

import numpy as np

from aeromag_env.reports import html as h
from aeromag_env.reports.decimate import extreme_indices_many, runs
from aeromag_env.reports.plots import finish_legend, lines, new_figure, shade

HEADLINES = (
    ("held-out gap, base model", "gap.rms_before_nt", "nT"),
    ("held-out gap, with named effects", "gap.rms_after_nt", "nT"),
    ("gap shrink", "gap.shrink", "×"),
    ("white-noise floor", "gap.white_noise_floor_nt", "nT"),
)
#: Points per driver scatter (the residual's extremes per column of the driver's order).
SCATTER_POINTS = 3000


@h.page_builder
def discover_page(
    report: dict[str, Any],
    series: dict[str, np.ndarray],
    drivers: Sequence[tuple[str, str, np.ndarray]] = (),
) -> str:
    """The HTML page of one discrepancy run.

    Parameters
    ----------
    report : dict
        What ``report.json`` holds (``verdict``, ``gap``, ``missing_effects``, ``candidates``,
        ``caveats``…).
    series : dict
        ``tt`` (n,) [s], ``residual_before`` and ``residual_after`` (n, 3) [nT], ``held_out``
        (n,) bool.
    drivers : sequence of (effect name, channel name, (n,) samples)
        What drives each named effect.

    Returns
    -------
    str
        A self-contained HTML document.
    """
    tt = np.asarray(series["tt"], dtype=float)
    verdict = json.dumps(report.get("verdict"))
    blocks: list[Any] = [
        f'<p class="verdict" data-key="verdict" data-value="{h.esc(verdict)}">'
        f"Verdict: <b>{h.esc(report.get('verdict'))}</b></p>",
        h.headline_block(report, HEADLINES),
        h.heading("Caveats"),
        h.card(h.notes(report.get("caveats") or [], "no caveats")),
    ]
    problems = report.get("input_problems") or []
    if problems:
        blocks += [h.heading("Input warnings"), h.card(h.notes([str(p) for p in problems]))]
    blocks += [h.heading("Measured − simulated, before and after the named effects")]
    held = runs(tt, np.asarray(series.get("held_out", np.zeros(tt.size)), dtype=bool))
    first = None
    for i, axis in enumerate("xyz"):
        fig = new_figure(
            f"residual {axis} (held-out part shaded)",
            "time [s]",
            "[nT]",
            x_range=first.x_range if first is not None else None,
        )
        before = series["residual_before"][:, i]
        after = series["residual_after"][:, i]
        lines(fig, tt, [("base model", before), ("with named effects", after)])
        shade(fig, held)
        first = first or fig
        blocks.append(fig)
    for name, channel, x in drivers:
        blocks.append(_against_driver(series, name, channel, np.asarray(x, dtype=float)))
    blocks += [h.heading("Named effects"), h.card(_effects(report.get("missing_effects") or []))]
    blocks += [h.heading("Candidates"), h.card(_candidates(report))]
    gap = report.get("gap") or {}
    blocks += [
        h.heading("Held-out scheme and data"),
        h.card(
            h.definitions(
                {
                    "held-out scheme": gap.get("held_out_scheme"),
                    "raw RMS before [nT]": gap.get("raw_rms_before_nt"),
                    "raw RMS after [nT]": gap.get("raw_rms_after_nt"),
                    **(report.get("data") or {}),
                }
            )
        ),
    ]
    return h.render_page(
        "Discrepancy report", f"{report.get('input', '')} · {tt.size} samples", blocks
    )


def _against_driver(series: dict[str, np.ndarray], name: str, channel: str, x: np.ndarray) -> Any:
    """The residual against an effect's driving channel, on the axis where it changed most."""
    from bokeh.models import ColumnDataSource

    before, after = series["residual_before"], series["residual_after"]
    change = np.nanstd(before - after, axis=0)
    i = int(np.nanargmax(change)) if np.isfinite(change).any() else 0
    order = np.argsort(x, kind="stable")
    idx = order[extreme_indices_many([before[order, i], after[order, i]], SCATTER_POINTS // 4)]
    fig = new_figure(
        f"{name}: residual {'xyz'[i]} against {channel}",
        channel,
        f"residual {'xyz'[i]} [nT]",
        height=300,
        tools="pan,wheel_zoom,box_zoom,reset,save",
    )
    for label, r, colour in (
        ("base model", before, "#0072B2"),
        ("with named effects", after, "#D55E00"),
    ):
        source = ColumnDataSource({"x": x[idx], "y": r[idx, i]})
        fig.scatter("x", "y", source=source, size=3, alpha=0.5, color=colour, legend_label=label)
    finish_legend(fig)
    return fig


def _effects(missing: list[dict[str, Any]]) -> str:
    """Each named effect's evidence and held-out gap."""
    if not missing:
        return '<p class="none">no missing effect named</p>'
    rows = []
    for e in missing:
        ev, g = e.get("evidence") or {}, e.get("held_out_gap") or {}
        rows.append(
            [
                e["name"],
                e.get("channel") or "–",
                ev.get("test", "F-test"),
                ev.get("f_statistic"),
                ev.get("log10_p_value"),
                ev.get("holm_threshold"),
                ev.get("delta_bic"),
                g.get("rms_without_nt"),
                g.get("rms_with_nt"),
            ]
        )
    header = [
        "effect",
        "channel",
        "test",
        "F",
        "log10 p",
        "Holm threshold",
        "ΔBIC",
        "held-out gap without [nT]",
        "with [nT]",
    ]
    return h.table(header, rows, text_columns=3)


def _candidates(report: dict[str, Any]) -> str:
    """Every candidate with its verdict and last test; the skipped ones with their reason."""
    rows = []
    for c in report.get("candidates") or []:
        test = c.get("last_test") or {}
        rows.append(
            [
                c["name"],
                c.get("channel") or "–",
                c["verdict"],
                c.get("regressors"),
                c.get("identifiable_fraction"),
                test.get("f_statistic") if isinstance(test, dict) else None,
                test.get("log10_p_value") if isinstance(test, dict) else None,
            ]
        )
    header = ["candidate", "channel", "verdict", "regressors", "identifiable", "F", "log10 p"]
    skipped = [f"{s['name']}: {s['reason']}" for s in report.get("skipped") or []]
    extra = f"<h3>Skipped</h3>{h.notes(skipped)}" if skipped else ""
    return h.table(header, rows, text_columns=3) + extra
