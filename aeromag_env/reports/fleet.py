"""The index page of a fleet run: one sortable row per flight, linking to the flight's page.

Shown: how many flights ran and failed (headline figures), the headline figure of each flight
against the flight (improvement ratio for ``compensate``, gap shrink for ``discover``), and
the table of ``fleet.csv`` (click a column header to sort) with a link to each flight's
``report.html``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from aeromag_env.reports import html as h
from aeromag_env.reports.plots import new_figure

#: The figure plotted per flight, by command: key, label.
PLOTTED = {
    "compensate": ("improvement_ratio", "improvement ratio (band-passed std before / after)"),
    "discover": ("gap_shrink", "held-out gap shrink"),
}
#: Table row height [px] and most rows shown without scrolling the table.
ROW_PX, MAX_ROWS = 26, 24
#: The ``file`` cell: the file's name, its whole path on hover.
FILE_TEMPLATE = '<span title="<%- value %>"><%- value.split("/").pop() %></span>'
#: The ``output`` cell: a link to the flight's page when it has one (underscore template).
LINK_TEMPLATE = (
    '<% if (link) { %><a href="<%- link %>"><%- value %></a><% } else { %><%- value %><% } %>'
)


@h.page_builder
def fleet_page(
    rows: Sequence[dict[str, Any]], columns: Sequence[str], command: str, page: str | None
) -> str:
    """The HTML index of a fleet run.

    Parameters
    ----------
    rows : sequence of dict
        One per flight, the values of ``fleet.csv`` (``output`` names the flight's folder).
    columns : sequence of str
        The columns to show, in order (those of ``fleet.csv``).
    command : str
        ``compensate`` or ``discover``.
    page : str or None
        The file name of each flight's page in its folder (None: no links).

    Returns
    -------
    str
        A self-contained HTML document.
    """
    failed = sum(r.get("status") != "ok" for r in rows)
    warned = sum(1 for r in rows if r.get("warnings"))
    cards = h.headlines(
        [
            h.Headline("flights", "flights", len(rows)),
            h.Headline("failed", "failed", failed),
            h.Headline("with warnings", "with_warnings", warned),
        ]
    )
    blocks: list[Any] = [
        cards,
        h.heading("Flights (click a column header to sort)"),
        _table(rows, columns, page),
    ]
    key, label = PLOTTED.get(command, (None, ""))
    if key and any(_number(r.get(key)) is not None for r in rows):
        blocks += [h.heading(f"{label} per flight"), _per_flight(rows, key, label)]
    errors = [f"{r.get('file')}: {r.get('error')}" for r in rows if r.get("status") != "ok"]
    if errors:
        blocks += [h.heading("Errors"), h.card(h.notes(errors, bad=True))]
    return h.render_page(f"Fleet: aeromag {command}", f"{len(rows)} flights", blocks)


def _number(value: Any) -> float | None:
    try:
        out = float(value)
    except (TypeError, ValueError):
        return None
    return out if np.isfinite(out) else None


def _table(rows: Sequence[dict[str, Any]], columns: Sequence[str], page: str | None) -> Any:
    """A Bokeh DataTable (sortable); the ``output`` column links to the flight's page."""
    from bokeh.models import (
        ColumnDataSource,
        DataTable,
        HTMLTemplateFormatter,
        NumberFormatter,
        StringFormatter,
        TableColumn,
    )

    shown = [c for c in columns if c != "warning_text"]
    data: dict[str, list[Any]] = {}
    for c in shown:
        values = [r.get(c) for r in rows]
        numeric = [v for v in values if v is not None and not isinstance(v, str)]
        if numeric and all(isinstance(v, (int, float)) for v in numeric):
            data[c] = [float("nan") if v is None else float(v) for v in values]
        else:
            data[c] = ["" if v is None else str(v) for v in values]
    data["link"] = [
        f"{r.get('output')}/{page}" if page and r.get("status") == "ok" else "" for r in rows
    ]
    data["tip"] = [str(r.get("warning_text") or r.get("error") or "") for r in rows]
    table_columns = []
    for c in shown:
        if c == "file":
            fmt: Any = HTMLTemplateFormatter(template=FILE_TEMPLATE)
        elif c == "output":
            fmt = HTMLTemplateFormatter(template=LINK_TEMPLATE)
        elif isinstance(data[c][0] if data[c] else "", float):
            whole = all(v != v or float(v).is_integer() for v in data[c])  # NaN or whole
            fmt = NumberFormatter(
                format="0" if whole else "0.000", nan_format="–", text_align="right"
            )
        else:
            fmt = StringFormatter()
        table_columns.append(TableColumn(field=c, title=c, formatter=fmt, width=_width(c)))
    height = ROW_PX * (min(len(rows), MAX_ROWS) + 1) + 4
    return DataTable(
        source=ColumnDataSource(data),
        columns=table_columns,
        sortable=True,
        index_position=None,
        sizing_mode="stretch_width",
        height=height,
        row_height=ROW_PX,
        name="fleet_table",
    )


def _width(column: str) -> int:
    """A column's width [px]: room for its title, more for file names and messages."""
    return {"file": 160, "error": 300, "named_effects": 200}.get(column, max(70, 8 * len(column)))


def _per_flight(rows: Sequence[dict[str, Any]], key: str, label: str) -> Any:
    """The headline figure of each flight (failed flights left out)."""
    from bokeh.models import ColumnDataSource

    ok = [(str(r.get("output")), _number(r.get(key))) for r in rows]
    ok = [(name, v) for name, v in ok if v is not None]
    fig = new_figure(
        label,
        "flight",
        label,
        height=300,
        x_range=[n for n, _ in ok],
        tools="save,hover",
        tooltips=[("flight", "@f"), ("value", "@v{0.000}")],
    )
    source = ColumnDataSource({"f": [n for n, _ in ok], "v": [v for _, v in ok]})
    fig.vbar(x="f", top="v", source=source, width=0.7, color="#0072B2", alpha=0.8)
    fig.xaxis.major_label_orientation = 0.8 if len(ok) > 8 else 0
    fig.y_range.start = 0
    return fig
