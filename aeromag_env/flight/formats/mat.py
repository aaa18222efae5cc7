"""MATLAB ``.mat`` files: v5 (also v6/v7) through :func:`scipy.io.loadmat`, v7.3 through h5py.

Reading
    The fields are the top-level numeric vectors, (n, 1) or (1, n) as MATLAB stores them; or, when
    the file holds one struct and no top-level vectors (MagNav.jl's ``traj`` layout), the vectors
    inside that struct (its name goes to the attribute ``mat_struct``). One-element numbers
    (``dt``, ``N``) and character arrays become attributes, a character array
    ``aeromag_attrs`` holding a JSON object becomes the attributes themselves. Logical arrays
    (flags, not numbers) are skipped and reported on their own, a one-element logical is an
    attribute (a logical is stored as uint8: a v5 file with integer variables is loaded a
    second time as MATLAB classes, ``mat_dtype``, to tell them apart). Matrices, cell arrays,
    empty arrays and further structs are skipped and reported. A v7.3 file is HDF5 with a
    512-byte MATLAB header: its ``#refs#`` and ``#subsystem#`` groups are MATLAB's own and
    passed over.
Writing (v5 only)
    One double column vector (n × 1) per field, in flight order, compressed, and the attributes
    as JSON (ASCII) in the character array ``aeromag_attrs``. Write → read gives bit-identical
    arrays (NaN payloads included) and equal attributes (JSON types). Field names must be MATLAB
    names: a letter, then letters, digits or ``_``, at most 63 characters.
"""

from __future__ import annotations

import json
import re
import struct
import warnings
import zlib
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import scipy.io
from scipy.io.matlab import MatReadError

from aeromag_env.flight.data import Flight
from aeromag_env.flight.formats.common import (
    BOOLEAN_ITEMS,
    BOOLEAN_KIND,
    NUMERIC_KINDS,
    UNOPENED_ITEMS,
    RawFile,
    is_vector_shape,
    plain,
    reading,
    skipped_note,
    split_scalars,
    to_json,
)
from aeromag_env.flight.formats.hdf5 import H5PY_ERRORS
from aeromag_env.flight.formats.hdf5_check import check_global_heaps
from aeromag_env.flight.formats.mat5_check import check_data_types

MAT5_HEADER = b"MATLAB 5.0 MAT-file"
#: What scipy's v5 reader raises on a damaged file: its own MatReadError, ValueError (a bad
#: size, tag or text), TypeError (an element of another type than the layout wants), KeyError
#: and IndexError (a type or class code it has no entry for), EOFError and OSError (data cut
#: short), struct.error (a header cut short), zlib.error (a damaged compressed variable),
#: ZeroDivisionError (a struct's field-name length of 0), OverflowError (a size beyond C's).
SCIPY_MAT_ERRORS: tuple[type[Exception], ...] = (
    MatReadError,
    ValueError,
    TypeError,
    KeyError,
    IndexError,
    EOFError,
    OSError,
    struct.error,
    zlib.error,
    ZeroDivisionError,
    OverflowError,
)
MAT73_HEADER = b"MATLAB 7.3 MAT-file"
ATTRS_VARIABLE = "aeromag_attrs"
STRUCT_ATTR = "mat_struct"
_MATLAB_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]{0,62}$")


class _Struct(dict[str, Any]):
    """The fields of a MATLAB struct (a dict, marked as such)."""


def read_mat5(path: Path) -> RawFile:
    """Fields, attributes and notes of a v5/v6/v7 MAT-file (see the module docstring)."""
    check_data_types(path)  # a type code that would crash scipy's reader is refused first
    items = _load_mat5(path, as_class=False)
    if _has_integers(items):  # a logical loads as the uint8 it is stored as: find it by class
        items = _logicals_as_bool(items, _load_mat5(path, as_class=True))
    return _collect(items)


def _load_mat5(path: Path, as_class: bool) -> dict[str, Any]:
    """The variables of a v5 MAT-file, structs marked. ``as_class``: each converted to its
    MATLAB class (``mat_dtype``), which tells a logical from a uint8 but casts complex values
    to real: such a load is only asked for its logicals (ComplexWarning silenced)."""
    reader = reading(path, "mat5", SCIPY_MAT_ERRORS)
    with reader, open(path, "rb") as fh, warnings.catch_warnings():
        warnings.simplefilter("ignore", np.exceptions.ComplexWarning)
        data = scipy.io.loadmat(fh, simplify_cells=True, mat_dtype=as_class)
    return {k: _mark_structs(v) for k, v in data.items() if not k.startswith("__")}


def _has_integers(items: dict[str, Any]) -> bool:
    """Whether any variable (in structs too) loaded as an integer: possibly a logical."""
    return any(
        _has_integers(v) if isinstance(v, _Struct) else np.asarray(v).dtype.kind in "iu"
        for v in items.values()
        if isinstance(v, (_Struct, np.ndarray, np.generic, int))
    )


def _logicals_as_bool(items: dict[str, Any], classes: dict[str, Any]) -> dict[str, Any]:
    """``items`` with the variables that are logical in ``classes`` (the same file loaded as
    MATLAB classes) as bool arrays, in structs too."""
    out = dict(items)
    for name, value in items.items():
        cls = classes.get(name)
        if isinstance(value, _Struct) and isinstance(cls, _Struct):
            out[name] = _Struct(_logicals_as_bool(value, cls))
        elif isinstance(cls, (bool, np.bool_, np.ndarray)) and np.asarray(cls).dtype.kind == "b":
            out[name] = np.asarray(cls)
    return out


def _mark_structs(value: Any) -> Any:
    """loadmat's dicts (structs) → :class:`_Struct`, recursively."""
    if isinstance(value, dict):
        return _Struct({k: _mark_structs(v) for k, v in value.items()})
    return value


def read_mat73(path: Path) -> RawFile:
    """Fields, attributes and notes of a v7.3 MAT-file (HDF5 with a MATLAB header)."""
    unopened: list[str] = []
    check_global_heaps(path, "mat73")  # a collection the library would loop on is refused first
    with reading(path, "mat73", H5PY_ERRORS), h5py.File(path, "r") as f:
        items = _h5_items(f, unopened)
    fields, attrs, notes = _collect(items)
    return fields, attrs, skipped_note(unopened, UNOPENED_ITEMS) + notes


def _h5_items(group: h5py.Group, unopened: list[str], prefix: str = "") -> dict[str, Any]:
    """A v7.3 group as loadmat would give it: arrays, strings, structs, None for the rest;
    the names h5py lists but cannot open are added to ``unopened``."""
    items: dict[str, Any] = {}
    for name, item in group.items():
        if name.startswith("#"):
            continue
        if item is None:  # a link to nothing, or a damaged object header
            unopened.append(prefix + name)
            continue
        cls = plain(item.attrs.get("MATLAB_class", b""))
        if isinstance(item, h5py.Group):
            inner = _h5_items(item, unopened, f"{prefix}{name}.") if cls == "struct" else None
            items[name] = None if inner is None else _Struct(inner)
        elif item.attrs.get("MATLAB_empty", 0):
            items[name] = np.empty(0)
        elif cls == "char":
            items[name] = "".join(map(chr, np.asarray(item[()]).ravel().tolist()))
        elif cls == "logical":  # stored as uint8
            items[name] = np.asarray(item[()]).astype(bool)
        elif item.dtype.kind in NUMERIC_KINDS + BOOLEAN_KIND:
            items[name] = np.asarray(item[()])
        else:
            items[name] = None  # cell arrays (object references), function handles…
    return items


def _collect(items: dict[str, Any]) -> RawFile:
    """Fields (top level, or the single struct's), attributes and the names skipped."""
    attrs: dict[str, Any] = {}
    text = items.pop(ATTRS_VARIABLE, None)
    structs = [nm for nm, v in items.items() if isinstance(v, _Struct)]
    vectors, shapes, found, skipped, booleans = _sort_items(items)
    if len(structs) == 1 and not any(v.size > 1 for v in vectors.values()):
        name = structs[0]
        attrs.update({nm: plain(v[0]) for nm, v in vectors.items()})  # top-level scalars
        vectors, shapes, inner, skipped_inner, booleans_inner = _sort_items(items[name])
        attrs[STRUCT_ATTR] = name
        skipped = [nm for nm in skipped if nm != name] + [f"{name}.{nm}" for nm in skipped_inner]
        booleans += [f"{name}.{nm}" for nm in booleans_inner]
        found = {**found, **inner}
    fields, scalars = split_scalars(vectors, shapes)
    attrs.update({**scalars, **found})
    if isinstance(text, str):
        attrs.update(_json_object(text))
    notes = skipped_note(booleans, BOOLEAN_ITEMS)
    return fields, attrs, notes + skipped_note(skipped, "item(s) that are not vectors")


def _sort_items(
    items: dict[str, Any],
) -> tuple[dict[str, np.ndarray], dict[str, tuple[int, ...]], dict[str, Any], list[str], list[str]]:
    """Numeric vectors (with their MATLAB shapes), string, number and one-element logical
    attributes, skipped names, skipped logical arrays' names."""
    vectors: dict[str, np.ndarray] = {}
    shapes: dict[str, tuple[int, ...]] = {}
    attrs: dict[str, Any] = {}
    skipped: list[str] = []
    booleans: list[str] = []
    for name, value in items.items():
        if isinstance(value, str):
            attrs[name] = value
            continue
        numeric = isinstance(value, (np.ndarray, np.generic, int, float))
        array = np.asarray(value) if numeric else None
        if array is not None and array.dtype.kind == BOOLEAN_KIND and array.size == 1:
            attrs[name] = plain(array.reshape(-1)[0])
        elif array is not None and array.dtype.kind == BOOLEAN_KIND:
            booleans.append(name)
        elif array is None or array.dtype.kind not in NUMERIC_KINDS or array.size == 0:
            skipped.append(name)
        elif array.ndim == 0 or is_vector_shape(array.shape):
            vectors[name] = np.asarray(array, dtype=np.float64).reshape(-1)
            shapes[name] = array.shape if array.ndim else (1, 1)
        else:
            skipped.append(name)
    return vectors, shapes, attrs, skipped, booleans


def _json_object(text: str) -> dict[str, Any]:
    """The attributes our writer stored; anything else is kept as the string it is."""
    try:
        value = json.loads(text)
    except ValueError:
        value = None
    return value if isinstance(value, dict) else {ATTRS_VARIABLE: text}


def invalid_names(names: list[str]) -> list[str]:
    """Field names a MAT-file cannot hold (not MATLAB names, or our attribute variable)."""
    return [nm for nm in names if not _MATLAB_NAME.match(nm) or nm == ATTRS_VARIABLE]


def write_mat5(flight: Flight, tmp: Path) -> None:
    """A v5 MAT-file: one n × 1 double per field, the attributes as JSON (module docstring)."""
    variables: dict[str, Any] = {
        name: np.asarray(values, dtype=np.float64).reshape(-1, 1)
        for name, values in flight.fields.items()
    }
    if flight.attrs:
        variables[ATTRS_VARIABLE] = to_json(flight.attrs)
    with open(tmp, "wb") as fh:
        scipy.io.savemat(fh, variables, format="5", do_compression=True, oned_as="column")
