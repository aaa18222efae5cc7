"""HDF5 in the flat MagNav/SGL layout (SGL 2020 and 2021, MagNav.jl, our own files).

Reading
    Every numeric dataset at the root with at most one axis longer than 1 is a field: (n,), and
    also (n, 1) or (1, n) as some exporters write them. A (1, 1) or 0-D dataset (SGL's ``N``,
    ``dt``) and a string dataset (``info``) become attributes; a boolean array is not a field
    (a flag, not numbers) and is skipped and reported on its own; anything else (matrices such
    as MagNav.jl's ``Cnb``, groups) is skipped and reported. File attributes become
    :attr:`Flight.attrs`, bytes decoded to ``str``.
Writing
    One float64 1-D dataset per field, in flight order (gzip above 4096 samples). Attributes
    are stored as strings: non-string values JSON-encoded, their names listed in the attribute
    ``_json_attrs`` so that the reader decodes them back. Nothing is lost: write → read gives
    bit-identical arrays (NaN payloads included) and equal attributes.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import h5py
import numpy as np

from aeromag_env.flight.data import Flight
from aeromag_env.flight.formats.common import (
    BOOLEAN_ITEMS,
    BOOLEAN_KIND,
    JSON_ATTRS,
    NUMERIC_KINDS,
    UNOPENED_ITEMS,
    RawFile,
    decode_json_attrs,
    is_vector_shape,
    plain,
    reading,
    skipped_note,
    split_scalars,
    to_json,
)
from aeromag_env.flight.formats.hdf5_check import check_global_heaps

#: What h5py raises on a damaged file: it maps HDF5's error classes onto OSError (I/O, a
#: truncated file, a filter that fails), KeyError (an object not found), ValueError and
#: TypeError (bad values and datatypes) and RuntimeError for the rest (a broken B-tree, symbol
#: table, heap or object header); NotImplementedError (a RuntimeError) for a feature it lacks.
H5PY_ERRORS: tuple[type[Exception], ...] = (OSError, RuntimeError, KeyError, ValueError, TypeError)
_GZIP: dict[str, Any] = {"compression": "gzip", "compression_opts": 1, "shuffle": True}
_GZIP_MIN_SAMPLES = 4096  # smaller datasets are stored plain (chunking overhead)


def read_h5(path: Path) -> RawFile:
    """Fields, attributes and notes of a flat HDF5 flight file (see the module docstring)."""
    check_global_heaps(path)  # a collection the library would loop on is refused first
    with reading(path, "hdf5", H5PY_ERRORS), h5py.File(path, "r") as f:
        items = [(name, *_read_item(item)) for name, item in f.items()]
        file_attrs = dict(f.attrs.items())
    vectors: dict[str, np.ndarray] = {}
    shapes: dict[str, tuple[int, ...]] = {}
    attrs: dict[str, Any] = {}
    passed: dict[str, list[str]] = {"boolean": [], "skipped": [], "unopened": []}
    for name, role, shape, value in items:
        if role == "attribute":
            attrs[name] = plain(value)
        elif role == "field":
            vectors[name] = np.asarray(value, dtype=np.float64).reshape(-1)
            shapes[name] = shape
        else:
            passed[role].append(name)
    attrs.update(decode_json_attrs({k: plain(v) for k, v in file_attrs.items()}))
    fields, scalars = split_scalars(vectors, shapes)
    notes = (
        skipped_note(passed["unopened"], UNOPENED_ITEMS)
        + skipped_note(passed["boolean"], BOOLEAN_ITEMS)
        + skipped_note(passed["skipped"])
    )
    return fields, {**scalars, **attrs}, notes


def _read_item(item: Any) -> tuple[str, tuple[int, ...], Any]:
    """A root item's role (``field``, ``attribute``, ``boolean``, ``skipped`` or ``unopened``),
    its shape and, for a field or an attribute, its value, read while the file is open. ``item``
    is what h5py found under the name: a dataset, a group, or None when it cannot open it."""
    if item is None:
        return "unopened", (), None
    if not isinstance(item, h5py.Dataset):
        return "skipped", (), None
    kind, shape = item.dtype.kind, item.shape
    if item.ndim == 0 and kind in NUMERIC_KINDS + BOOLEAN_KIND + "SUO":
        return "attribute", shape, item[()]
    if kind in NUMERIC_KINDS and item.ndim and is_vector_shape(shape):
        return "field", shape, item[()]
    return ("boolean" if kind == BOOLEAN_KIND else "skipped"), shape, None


def write_h5(flight: Flight, tmp: Path) -> None:
    """One float64 dataset per field, in flight order; attributes as strings."""
    with h5py.File(tmp, "w", track_order=True) as f:
        for name, values in flight.fields.items():
            data = np.ascontiguousarray(values, dtype=np.float64)
            f.create_dataset(name, data=data, **(_GZIP if data.size >= _GZIP_MIN_SAMPLES else {}))
        encoded = []
        for key, value in flight.attrs.items():
            f.attrs[key] = value if isinstance(value, str) else to_json(value)
            if not isinstance(value, str):
                encoded.append(key)
        if encoded:
            f.attrs[JSON_ATTRS] = to_json(encoded)
