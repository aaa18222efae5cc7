"""Small helpers the page generators share: escaping, tables, writing only what changed."""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

_SPECIAL = re.compile(r"([\\*`|])")
_TRAILING_UNDERSCORE = re.compile(r"(\w)_(?=\W|$)")


def text(value: object, collapse: bool = True) -> str:
    """Plain text made safe for reStructuredText (no markup is read in it); whitespace runs
    become one space unless ``collapse`` is false."""
    shown = " ".join(str(value).split()) if collapse else str(value)
    escaped = _SPECIAL.sub(r"\\\1", shown)
    return _TRAILING_UNDERSCORE.sub(r"\1\\_", escaped)


def literal(value: object) -> str:
    """``value`` as an inline literal (empty text stays empty)."""
    shown = " ".join(str(value).split())
    return f"``{shown}``" if shown else ""


def heading(title: str, char: str, overline: bool = False) -> str:
    line = char * max(len(title), 3)
    return f"{line}\n{title}\n{line}\n" if overline else f"{title}\n{line}\n"


def list_table(
    header: Sequence[str] | None, rows: Sequence[Sequence[str]], widths: str = "auto"
) -> str:
    """A ``list-table`` directive (no header row when ``header`` is None); cells are
    reStructuredText already (use :func:`text`)."""
    out = [".. list-table::", f"   :header-rows: {0 if header is None else 1}"]
    out += [f"   :widths: {widths}", ""]
    for row in (*([] if header is None else [header]), *rows):
        for i, cell in enumerate(row):
            lines = str(cell).splitlines() or [""]
            out.append(f"   {'*' if i == 0 else ' '} - {lines[0]}".rstrip())
            out.extend(f"       {line}".rstrip() for line in lines[1:])
    return "\n".join(out) + "\n"


def indent(block: str, spaces: int = 3) -> str:
    pad = " " * spaces
    return "\n".join(pad + line if line.strip() else "" for line in block.splitlines())


def write_if_changed(path: Path, content: str) -> bool:
    """Write ``content`` to ``path`` unless it holds it already (so Sphinx rebuilds only what
    changed); returns whether it wrote."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.exists() and path.read_text(encoding="utf-8") == content:
        return False
    path.write_text(content, encoding="utf-8")
    return True


def remove_stale(folder: Path, keep: set[Path], pattern: str = "*.rst") -> None:
    """Delete generated files in ``folder`` that this build did not write (a removed id)."""
    for path in folder.glob(pattern):
        if path not in keep:
            path.unlink()
