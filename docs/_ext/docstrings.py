"""Docstrings written for people reading the code, made into valid reStructuredText.

The environment's docstring follows Gymnasium's: ``## Section`` headings and a Markdown table;
formulas write norms as ``|r|``. Sphinx reads docstrings as reStructuredText, where those are a
syntax error (a ``|...|`` is a substitution). Before numpydoc and autodoc read a docstring this
turns each heading into a rubric, each Markdown table into a ``list-table`` and escapes the
other ``|`` outside literals; and it puts back into its bullet item a line that a reflow of the
source pushed out of it (the docstring reads the same in the code either way).
"""

from __future__ import annotations

import re
from typing import Any

_LITERAL = re.compile(r"(``[^`]*``|`[^`]*`)")
_RULE = re.compile(r"^\|?\s*:?-{3,}")


def markdown_to_rst(lines: list[str]) -> list[str]:
    """``## Heading`` → rubric, Markdown tables → list-table, bare ``|`` escaped."""
    out: list[str] = []
    i = 0
    while i < len(lines):
        line = lines[i]
        stripped = line.strip()
        pad = line[: len(line) - len(line.lstrip())]
        if stripped.startswith("## "):
            out += [f"{pad}.. rubric:: {stripped[3:].strip()}", ""]
        elif stripped.startswith("|") and stripped.endswith("|") and stripped.count("|") > 2:
            table = []
            while i < len(lines) and lines[i].strip().startswith("|"):
                table.append(lines[i].strip())
                i += 1
            out += _table(table, pad)
            continue
        else:
            out.append(_escape_pipes(line))
        i += 1
    return out


def _escape_pipes(line: str) -> str:
    parts = _LITERAL.split(line)
    return "".join(p if _LITERAL.fullmatch(p) else re.sub(r"(?<!\\)\|", r"\\|", p) for p in parts)


def _table(rows: list[str], pad: str) -> list[str]:
    cells = [[c.strip() for c in r.strip("|").split("|")] for r in rows if not _RULE.match(r)]
    out = ["", f"{pad}.. list-table::", f"{pad}   :header-rows: 1", ""]
    for row in cells:
        for j, cell in enumerate(row):
            out.append(f"{pad}   {'*' if j == 0 else ' '} - {cell}".rstrip())
    return [*out, ""]


_BULLET = re.compile(r"^(\s*)([*-]) ")


def rejoin_bullets(lines: list[str]) -> list[str]:
    """Re-indent a line that a reflow pushed out of its bullet item: one indented less than
    the item's text, between the item's first line and a line indented as its text."""
    out = list(lines)
    content = None  # indentation of the current bullet item's text
    for i, line in enumerate(out):
        match = _BULLET.match(line)
        indent = len(line) - len(line.lstrip())
        if match:
            content = len(match.group(1)) + 2
        elif not line.strip():
            content = None
        elif content is not None and indent < content:
            following = out[i + 1] if i + 1 < len(out) else ""
            follow_indent = len(following) - len(following.lstrip())
            if following.strip() and follow_indent == content and not _BULLET.match(following):
                out[i] = " " * content + line.lstrip()
            else:
                content = None
    return out


def process(app: Any, what: str, name: str, obj: Any, options: Any, lines: list[str]) -> None:
    """``autodoc-process-docstring`` handler: rewrite ``lines`` in place."""
    lines[:] = markdown_to_rst(rejoin_bullets(lines))
