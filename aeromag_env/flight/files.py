"""Flight files: read and write the flat MagNav/SGL layout as HDF5 or CSV.

HDF5 (``.h5``, ``.hdf5``)
    One 1-D numeric dataset per field at the root (other datasets are skipped and reported;
    0-D datasets become attributes). File attributes become :attr:`Flight.attrs`, bytes decoded
    to ``str``. The writer stores attributes as strings: non-string values JSON-encoded, their
    names listed in the attribute ``_json_attrs`` so that the reader decodes them back.
CSV (``.csv``)
    A header row of column names, then one row per sample. An optional first line
    ``#@ {json}`` carries the attributes as one JSON object. Numbers are written with Python's
    shortest round-trip ``repr`` (``nan``, ``inf`` for non-finite samples).

All arrays are float64, and write → read returns bit-identical arrays and equal attributes
(CSV keeps NaN as NaN, not its payload bits). Writers refuse to overwrite an input file and write
atomically: a temporary file in the target folder, then ``os.replace``.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import os
import warnings
from collections import Counter
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from aeromag_env.atomic import atomic_path, check_not_input
from aeromag_env.errors import FlightFileError
from aeromag_env.flight.data import Flight
from aeromag_env.flight.validation import (
    FlightFileWarning,
    PathLike,
    check_structure,
    file_error,
    truncated_list,
    validate,
)

H5_SUFFIXES = (".h5", ".hdf5")
CSV_SUFFIXES = (".csv",)
ATTR_LINE = "#@"
_JSON_ATTRS = "_json_attrs"
_GZIP: dict[str, Any] = {"compression": "gzip", "compression_opts": 1, "shuffle": True}
_GZIP_MIN_SAMPLES = 4096  # smaller datasets are stored plain (chunking overhead)

RawFile = tuple[dict[str, np.ndarray], dict[str, Any], list[str]]


def read_flight(path: PathLike, needs: Iterable[str] = ("tt",)) -> Flight:
    """Read and validate a flight file (HDF5 or CSV).

    Parameters
    ----------
    path : str or PathLike
        ``.h5``/``.hdf5`` or ``.csv`` (another suffix is read as HDF5 if the file is one).
    needs : iterable of str
        What the caller will use (see :func:`aeromag_env.flight.validation.validate`): field names,
        vector prefixes such as ``"flux_a"``, and the groups ``"position"``, ``"attitude"``,
        ``"date"``. Only these must be present; ``tt`` always is.

    Returns
    -------
    Flight
        Float64 fields in file order and the file attributes. Warnings (non-finite samples,
        implausible channels not in ``needs``, skipped datasets) are issued as
        :class:`~aeromag_env.flight.validation.FlightFileWarning`; :func:`load_flight` returns them.

    Raises
    ------
    FlightFileError
        One-line message naming the file and the problem.
    """
    flight, problems = load_flight(path, needs)
    for problem in problems:
        warnings.warn(f"{os.fspath(path)}: {problem}", FlightFileWarning, stacklevel=2)
    return flight


def load_flight(path: PathLike, needs: Iterable[str] = ("tt",)) -> tuple[Flight, list[str]]:
    """Like :func:`read_flight`, but return the warnings as one-line strings instead."""
    fields, attrs, notes = _read_raw(Path(path))
    flight = Flight(fields, attrs)
    return flight, notes + validate(flight, path, needs)


def file_format(path: PathLike) -> str | None:
    """``"hdf5"`` or ``"csv"`` from the suffix, else None."""
    suffix = Path(path).suffix.lower()
    if suffix in H5_SUFFIXES:
        return "hdf5"
    return "csv" if suffix in CSV_SUFFIXES else None


def _read_raw(path: Path) -> RawFile:
    """Fields, attributes and notes (skipped items) of a file, not yet validated."""
    if not path.exists():
        raise file_error(path, "file not found")
    if path.is_dir():
        raise file_error(path, "is a folder, not a flight file")
    if not os.access(path, os.R_OK):
        raise file_error(path, "permission denied")
    if path.stat().st_size == 0:
        raise file_error(path, "file is empty")
    kind = file_format(path) or ("hdf5" if h5py.is_hdf5(path) else None)
    if kind is None:
        raise file_error(path, f"unsupported file type {path.suffix!r} (use .h5, .hdf5 or .csv)")
    if kind == "hdf5" and not h5py.is_hdf5(path):
        raise file_error(path, "not an HDF5 file (no HDF5 signature)")
    try:
        return _read_h5(path) if kind == "hdf5" else _read_csv(path)
    except FlightFileError:
        raise
    except UnicodeDecodeError:
        raise file_error(path, "cannot read as CSV: not UTF-8 text") from None
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise file_error(path, f"cannot read as {kind.upper()}: {_reason(exc)}") from None


def _reason(exc: BaseException) -> str:
    """First line of an exception message (or its type)."""
    lines = str(exc).strip().splitlines()
    return lines[0] if lines else type(exc).__name__


def _read_h5(path: Path) -> RawFile:
    """Root-level 1-D numeric datasets as fields; 0-D datasets and file attributes as attrs."""
    fields: dict[str, np.ndarray] = {}
    attrs: dict[str, Any] = {}
    skipped = []
    with h5py.File(path, "r") as f:
        for name, item in f.items():
            is_dataset = isinstance(item, h5py.Dataset)
            if is_dataset and item.ndim == 1 and item.dtype.kind in "biuf":
                fields[name] = np.asarray(item[()], dtype=np.float64)
            elif is_dataset and item.ndim == 0 and item.dtype.kind in "biufSUO":
                attrs[name] = _plain(item[()])
            else:
                skipped.append(name)
        attrs.update(_decode_json_attrs({k: _plain(v) for k, v in f.attrs.items()}))
    notes = (
        [f"skipped non-numeric or non-1-D item(s): {truncated_list(skipped)}"] if skipped else []
    )
    return fields, attrs, notes


def _plain(value: Any) -> Any:
    """HDF5 value → plain Python (bytes decoded, numpy scalars and arrays unpacked)."""
    if isinstance(value, bytes):
        return value.decode("utf-8", errors="replace")
    if isinstance(value, str):
        return str(value)
    if isinstance(value, np.ndarray):
        return [_plain(v) for v in value.tolist()] if value.ndim else _plain(value.item())
    if isinstance(value, np.generic):
        return _plain(value.item())
    return value


def _decode_json_attrs(attrs: dict[str, Any]) -> dict[str, Any]:
    """Decode the attributes that the writer JSON-encoded (listed in ``_json_attrs``)."""
    listed = attrs.pop(_JSON_ATTRS, "[]")
    try:
        names = json.loads(listed) if isinstance(listed, str) else []
    except ValueError:
        names = []
    for name in names if isinstance(names, list) else []:
        if isinstance(attrs.get(name), str):
            with contextlib.suppress(ValueError):
                attrs[name] = json.loads(attrs[name])
    return attrs


def _read_csv(path: Path) -> RawFile:
    """Header row, optional ``#@ {json}`` attribute line, numeric columns."""
    attrs: dict[str, Any] = {}
    with open(path, encoding="utf-8-sig") as fh:
        line = fh.readline()
        while line.startswith("#"):
            if line.startswith(ATTR_LINE):
                attrs = _parse_attr_line(path, line[len(ATTR_LINE) :])
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
    columns, skipped = _parse_csv_body(path, body, names)
    unnamed = [f"column {j + 1}" for j, nm in enumerate(names) if not nm]
    skipped += unnamed
    notes = [f"skipped column(s): {truncated_list(skipped)}"] if skipped else []
    return (
        {nm: col for nm, col in zip(names, columns, strict=True) if nm and col is not None},
        attrs,
        notes,
    )


def _parse_attr_line(path: Path, text: str) -> dict[str, Any]:
    """The JSON object after ``#@``."""
    try:
        attrs = json.loads(text)
    except ValueError as exc:
        raise file_error(path, f"attribute line {ATTR_LINE} is not valid JSON ({exc})") from None
    if not isinstance(attrs, dict):
        raise file_error(path, f"attribute line {ATTR_LINE} must hold a JSON object")
    return attrs


def _parse_csv_body(
    path: Path, body: str, names: list[str]
) -> tuple[list[np.ndarray | None], list[str]]:
    """Columns (None where non-numeric) and the names skipped; fast path for all-numeric data."""
    if not body.strip():
        return [np.empty(0) for _ in names], []
    try:
        table = np.loadtxt(io.StringIO(body), delimiter=",", dtype=np.float64, ndmin=2)
    except ValueError:
        return _parse_csv_slow(path, body, names)
    if table.shape[1] != len(names):
        raise file_error(
            path, f"rows have {table.shape[1]} values but the header names {len(names)} columns"
        )
    return [np.ascontiguousarray(table[:, j]) for j in range(len(names))], []


def _parse_csv_slow(
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


def write_flight(flight: Flight, path: PathLike, *, inputs: Iterable[PathLike] = ()) -> Path:
    """Write a flight as HDF5 or CSV (by suffix), atomically, never over an input file.

    Parameters
    ----------
    flight : Flight
    path : str or PathLike
        ``.h5``/``.hdf5`` or ``.csv``; the parent folder is created.
    inputs : iterable of str or PathLike
        Files the run read; ``path`` must not be (or resolve to) any of them.

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    FlightFileError
        Unknown suffix, ``path`` is an input, inconsistent fields, or the write failed (the
        temporary file is removed and an existing file at ``path`` is left untouched).
    """
    out = Path(path)
    kind = file_format(out)
    if kind is None:
        raise file_error(out, f"unsupported output type {out.suffix!r} (use .h5, .hdf5 or .csv)")
    check_not_input(out, inputs, FlightFileError)
    check_structure(flight, out)
    bad_names = [nm for nm in flight.names if not nm or (kind == "hdf5" and "/" in nm)]
    if bad_names:
        raise file_error(out, f"invalid field name(s) for {kind.upper()}: {bad_names}")
    writer = _write_h5 if kind == "hdf5" else _write_csv
    try:
        with atomic_path(out) as tmp:
            writer(flight, tmp)
    except (OSError, TypeError, ValueError) as exc:
        if isinstance(exc, FlightFileError):
            raise
        raise file_error(out, f"cannot write: {_reason(exc)}") from exc
    return out


def _to_json(value: Any) -> str:
    """JSON text of an attribute value (numpy scalars and arrays as plain numbers and lists)."""

    def default(obj: Any) -> Any:
        if isinstance(obj, (np.generic, np.ndarray)):
            return obj.tolist()
        if isinstance(obj, os.PathLike):
            return os.fspath(obj)
        raise TypeError(f"attribute value of type {type(obj).__name__} is not JSON serialisable")

    return json.dumps(value, default=default)


def _write_h5(flight: Flight, tmp: Path) -> None:
    """One float64 dataset per field, in flight order; attributes as strings."""
    with h5py.File(tmp, "w", track_order=True) as f:
        for name, values in flight.fields.items():
            data = np.ascontiguousarray(values, dtype=np.float64)
            f.create_dataset(name, data=data, **(_GZIP if data.size >= _GZIP_MIN_SAMPLES else {}))
        encoded = []
        for key, value in flight.attrs.items():
            f.attrs[key] = value if isinstance(value, str) else _to_json(value)
            if not isinstance(value, str):
                encoded.append(key)
        if encoded:
            f.attrs[_JSON_ATTRS] = json.dumps(encoded)


def _write_csv(flight: Flight, tmp: Path) -> None:
    """Attribute line, header, then rows of shortest round-trip floats."""
    table = np.column_stack([np.asarray(v, dtype=np.float64) for v in flight.fields.values()])
    with open(tmp, "w", encoding="utf-8", newline="") as fh:
        if flight.attrs:
            fh.write(f"{ATTR_LINE} {_to_json(flight.attrs)}\n")
        csv.writer(fh, lineterminator="\n").writerow(flight.names)
        fh.writelines(",".join(map(repr, row)) + "\n" for row in table.tolist())
