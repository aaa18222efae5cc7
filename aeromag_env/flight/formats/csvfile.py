"""CSV: a header row of column names, then one row per sample.

Reading
    ``#`` lines before the header are comments, except an optional ``#@ {json}`` line that
    carries the attributes as one JSON object. Empty cells are NaN; columns of text only (labels,
    dates as text) are skipped and reported. In a column of numbers, a cell that is not a number
    is read as missing (NaN) and reported once per column with its line, up to
    :data:`MAX_CELLS_LISTED` of them and the count; a column where most cells are text but some
    are numbers is refused, naming it (its numbers cannot be trusted).
Writing
    The ``#@`` attribute line (when there are attributes), the header, then rows of Python's
    shortest round-trip ``repr`` (``nan``, ``inf`` for non-finite samples). Write → read gives
    bit-identical finite values and NaN where NaN was (not its payload bits) and equal
    attributes (JSON types: a tuple comes back as a list).
"""

from __future__ import annotations

import csv
import io
import json
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from aeromag_env.flight.data import Flight
from aeromag_env.flight.formats.common import RawFile, reading, reason, skipped_note, to_json
from aeromag_env.flight.validation import file_error, truncated_list

ATTR_LINE = "#@"
#: What Python's CSV parser raises on a damaged file: a quote left open swallows the rest of
#: the file into one cell, longer than the parser's field limit.
CSV_ERRORS: tuple[type[Exception], ...] = (csv.Error,)
#: Unreadable cells quoted (line and text) in a column's warning; the rest are counted.
MAX_CELLS_LISTED = 3


def read_csv(path: Path) -> RawFile:
    """Header row, optional ``#@ {json}`` attribute line, numeric columns."""
    attrs: dict[str, Any] = {}
    try:
        with open(path, encoding="utf-8-sig") as fh:
            line, header_line = fh.readline(), 1
            while line.startswith("#"):
                if line.startswith(ATTR_LINE):
                    attrs = parse_attr_line(path, line[len(ATTR_LINE) :], ATTR_LINE)
                line, header_line = fh.readline(), header_line + 1
            body = fh.read()
    except UnicodeDecodeError as exc:
        raise file_error(path, f"cannot read as CSV: not UTF-8 text ({reason(exc)})") from None
    with reading(path, "csv", CSV_ERRORS):
        names = [nm.strip() for nm in next(csv.reader([line]))] if line.strip() else []
    if not names:
        raise file_error(path, "no header row of column names")
    if len(names) == 1 and ";" in names[0]:
        raise file_error(path, "columns must be separated by commas, found ';'")
    duplicated = [nm for nm, count in Counter(names).items() if count > 1 and nm]
    if duplicated:
        raise file_error(path, f"duplicate column name(s): {truncated_list(duplicated)}")
    columns, skipped, notes = _parse_body(path, body, names, header_line)
    skipped += [f"column {j + 1}" for j, nm in enumerate(names) if not nm]
    fields = {nm: col for nm, col in zip(names, columns, strict=True) if nm and col is not None}
    return fields, attrs, skipped_note(skipped, "column(s)") + notes


def parse_attr_line(path: Path, text: str, marker: str) -> dict[str, Any]:
    """The JSON object after an attribute marker (``#@`` in CSV, ``/ @`` in XYZ)."""
    try:
        attrs = json.loads(text)
    except ValueError as exc:
        raise file_error(path, f"attribute line {marker} is not valid JSON ({exc})") from None
    if not isinstance(attrs, dict):
        raise file_error(path, f"attribute line {marker} must hold a JSON object")
    return attrs


def _parse_body(
    path: Path, body: str, names: list[str], header_line: int
) -> tuple[list[np.ndarray | None], list[str], list[str]]:
    """Columns (None where skipped), the names skipped and the warnings about unreadable cells;
    a fast path for all-numeric data. ``header_line`` is the header's line number (from 1)."""
    if not body.strip():
        return [np.empty(0) for _ in names], [], []
    try:
        table = np.loadtxt(io.StringIO(body), delimiter=",", dtype=np.float64, ndmin=2)
    except ValueError:
        return _parse_slow(path, body, names, header_line)
    if table.shape[1] != len(names):
        raise file_error(
            path, f"rows have {table.shape[1]} values but the header names {len(names)} columns"
        )
    return [np.ascontiguousarray(table[:, j]) for j in range(len(names))], [], []


def _parse_slow(
    path: Path, body: str, names: list[str], header_line: int
) -> tuple[list[np.ndarray | None], list[str], list[str]]:
    """Cell by cell: empty cells are NaN, text-only columns are skipped, unreadable cells of a
    numeric column are NaN and reported (:func:`_parse_column`)."""
    reader = csv.reader(io.StringIO(body))
    rows, lines = [], []
    with reading(path, "csv", CSV_ERRORS):
        for row in reader:
            if row and not row[0].startswith("#"):
                rows.append(row)
                lines.append(header_line + reader.line_num)
    for i, row in enumerate(rows):
        if len(row) != len(names):
            raise file_error(
                path, f"data row {i + 1} has {len(row)} values but the header has {len(names)}"
            )
    columns: list[np.ndarray | None] = []
    skipped, notes = [], []
    for j, name in enumerate(names):
        column, note = _parse_column(path, name, [row[j].strip() for row in rows], lines)
        columns.append(column)
        if column is None:
            skipped.append(name)
        elif note:
            notes.append(note)
    return columns, skipped, notes


def _parse_column(
    path: Path, name: str, cells: list[str], lines: list[int]
) -> tuple[np.ndarray | None, str | None]:
    """One column's values (None: text only, skipped) and the warning about its unreadable
    cells (NaN); raise when most of its cells are text but some are numbers."""
    try:
        return np.array([cell or "nan" for cell in cells], dtype=np.float64), None
    except ValueError:
        pass
    values = np.full(len(cells), np.nan)
    bad = []
    for i, cell in enumerate(cells):
        try:
            values[i] = float(cell) if cell else np.nan
        except ValueError:
            bad.append(i)
    filled = sum(1 for cell in cells if cell)
    if len(bad) == filled:
        return None, None  # labels, dates as text: not a channel
    quoted = ", ".join(f"line {lines[i]} {_shown(cells[i])}" for i in bad[:MAX_CELLS_LISTED])
    if 2 * len(bad) > filled:
        raise file_error(
            path,
            f"column {name} is not numeric: {len(bad)} of its {filled} cells are not "
            f"numbers ({quoted}); fix or remove the column",
        )
    more = f" (first {MAX_CELLS_LISTED} shown)" if len(bad) > MAX_CELLS_LISTED else ""
    cells_are = "cell is not a number" if len(bad) == 1 else "cells are not numbers"
    return values, f"column {name}: {len(bad)} {cells_are}, read as missing (NaN): {quoted}{more}"


def _shown(text: str) -> str:
    """A cell's text quoted, cut to 20 characters."""
    return repr(text if len(text) <= 20 else text[:17] + "...")


def write_csv(flight: Flight, tmp: Path) -> None:
    """Attribute line, header, then rows of shortest round-trip floats."""
    table = np.column_stack([np.asarray(v, dtype=np.float64) for v in flight.fields.values()])
    with open(tmp, "w", encoding="utf-8", newline="") as fh:
        if flight.attrs:
            fh.write(f"{ATTR_LINE} {to_json(flight.attrs)}\n")
        csv.writer(fh, lineterminator="\n").writerow(flight.names)
        fh.writelines(",".join(map(repr, row)) + "\n" for row in table.tolist())
