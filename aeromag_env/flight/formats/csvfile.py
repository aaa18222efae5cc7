"""CSV: a header row of column names, then one row per sample.

Reading
    ``#`` lines before the header are comments, except an optional ``#@ {json}`` line that
    carries the attributes as one JSON object. Empty cells are NaN; columns that are not numbers
    (labels, dates as text) are skipped and reported.
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
from aeromag_env.flight.formats.common import RawFile, skipped_note, to_json
from aeromag_env.flight.validation import file_error, truncated_list

ATTR_LINE = "#@"


def read_csv(path: Path) -> RawFile:
    """Header row, optional ``#@ {json}`` attribute line, numeric columns."""
    attrs: dict[str, Any] = {}
    with open(path, encoding="utf-8-sig") as fh:
        line = fh.readline()
        while line.startswith("#"):
            if line.startswith(ATTR_LINE):
                attrs = parse_attr_line(path, line[len(ATTR_LINE) :], ATTR_LINE)
            line = fh.readline()
        body = fh.read()
    names = [nm.strip() for nm in next(csv.reader([line]))] if line.strip() else []
    if not names:
        raise file_error(path, "no header row of column names")
    if len(names) == 1 and ";" in names[0]:
        raise file_error(path, "columns must be separated by commas, found ';'")
    duplicated = [nm for nm, count in Counter(names).items() if count > 1 and nm]
    if duplicated:
        raise file_error(path, f"duplicate column name(s): {truncated_list(duplicated)}")
    columns, skipped = _parse_body(path, body, names)
    skipped += [f"column {j + 1}" for j, nm in enumerate(names) if not nm]
    fields = {nm: col for nm, col in zip(names, columns, strict=True) if nm and col is not None}
    return fields, attrs, skipped_note(skipped, "column(s)")


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
    path: Path, body: str, names: list[str]
) -> tuple[list[np.ndarray | None], list[str]]:
    """Columns (None where non-numeric) and the names skipped; fast path for all-numeric data."""
    if not body.strip():
        return [np.empty(0) for _ in names], []
    try:
        table = np.loadtxt(io.StringIO(body), delimiter=",", dtype=np.float64, ndmin=2)
    except ValueError:
        return _parse_slow(path, body, names)
    if table.shape[1] != len(names):
        raise file_error(
            path, f"rows have {table.shape[1]} values but the header names {len(names)} columns"
        )
    return [np.ascontiguousarray(table[:, j]) for j in range(len(names))], []


def _parse_slow(
    path: Path, body: str, names: list[str]
) -> tuple[list[np.ndarray | None], list[str]]:
    """Cell by cell: empty cells are NaN, non-numeric columns are skipped."""
    rows = [row for row in csv.reader(io.StringIO(body)) if row and not row[0].startswith("#")]
    for i, row in enumerate(rows):
        if len(row) != len(names):
            raise file_error(
                path, f"data row {i + 1} has {len(row)} values but the header has {len(names)}"
            )
    columns: list[np.ndarray | None] = []
    skipped = []
    for j, name in enumerate(names):
        cells = [row[j].strip() or "nan" for row in rows]
        try:
            columns.append(np.array(cells, dtype=np.float64))
        except ValueError:
            columns.append(None)
            skipped.append(name)
    return columns, skipped


def write_csv(flight: Flight, tmp: Path) -> None:
    """Attribute line, header, then rows of shortest round-trip floats."""
    table = np.column_stack([np.asarray(v, dtype=np.float64) for v in flight.fields.values()])
    with open(tmp, "w", encoding="utf-8", newline="") as fh:
        if flight.attrs:
            fh.write(f"{ATTR_LINE} {to_json(flight.attrs)}\n")
        csv.writer(fh, lineterminator="\n").writerow(flight.names)
        fh.writelines(",".join(map(repr, row)) + "\n" for row in table.tolist())
