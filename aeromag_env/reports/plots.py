"""Bokeh building blocks shared by the pages: a styled figure, decimated lines, shaded windows.

Every function imports Bokeh when called, so importing this module costs nothing.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from aeromag_env.reports.decimate import COLUMNS, extreme_indices, time_gaps, with_breaks
from aeromag_env.reports.html import COLOURS, PLOT_HEIGHT, WINDOW_FILL

#: Tools of every plot: pan and zoom (box and wheel), reset, save as PNG, hover off.
TOOLS = "xpan,xwheel_zoom,box_zoom,reset,save"
#: Most time windows (gaps, manoeuvres) a plot shades; more are left out.
MAX_WINDOWS = 300


def new_figure(
    title: str,
    x_label: str,
    y_label: str,
    *,
    height: int = PLOT_HEIGHT,
    x_range: Any = None,
    y_log: bool = False,
    tools: str = TOOLS,
    **kwargs: Any,
) -> Any:
    """A Bokeh figure in the pages' style: full width, no logo, legend that hides a line on
    click."""
    from bokeh.plotting import figure

    args: dict[str, Any] = {"x_range": x_range} if x_range is not None else {}
    if y_log:  # else Bokeh's "auto": linear, or categorical for a list of factors
        args["y_axis_type"] = "log"
    fig = figure(
        title=title,
        height=height,
        sizing_mode="stretch_width",
        tools=tools,
        active_scroll=None,
        output_backend="canvas",
        **args,
        **kwargs,
    )
    fig.toolbar.logo = None
    fig.xaxis.axis_label, fig.yaxis.axis_label = x_label, y_label
    fig.title.text_font_size = "13px"
    fig.title.text_font_style = "bold"
    fig.axis.axis_label_text_font_style = "normal"
    fig.axis.axis_label_text_font_size = "12px"
    fig.grid.grid_line_alpha = 0.5
    fig.outline_line_color = None
    fig.min_border_left = 60
    return fig


def finish_legend(fig: Any, outside: bool = True) -> None:
    """The legend right of the plot (``outside``, so it hides no data) or in its top left
    corner; clicking an entry hides its line. Call after the glyphs."""
    if fig.legend:
        legend = fig.legend[0]
        if outside and legend not in fig.right:
            fig.add_layout(legend, "right")
        fig.legend.location = "top_left"
        fig.legend.click_policy = "hide"
        fig.legend.label_text_font_size = "11px"
        fig.legend.background_fill_alpha = 0.7
        fig.legend.spacing = 0
        fig.legend.padding = 4


def lines(
    fig: Any,
    tt: np.ndarray,
    series: Sequence[tuple[str, np.ndarray]],
    *,
    columns: int = COLUMNS,
    colours: Sequence[str] = COLOURS,
    width: float = 1.2,
    positive: bool = False,
) -> None:
    """Draw each named series against ``tt`` [s], decimated (min/max per column) and broken at
    NaN samples and time gaps; ``positive`` masks values ≤ 0 (for a log axis)."""
    from bokeh.models import ColumnDataSource

    gaps = time_gaps(tt)
    for (name, y), colour in zip(series, colours, strict=False):
        y = np.asarray(y, dtype=float)
        if positive:
            y = np.where(y > 0, y, np.nan)
        if not np.isfinite(y).any():
            continue
        x, (yd,) = with_breaks(tt, [y], extreme_indices(y, columns), gaps)
        source = ColumnDataSource({"t": x, "y": yd})
        fig.line("t", "y", source=source, legend_label=name, color=colour, line_width=width)
    finish_legend(fig)


def markers(
    fig: Any,
    tt: np.ndarray,
    y: np.ndarray,
    mask: np.ndarray,
    label: str,
    colour: str,
    marker: str = "x",
    limit: int = 2 * COLUMNS,
) -> int:
    """Mark the samples ``mask`` of the series ``y`` (non-finite values on the plot's floor);
    at most ``limit`` marks (the extremes of each column, as for a line). Returns the number
    of samples marked."""
    from bokeh.models import ColumnDataSource

    idx = np.flatnonzero(mask)
    if idx.size == 0:
        return 0
    values = np.asarray(y, dtype=float)[idx]
    floor = np.nanmin(y) if np.isfinite(y).any() else 0.0
    values = np.where(np.isfinite(values), values, floor)
    if idx.size > limit:
        keep = extreme_indices(values, limit // 2)
        idx, values = idx[keep], values[keep]
    source = ColumnDataSource({"t": np.asarray(tt, dtype=float)[idx], "y": values})
    fig.scatter(
        "t",
        "y",
        source=source,
        marker=marker,
        size=9,
        line_width=2,
        color=colour,
        legend_label=f"{label} ({int(mask.sum())})",
    )
    return int(mask.sum())


def shade(fig: Any, windows: Sequence[tuple[float, float]], colour: str = WINDOW_FILL) -> None:
    """Shade time windows ``[(t0, t1), …]`` [s] behind the lines (at most :data:`MAX_WINDOWS`):
    one strip glyph for all of them (a model per window would make a long flight's page slow
    to write)."""
    from bokeh.models import ColumnDataSource

    shown = list(windows)[:MAX_WINDOWS]
    if not shown:
        return
    t0, t1 = (np.array(v, dtype=float) for v in zip(*shown, strict=True))
    source = ColumnDataSource({"t0": t0, "t1": t1})
    renderer = fig.vstrip(
        x0="t0", x1="t1", source=source, fill_color=colour, fill_alpha=0.25, line_alpha=0
    )
    renderer.level = "underlay"


def gap_windows(tt: np.ndarray) -> list[tuple[float, float]]:
    """The time gaps of ``tt`` as windows ``(t_before, t_after)`` [s]."""
    tt = np.asarray(tt, dtype=float)
    return [(float(tt[k]), float(tt[k + 1])) for k in time_gaps(tt)]
