"""Geosoft XYZ: the ASCII format in which survey data (and SGL's flights) are delivered.

Layout::

    / any header or comment line starts with '/'
    / @ {"date": "2020-06-20"}            ← optional: the attributes as one JSON object
    /  TIME      LAT        LONG  UNCOMPMAG1 ...   ← the column names
    LINE 1002.01                          ← the line id of the rows that follow
      45100.0  45.3  -75.7  52314.6 ...
      45100.1  45.3  -75.7        * ...   ← '*' is the dummy: no value (NaN)
    TIE 5

Reading
    Values are separated by blanks or tabs. The column names are the last ``/`` line before the
    first data row that has one name per value and no number among them (so ``//Flight 1002``
    remarks in between are passed over); other ``/`` lines are comments and ignored. ``LINE n``
    and ``TIE n`` records (any case; ``L``/``T`` prefixes, ``:version`` suffixes and words after
    the id allowed; ``*`` for none) set the line id of the rows that follow: they become the
    field ``line`` (NaN before the first record), and the ids given by ``TIE`` records the
    attribute ``tie_lines``. When a column already holds the line (``LINE`` or ``line``) and
    agrees with the records, it is kept alone; when they disagree the records are kept as
    ``xyz_line_record`` and a warning says so. Columns that are not numbers are skipped and
    reported. The text is read as UTF-8, else as Latin-1.
Writing
    A ``/`` title line, the ``/ @`` attribute line, the ``/`` column names, and one row per sample
    of shortest round-trip ``repr`` values with ``*`` for NaN. When the flight has a ``line``
    field it stays a column, and a ``LINE`` record (``TIE`` for the ids in the ``tie_lines``
    attribute) starts each run of equal ids. Write → read gives bit-identical finite values, NaN
    where NaN was (not its payload bits) and equal attributes (JSON types: a tuple comes back as a
    list). Field names may not contain blanks.
"""

from __future__ import annotations

import io
import re
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from aeromag_env.flight.aliases import canonical_name
from aeromag_env.flight.data import Flight
from aeromag_env.flight.formats.common import RawFile, skipped_note, to_json
from aeromag_env.flight.formats.csvfile import parse_attr_line
from aeromag_env.flight.validation import file_error, truncated_list

RECORD_RE = re.compile(r"^(LINE|TIE)\s+(\S+)(\s.*)?$", re.IGNORECASE)
ATTR_MARK = "/ @"
DUMMY = "*"
RECORD_FIELD = "xyz_line_record"
TIE_ATTR = "tie_lines"
_DUMMY_RE = re.compile(r"(?<!\S)\*(?!\S)")


class _Scan(NamedTuple):
    """A file split into its parts (``ids``: the line id of each data row)."""

    headers: list[str]
    attrs: dict[str, Any]
    rows: list[str]
    row_numbers: list[int]
    ids: list[float]
    ties: list[float]
    has_records: bool


def read_xyz(path: Path) -> RawFile:
    """Fields, attributes and notes of a Geosoft XYZ file (see the module docstring)."""
    scan = _scan(path, _read_text(path))
    names = _column_names(path, scan)
    columns, skipped = _parse_rows(path, scan, names)
    fields = {nm: col for nm, col in zip(names, columns, strict=True) if col is not None}
    attrs, notes = dict(scan.attrs), skipped_note(skipped, "non-numeric column(s)")
    if scan.ties:
        attrs[TIE_ATTR] = sorted(set(scan.ties))
    if scan.has_records:
        notes += _add_record_lines(fields, np.array(scan.ids, dtype=np.float64))
    return fields, attrs, notes


def _read_text(path: Path) -> str:
    """The file as text: UTF-8 (with or without BOM), else Latin-1 (every byte is a character)."""
    data = path.read_bytes()
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError:
        return data.decode("latin-1")


def _scan(path: Path, text: str) -> _Scan:
    """Header lines (before the first row), attributes, data rows and their line ids."""
    scan = _Scan([], {}, [], [], [], [], False)
    current, has_records = float("nan"), False
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line:
            continue
        if line.startswith("/"):
            body = line.lstrip("/").strip()
            if body.startswith("@") and body[1:].lstrip().startswith(("{", "[")):
                scan.attrs.update(parse_attr_line(path, body[1:], ATTR_MARK))
            elif not scan.rows:
                scan.headers.append(body)
            continue
        record = RECORD_RE.match(line)
        if record:
            current, has_records = _line_id(path, record.group(2), number), True
            if record.group(1).upper() == "TIE" and not np.isnan(current):
                scan.ties.append(current)
            continue
        scan.rows.append(line)
        scan.row_numbers.append(number)
        scan.ids.append(current)
    return scan._replace(has_records=has_records)


def _line_id(path: Path, token: str, number: int) -> float:
    """``1002.01``, ``L100``, ``T5``, ``100:2`` (version dropped) → float; ``*`` → NaN."""
    if token == DUMMY:
        return float("nan")
    try:
        return float(token.lstrip("LTlt").split(":")[0])
    except ValueError:
        raise file_error(path, f"line {number}: cannot read the line id {token!r}") from None


def _is_number(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return token == DUMMY
    return True


def _column_names(path: Path, scan: _Scan) -> list[str]:
    """The header line naming one column per value of the first data row."""
    width = len(scan.rows[0].split()) if scan.rows else None
    candidates = [
        tokens
        for tokens in (h.split() for h in scan.headers)
        if tokens and not any(_is_number(t) for t in tokens)
    ]
    fitting = [t for t in candidates if width is None or len(t) == width]
    if not fitting:
        found = f"for the {width} values of the first data row" if width else ""
        raise file_error(path, f"no '/' header line naming the columns {found}".strip())
    names = fitting[-1]
    duplicated = sorted({nm for nm in names if names.count(nm) > 1})
    if duplicated:
        raise file_error(path, f"duplicate column name(s): {truncated_list(duplicated)}")
    return names


def _parse_rows(
    path: Path, scan: _Scan, names: list[str]
) -> tuple[list[np.ndarray | None], list[str]]:
    """Columns (None where non-numeric) and the names skipped; fast path for all-numeric rows."""
    if not scan.rows:
        return [np.empty(0) for _ in names], []
    body = _DUMMY_RE.sub("nan", "\n".join(scan.rows))
    try:
        table = np.loadtxt(io.StringIO(body), dtype=np.float64, ndmin=2, comments=None)
    except ValueError:
        table = None
    if table is not None and table.shape[1] == len(names):
        return [np.ascontiguousarray(table[:, j]) for j in range(len(names))], []
    cells = [row.split() for row in scan.rows]
    for number, row in zip(scan.row_numbers, cells, strict=True):
        if len(row) != len(names):
            raise file_error(
                path, f"line {number} has {len(row)} values but the header names {len(names)}"
            )
    columns: list[np.ndarray | None] = []
    skipped = []
    for j, name in enumerate(names):
        try:
            columns.append(np.array([_value(row[j]) for row in cells], dtype=np.float64))
        except ValueError:
            columns.append(None)
            skipped.append(name)
    return columns, skipped


def _value(token: str) -> float:
    return float("nan") if token == DUMMY else float(token)


def _add_record_lines(fields: dict[str, np.ndarray], ids: np.ndarray) -> list[str]:
    """Put the LINE/TIE ids in ``line``, unless a line column already says the same."""
    column = next((nm for nm in fields if canonical_name(nm) == "line"), None)
    if column is None:
        fields["line"] = ids
        return []
    if np.array_equal(fields[column], ids, equal_nan=True):
        return []
    fields[RECORD_FIELD] = ids
    differ = int(np.sum(~((fields[column] == ids) | (np.isnan(fields[column]) & np.isnan(ids)))))
    return [
        f"LINE/TIE records disagree with the {column} column at {differ} of {ids.size} rows: "
        f"the records are kept as {RECORD_FIELD}"
    ]


def invalid_names(names: list[str]) -> list[str]:
    """Field names an XYZ file cannot hold (empty, with blanks, or starting with '/')."""
    return [nm for nm in names if not nm or nm.startswith("/") or any(c.isspace() for c in nm)]


def write_xyz(flight: Flight, tmp: Path) -> None:
    """Title, attribute and column lines, then rows with LINE/TIE records (module docstring)."""
    table = np.column_stack([np.asarray(v, dtype=np.float64) for v in flight.fields.values()])
    line = table[:, flight.names.index("line")] if "line" in flight.fields else None
    ties = set(flight.attrs.get(TIE_ATTR) or ())
    previous: float | None = None
    with open(tmp, "w", encoding="utf-8", newline="\n") as fh:
        fh.write(f"/ aeromag_env flight file, Geosoft XYZ ({DUMMY} = no value)\n")
        if flight.attrs:
            fh.write(f"{ATTR_MARK} {to_json(flight.attrs)}\n")
        fh.write("/ " + " ".join(flight.names) + "\n")
        for i, row in enumerate(table.tolist()):
            if line is not None and not _same(line[i], previous):
                previous = float(line[i])
                keyword = "TIE" if previous in ties else "LINE"
                fh.write(f"{keyword} {_format_id(previous)}\n")
            fh.write(" ".join(DUMMY if v != v else repr(v) for v in row) + "\n")


def _same(value: float, previous: float | None) -> bool:
    """Whether a line id continues the run (NaN continues NaN; nothing precedes the first)."""
    if previous is None:
        return bool(np.isnan(value))
    return bool(value == previous or (np.isnan(value) and np.isnan(previous)))


def _format_id(value: float) -> str:
    """``5`` for 5.0, ``1002.01``, ``*`` for NaN."""
    if np.isnan(value):
        return DUMMY
    return str(int(value)) if value.is_integer() and abs(value) < 2**53 else repr(value)
