"""The page around the plots: one self-contained HTML file (Bokeh, imported lazily).

A page is a list of blocks, each either HTML text (headings, the headline figures, tables,
warnings) or a Bokeh layout. :func:`render_page` inlines BokehJS (only the bundles the page's
models need) and the style sheet, so the file opens from disk with no network: no CDN, no
remote font, no request.

The same data give the same bytes (:func:`page_builder`), so that a rerun's output set is
comparable with the last one's.

The headline figures carry their value and where it comes from in the report
(``data-key="metrics.fom_nt" data-value="85.60879053239755"``), so a test can check that the
page shows what ``report.json`` says.
"""

from __future__ import annotations

import functools
import html
import json
import math
import re
import uuid
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any, TypeVar

#: Line colours, in order (colour-blind safe: Okabe–Ito).
COLOURS = ("#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#000000", "#999999")
#: Fill of the shaded time windows (FOM manoeuvres, held-out part).
WINDOW_FILL = "#F0E442"
#: Height of a time-series plot [CSS px]: four fit a laptop screen with the page's header.
PLOT_HEIGHT = 250

STYLE = """
:root { --fg: #1d2330; --muted: #5b6475; --line: #d9dee7; --bg: #f6f7f9; --card: #fff;
        --warn: #8a5a00; --warnbg: #fff6e0; --bad: #a11d1d; --badbg: #fdecec; --ok: #17692f; }
* { box-sizing: border-box; }
body { margin: 0; background: var(--bg); color: var(--fg);
       font: 14px/1.45 system-ui, -apple-system, "Segoe UI", Roboto, "Helvetica Neue", Arial,
       sans-serif; }
main { max-width: 1240px; margin: 0 auto; padding: 18px 24px 40px; }
header h1 { font-size: 21px; margin: 0 0 2px; font-weight: 650; }
header p { margin: 0; color: var(--muted); overflow-wrap: anywhere; }
h2 { font-size: 16px; margin: 26px 0 8px; font-weight: 650; }
section.card { background: var(--card); border: 1px solid var(--line); border-radius: 8px;
               padding: 12px 14px; margin: 10px 0; }
.stats { display: flex; flex-wrap: wrap; gap: 10px; margin: 14px 0 4px; }
.stat { background: var(--card); border: 1px solid var(--line); border-radius: 8px;
        padding: 8px 14px; min-width: 150px; }
.stat .v { font-size: 22px; font-weight: 650; font-variant-numeric: tabular-nums; }
.stat .u { font-size: 13px; color: var(--muted); font-weight: 400; }
.stat .l { font-size: 12px; color: var(--muted); }
table { border-collapse: collapse; font-variant-numeric: tabular-nums; }
th, td { padding: 3px 10px; border-bottom: 1px solid var(--line); text-align: right; }
th { font-weight: 600; color: var(--muted); }
td.t, th.t { text-align: left; }
.notes { list-style: none; padding: 0; margin: 0; }
.notes li { padding: 6px 10px; margin: 4px 0; border-radius: 6px; background: var(--warnbg);
            color: var(--warn); }
.notes.bad li { background: var(--badbg); color: var(--bad); }
.none { color: var(--ok); }
dl.prov { display: grid; grid-template-columns: max-content 1fr; gap: 2px 14px; margin: 0; }
dl.prov dt { color: var(--muted); }
dl.prov dd { margin: 0; overflow-wrap: anywhere; }
code, pre { font: 12px/1.4 ui-monospace, SFMono-Regular, Menlo, Consolas, monospace; }
pre { white-space: pre-wrap; margin: 0; }
.plot { margin: 6px 0; }
footer { color: var(--muted); font-size: 12px; margin-top: 30px; }
"""


@dataclass(frozen=True)
class Headline:
    """A figure shown large at the top of a page.

    Attributes
    ----------
    label : str, what it is
    key : str, where it is in the report (dotted path, e.g. ``metrics.fom_nt``)
    value : the value (None shows a dash)
    unit : str, shown after the value
    """

    label: str
    key: str
    value: Any
    unit: str = ""


F = TypeVar("F", bound=Callable[..., str])
#: A UUID as Bokeh writes it (document and element ids).
_UUID = re.compile(r"[0-9a-f]{8}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{12}")


def page_builder(build: F) -> F:
    """Make a page function deterministic: Bokeh's model ids restart from the same number for
    each page (they count up per process otherwise), and :func:`render_page` numbers the
    random document ids in order."""

    @functools.wraps(build)
    def wrapper(*args: Any, **kwargs: Any) -> str:
        import bokeh.embed
        import bokeh.models
        import bokeh.plotting  # noqa: F401  (their imports create models: before the reset)
        from bokeh.util import serialization

        with serialization._simple_id_lock:
            serialization._simple_id = 1000
        return build(*args, **kwargs)

    return wrapper  # type: ignore[return-value]


def _number_uuids(text: str) -> str:
    """Every distinct UUID of ``text`` replaced by one counted in order of appearance."""
    seen: dict[str, str] = {}

    def stable(match: re.Match[str]) -> str:
        return seen.setdefault(match.group(0), str(uuid.UUID(int=len(seen) + 1)))

    return _UUID.sub(stable, text)


def esc(text: Any) -> str:
    """``text`` as HTML text (quotes escaped too)."""
    return html.escape(str(text), quote=True)


def number(value: Any, digits: int = 4) -> str:
    """A figure for people: ``digits`` significant digits, ``–`` for None or NaN."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "–"
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return str(value)
    if isinstance(value, int):
        return f"{value:d}"
    return f"{value:.{digits}g}"


def lookup(report: dict[str, Any], key: str) -> Any:
    """The value at the dotted path ``key`` of ``report`` (None when a part is missing)."""
    value: Any = report
    for part in key.split("."):
        if not isinstance(value, dict) or part not in value:
            return None
        value = value[part]
    return value


def headline_block(report: dict[str, Any], items: Iterable[tuple[str, str, str]]) -> str:
    """The headline figures ``(label, key, unit)`` found in ``report`` (missing ones left out)."""
    shown = [
        Headline(label, key, lookup(report, key), unit)
        for label, key, unit in items
        if lookup(report, key) is not None
    ]
    return headlines(shown)


def headlines(items: Sequence[Headline]) -> str:
    """The headline figures as cards, each with ``data-key`` and ``data-value``."""
    cards = []
    for h in items:
        raw = json.dumps(h.value) if h.value is not None else "null"
        unit = f' <span class="u">{esc(h.unit)}</span>' if h.unit else ""
        cards.append(
            f'<div class="stat" data-key="{esc(h.key)}" data-value="{esc(raw)}">'
            f'<div class="v">{esc(number(h.value))}{unit}</div>'
            f'<div class="l">{esc(h.label)}</div></div>'
        )
    return f'<div class="stats">{"".join(cards)}</div>'


def heading(text: str) -> str:
    """A section heading."""
    return f"<h2>{esc(text)}</h2>"


def card(inner_html: str) -> str:
    """A white box around ``inner_html``."""
    return f'<section class="card">{inner_html}</section>'


def notes(items: Sequence[str], empty: str = "none", bad: bool = False) -> str:
    """A list of warnings (or caveats); ``empty`` when there are none."""
    if not items:
        return f'<p class="none">{esc(empty)}</p>'
    cls = "notes bad" if bad else "notes"
    return f'<ul class="{cls}">' + "".join(f"<li>{esc(i)}</li>" for i in items) + "</ul>"


def table(header: Sequence[str], rows: Iterable[Sequence[Any]], text_columns: int = 1) -> str:
    """A table; the first ``text_columns`` columns left-aligned, numbers by :func:`number`; a
    :class:`Headline` cell shows its value and carries its ``data-key``/``data-value``."""
    cls = [' class="t"' if i < text_columns else "" for i in range(len(header))]
    head = "".join(f"<th{c}>{esc(h)}</th>" for c, h in zip(cls, header, strict=True))
    body = "".join(
        "<tr>" + "".join(_cell(c, v) for c, v in zip(cls, row, strict=True)) + "</tr>"
        for row in rows
    )
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _cell(cls: str, value: Any) -> str:
    if isinstance(value, Headline):
        raw = json.dumps(value.value) if value.value is not None else "null"
        return (
            f'<td{cls} data-key="{esc(value.key)}" data-value="{esc(raw)}">'
            f"{esc(number(value.value))}</td>"
        )
    return f"<td{cls}>{esc(number(value))}</td>"


def definitions(items: dict[str, Any]) -> str:
    """A definition list: plain values as text, nested ones as one-line JSON."""
    parts = []
    for key, value in items.items():
        if isinstance(value, (dict, list)):
            shown = f"<code>{esc(json.dumps(value, default=str, ensure_ascii=False))}</code>"
        else:
            shown = esc(number(value))
        parts.append(f"<dt>{esc(key)}</dt><dd>{shown}</dd>")
    return f'<dl class="prov">{"".join(parts)}</dl>'


def render_page(title: str, subtitle: str, blocks: Sequence[Any]) -> str:
    """The whole page: ``blocks`` are HTML strings or Bokeh layouts, in order.

    Returns
    -------
    str
        A self-contained HTML document (BokehJS and the style inlined).
    """
    from bokeh.embed import components
    from bokeh.embed.bundle import bundle_for_objs_and_resources
    from bokeh.resources import INLINE

    models = [b for b in blocks if not isinstance(b, str)]
    script, divs = components(models) if models else ("", ())
    script, *divs = _number_uuids("\0".join([script, *divs])).split("\0")  # one numbering
    placed = iter(divs)
    body = "\n".join(
        b if isinstance(b, str) else f'<div class="plot">{next(placed)}</div>' for b in blocks
    )
    js = ""
    if models:
        bundle = bundle_for_objs_and_resources(models, INLINE)
        js = "\n".join(f"<script>\n{_safe_script(code)}\n</script>" for code in bundle.js_raw)
    return (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
        f"<title>{esc(title)}</title>\n<style>{STYLE}</style>\n{js}\n</head>\n<body>\n<main>\n"
        f"<header><h1>{esc(title)}</h1><p>{esc(subtitle)}</p></header>\n{body}\n"
        "<footer>Written by aeromag_env. Plots: drag to pan, wheel to zoom, double-click "
        "the reset tool to go back; long series are drawn from the minimum and maximum of "
        "each of 2000 columns, so no spike is lost.</footer>\n"
        f"</main>\n{script}\n</body>\n</html>\n"
    )


def _safe_script(code: str) -> str:
    """``code`` with any ``</script`` broken up so that it cannot end the element early."""
    return code.replace("</script", "<\\/script")
