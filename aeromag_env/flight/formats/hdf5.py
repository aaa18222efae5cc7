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
    RawFile,
    decode_json_attrs,
    is_vector_shape,
    plain,
    skipped_note,
    split_scalars,
    to_json,
)

SIGNATURE = b"\x89HDF\r\n\x1a\n"
_GZIP: dict[str, Any] = {"compression": "gzip", "compression_opts": 1, "shuffle": True}
_GZIP_MIN_SAMPLES = 4096  # smaller datasets are stored plain (chunking overhead)


def read_h5(path: Path) -> RawFile:
    """Fields, attributes and notes of a flat HDF5 flight file (see the module docstring)."""
    vectors: dict[str, np.ndarray] = {}
    shapes: dict[str, tuple[int, ...]] = {}
    attrs: dict[str, Any] = {}
    skipped: list[str] = []
    booleans: list[str] = []
    with h5py.File(path, "r") as f:
        for name, item in f.items():
            kind = item.dtype.kind if isinstance(item, h5py.Dataset) else ""
            if kind and item.ndim == 0 and kind in NUMERIC_KINDS + BOOLEAN_KIND + "SUO":
                attrs[name] = plain(item[()])
            elif kind and kind in NUMERIC_KINDS and item.ndim and is_vector_shape(item.shape):
                vectors[name] = np.asarray(item[()], dtype=np.float64).reshape(-1)
                shapes[name] = item.shape
            else:
                (booleans if kind == BOOLEAN_KIND else skipped).append(name)
        attrs.update(decode_json_attrs({k: plain(v) for k, v in f.attrs.items()}))
    fields, scalars = split_scalars(vectors, shapes)
    notes = skipped_note(booleans, BOOLEAN_ITEMS) + skipped_note(skipped)
    return fields, {**scalars, **attrs}, notes


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
