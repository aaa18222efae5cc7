"""Flight files: read, write and convert HDF5, CSV, Geosoft XYZ and MATLAB ``.mat``.

========================== ============ =====================================================
format                     suffix       module (layout, what a round trip keeps)
========================== ============ =====================================================
HDF5, flat MagNav/SGL      .h5, .hdf5   :mod:`~aeromag_env.flight.formats.hdf5`
CSV                        .csv         :mod:`~aeromag_env.flight.formats.csvfile`
Geosoft XYZ                .xyz         :mod:`~aeromag_env.flight.formats.xyz`
MATLAB v5 (read v7.3 too)  .mat         :mod:`~aeromag_env.flight.formats.mat`
========================== ============ =====================================================

Readers find the format from the content (:mod:`~aeromag_env.flight.formats.detect`), so a file
with a wrong suffix still reads (with a warning), and rename the fields that have an alias to our
names (:mod:`~aeromag_env.flight.aliases`: SGL 2020 names; SGL 2021, MagNav.jl's older names and
the Geosoft XYZ columns are mapped), recording the originals in ``attrs["aliases"]``. Writers
pick the format from the suffix.

All arrays are float64. Write → read returns the same field names and attributes, bit-identical
arrays for HDF5 and MAT, and bit-identical finite values with NaN kept as NaN (not its payload)
for CSV and XYZ. Writers refuse to overwrite an input file and write atomically: a temporary
file in the target folder, then ``os.replace``.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable, Iterable
from pathlib import Path

from aeromag_env.atomic import atomic_path, check_output_file
from aeromag_env.errors import FlightFileError
from aeromag_env.flight.aliases import apply_aliases
from aeromag_env.flight.data import Flight
from aeromag_env.flight.formats import mat, xyz
from aeromag_env.flight.formats.common import LABELS, RawFile, reason
from aeromag_env.flight.formats.csvfile import read_csv
from aeromag_env.flight.formats.csvfile import write_csv as _write_csv
from aeromag_env.flight.formats.detect import SUFFIXES, detect_format
from aeromag_env.flight.formats.hdf5 import read_h5
from aeromag_env.flight.formats.hdf5 import write_h5 as _write_h5
from aeromag_env.flight.validation import (
    FlightFileWarning,
    PathLike,
    check_structure,
    file_error,
    validate,
)

_SUPPORTED = ".h5, .hdf5, .csv, .xyz or .mat"
_READERS: dict[str, Callable[[Path], RawFile]] = {
    "hdf5": read_h5,
    "mat73": mat.read_mat73,
    "mat5": mat.read_mat5,
    "csv": read_csv,
    "xyz": xyz.read_xyz,
}


def read_flight(path: PathLike, needs: Iterable[str] = ("tt",)) -> Flight:
    """Read and validate a flight file (HDF5, CSV, Geosoft XYZ or MATLAB ``.mat``).

    Parameters
    ----------
    path : str or PathLike
        The file; its format is found from its content (see the module docstring).
    needs : iterable of str
        What the caller will use (see :func:`aeromag_env.flight.validation.validate`): field names,
        vector prefixes such as ``"flux_a"``, and the groups ``"position"``, ``"attitude"``,
        ``"date"``. Only these must be present; ``tt`` always is.

    Returns
    -------
    Flight
        Float64 fields in file order, under our names (aliases applied), and the file
        attributes. Warnings (aliases applied, non-finite samples, implausible channels not in
        ``needs``, skipped items) are issued as
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
    fields, attrs, renamed = apply_aliases(fields, attrs)
    flight = Flight(fields, attrs)
    return flight, notes + renamed + validate(flight, path, needs)


def file_format(path: PathLike) -> str | None:
    """``"hdf5"``, ``"csv"``, ``"xyz"`` or ``"mat"`` from the suffix, else None.

    This is what a writer produces; a reader looks at the content instead.
    """
    return SUFFIXES.get(Path(path).suffix.lower())


def _read_raw(path: Path) -> RawFile:
    """Fields (the file's names), attributes and notes of a file, not yet validated."""
    if not path.exists():
        raise file_error(path, "file not found")
    if path.is_dir():
        raise file_error(path, "is a folder, not a flight file")
    if not os.access(path, os.R_OK):
        raise file_error(path, "permission denied")
    if path.stat().st_size == 0:
        raise file_error(path, "file is empty")
    try:  # each reader turns what its library raises on a damaged file into FlightFileError
        kind = detect_format(path)
        fields, attrs, notes = _READERS[kind](path)
    except OSError as exc:  # the file itself cannot be read (an I/O error, gone meanwhile)
        raise file_error(path, f"cannot read: {exc.strerror or reason(exc)}") from None
    return fields, attrs, _suffix_note(path, kind) + notes


def _suffix_note(path: Path, kind: str) -> list[str]:
    """A warning when the suffix promises another format than the content is."""
    promised = file_format(path)
    if promised is None or promised == kind or (promised == "mat" and kind.startswith("mat")):
        return []
    said = LABELS[promised]
    return [f"the content is {LABELS[kind]}, not {said} as the suffix says: read as {LABELS[kind]}"]


def _writer(kind: str) -> tuple[Callable[[Flight, Path], None], Callable[[list[str]], list[str]]]:
    """The writer of a format and the check of its field names (looked up at call time)."""
    if kind == "hdf5":
        return _write_h5, lambda names: [nm for nm in names if not nm or "/" in nm]
    if kind == "csv":
        return _write_csv, lambda names: [nm for nm in names if not nm]
    if kind == "xyz":
        return xyz.write_xyz, xyz.invalid_names
    return mat.write_mat5, mat.invalid_names


def write_flight(flight: Flight, path: PathLike, *, inputs: Iterable[PathLike] = ()) -> Path:
    """Write a flight as HDF5, CSV, Geosoft XYZ or MAT v5 (by suffix), atomically, never over
    an input file.

    Parameters
    ----------
    flight : Flight
    path : str or PathLike
        ``.h5``/``.hdf5``, ``.csv``, ``.xyz`` or ``.mat``; the parent folder is created.
    inputs : iterable of str or PathLike
        Files the run read; ``path`` must not be (or resolve to) any of them.

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    FlightFileError
        Unknown suffix, ``path`` is an input, inconsistent fields, field names the format cannot
        hold, or the write failed (the temporary file is removed and an existing file at
        ``path`` is left untouched).
    """
    out = Path(path)
    kind = file_format(out)
    if kind is None:
        raise file_error(out, f"unsupported output type {out.suffix!r} (use {_SUPPORTED})")
    check_output_file(out, inputs, FlightFileError)
    check_structure(flight, out)
    writer, invalid = _writer(kind)
    bad_names = invalid(flight.names)
    if bad_names:
        raise file_error(out, f"invalid field name(s) for {LABELS[kind]}: {bad_names}")
    try:
        with atomic_path(out) as tmp:
            writer(flight, tmp)
    except (OSError, TypeError, ValueError) as exc:
        if isinstance(exc, FlightFileError):
            raise
        raise file_error(out, f"cannot write: {reason(exc)}") from exc
    return out


def convert_flight(source: PathLike, target: PathLike) -> tuple[Flight, list[str]]:
    """Read ``source`` (any format, by content) and write it to ``target`` (format by suffix).

    Parameters
    ----------
    source, target : str or PathLike
        ``target`` must not be ``source``; it is written atomically.

    Returns
    -------
    flight : Flight
        What was written (our field names, the aliases recorded in ``attrs["aliases"]``).
    warnings : list of str
        The reader's warnings (aliases applied, skipped items, non-finite samples…).

    Raises
    ------
    FlightFileError
        Unreadable input, unknown output suffix, output equal to the input, or a failed write.
    """
    if file_format(target) is None:
        raise file_error(
            target, f"unsupported output type {Path(target).suffix!r} (use {_SUPPORTED})"
        )
    check_output_file(target, [source], FlightFileError)
    flight, problems = load_flight(source)
    write_flight(flight, target, inputs=[source])
    return flight, problems
