"""What every format's reader and writer share: the raw result, the guard around a library
reading a file, attribute values, JSON, scalars."""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from aeromag_env.errors import FlightFileError
from aeromag_env.flight.validation import file_error, truncated_list

#: What a reader returns: fields (float64, file order, the file's names), attributes, notes.
RawFile = tuple[dict[str, np.ndarray], dict[str, Any], list[str]]

#: HDF5 attribute listing the attributes that the writer JSON-encoded.
JSON_ATTRS = "_json_attrs"

#: Array kinds read as numbers (signed, unsigned, float). Booleans (HDF5 bool, MATLAB logical)
#: are flags, not measurements: read as 0/1 they would pass every check as a field in wrong
#: units (a latitude of 0 or 1°), so the readers skip them with a note (:data:`BOOLEAN_ITEMS`).
NUMERIC_KINDS = "iuf"
#: The array kind of booleans.
BOOLEAN_KIND = "b"
#: How a reader's note names the boolean arrays it skipped.
BOOLEAN_ITEMS = "boolean (true/false) item(s), not numbers"
#: How an HDF5 reader's note names the items h5py lists but cannot open: a link to nothing,
#: or an object whose header is damaged. A field among them is then missing, by name.
UNOPENED_ITEMS = "item(s) that cannot be opened (a link to nothing, or damaged)"


#: Display names of the formats.
LABELS = {
    "hdf5": "HDF5",
    "mat5": "MAT v5",
    "mat73": "MAT v7.3",
    "mat": "MAT",
    "csv": "CSV",
    "xyz": "XYZ",
}


@contextlib.contextmanager
def reading(path: Path, kind: str, errors: tuple[type[BaseException], ...]) -> Iterator[None]:
    """Where a reader hands the file to a library (h5py, scipy, the text decoder): the
    exceptions in ``errors``, which that library raises on a damaged file, become the one-line
    :class:`~aeromag_env.errors.FlightFileError` naming the file, its format ``kind`` (a key of
    :data:`LABELS`) and the library's reason. Our own errors pass through unchanged."""
    try:
        yield
    except FlightFileError:
        raise
    except errors as exc:
        raise damaged(path, kind, reason(exc)) from None


def damaged(path: Path, kind: str, why: str) -> FlightFileError:
    """``<path>: cannot read as <format>: damaged or unreadable file (<why>)``."""
    return file_error(path, f"cannot read as {LABELS[kind]}: damaged or unreadable file ({why})")


def reason(exc: BaseException) -> str:
    """First line of an exception message (or its type)."""
    lines = str(exc).strip().splitlines()
    return lines[0] if lines else type(exc).__name__


def plain(value: Any) -> Any:
    """File value → plain Python (bytes decoded, numpy scalars and arrays unpacked)."""
    if isinstance(value, bytes):
        return value.decode("utf-8", errors="replace")
    if isinstance(value, str):
        return str(value)
    if isinstance(value, np.ndarray):
        return [plain(v) for v in value.tolist()] if value.ndim else plain(value.item())
    if isinstance(value, np.generic):
        return plain(value.item())
    return value


def to_json(value: Any) -> str:
    """JSON text of an attribute value (numpy scalars and arrays as plain numbers and lists)."""

    def default(obj: Any) -> Any:
        if isinstance(obj, (np.generic, np.ndarray)):
            return obj.tolist()
        if isinstance(obj, os.PathLike):
            return os.fspath(obj)
        raise TypeError(f"attribute value of type {type(obj).__name__} is not JSON serialisable")

    return json.dumps(value, default=default)


def decode_json_attrs(attrs: dict[str, Any]) -> dict[str, Any]:
    """Decode the attributes that a writer JSON-encoded (listed in ``_json_attrs``)."""
    listed = attrs.pop(JSON_ATTRS, "[]")
    try:
        names = json.loads(listed) if isinstance(listed, str) else []
    except ValueError:
        names = []
    for name in names if isinstance(names, list) else []:
        if isinstance(attrs.get(name), str):
            with contextlib.suppress(ValueError):
                attrs[name] = json.loads(attrs[name])
    return attrs


def is_vector_shape(shape: tuple[int, ...]) -> bool:
    """Whether an array of this shape is a vector: (n,), (n, 1), (1, n), (1, 1), not (n, 3).

    MATLAB stores every vector as a matrix, and some HDF5 exporters do too.
    """
    return len(shape) > 0 and sum(size > 1 for size in shape) <= 1


def split_scalars(
    vectors: dict[str, np.ndarray], shapes: dict[str, tuple[int, ...]]
) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """Fields and scalar attributes from vector candidates whose file shape was 2-D or more.

    A one-element array stored as a matrix (MATLAB's 1×1, an HDF5 (1, 1) dataset) is a scalar
    such as ``dt`` or ``N``, made an attribute, unless every candidate has one element (a flight
    of one sample). 1-D arrays stay fields whatever their length.
    """
    longest = max((v.size for v in vectors.values()), default=0)
    fields: dict[str, np.ndarray] = {}
    attrs: dict[str, Any] = {}
    for name, values in vectors.items():
        if values.size == 1 and longest > 1 and len(shapes[name]) > 1:
            attrs[name] = plain(values[0])
        else:
            fields[name] = values
    return fields, attrs


def skipped_note(skipped: list[str], what: str = "non-numeric or non-vector item(s)") -> list[str]:
    """``["skipped <what>: a, b"]``, or nothing."""
    return [f"skipped {what}: {truncated_list(skipped)}"] if skipped else []
