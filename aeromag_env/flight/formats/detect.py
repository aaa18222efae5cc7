"""Which format a file is in, from its first bytes, not from its name.

* ``"mat73"``: a MAT-file v7.3, whose 512-byte header starts ``MATLAB 7.3 MAT-file`` and is
  followed by HDF5;
* ``"mat5"``: a MAT-file v5 (also v6, v7), whose header starts ``MATLAB 5.0 MAT-file``;
* ``"hdf5"``: the HDF5 signature at byte 0 (or after a user block of 512, 1024, … bytes);
* ``"xyz"``: text with ``/`` header lines or ``LINE``/``TIE`` records (Geosoft XYZ);
* ``"csv"``: text whose first line that is not a ``#`` comment holds a comma.

Text that is neither (a one-column CSV, a header-only file) is read as the suffix says when the
suffix is ``.csv`` or ``.xyz``. Anything else is refused with a one-line
:class:`~aeromag_env.errors.FlightFileError`.
"""

from __future__ import annotations

import codecs
from pathlib import Path

from aeromag_env.flight.formats.hdf5_check import SIGNATURE
from aeromag_env.flight.formats.mat import MAT5_HEADER, MAT73_HEADER
from aeromag_env.flight.formats.xyz import RECORD_RE
from aeromag_env.flight.validation import file_error

#: What each suffix promises (``.mat`` means either MAT version).
SUFFIXES = {".h5": "hdf5", ".hdf5": "hdf5", ".csv": "csv", ".xyz": "xyz", ".mat": "mat"}

_SAMPLE_BYTES = 65_536
_SAMPLE_LINES = 500
_CONTROL = set(range(32)) - {9, 10, 12, 13}  # control bytes other than tab, LF, FF, CR


def detect_format(path: Path) -> str:
    """``"hdf5"``, ``"mat5"``, ``"mat73"``, ``"csv"`` or ``"xyz"`` (see the module docstring).

    Raises
    ------
    FlightFileError
        Binary content of no known format, or text that is neither CSV nor XYZ.
    """
    with open(path, "rb") as fh:
        head = fh.read(_SAMPLE_BYTES)
    if head.startswith(MAT73_HEADER):
        return "mat73"
    if head.startswith(MAT5_HEADER):
        return "mat5"
    if any(head[at : at + 8] == SIGNATURE for at in _superblock_offsets(len(head))):
        return "hdf5"
    text = _text(head)
    if text is None:
        raise file_error(
            path, "unknown content: not HDF5, not a MAT-file and not UTF-8 text (CSV or XYZ)"
        )
    return _text_format(path, text)


def _superblock_offsets(size: int) -> list[int]:
    """Where HDF5 may put its signature: 0, 512, 1024, 2048, … (within the sample)."""
    offsets, at = [0], 512
    while at < size:
        offsets.append(at)
        at *= 2
    return offsets


def _text(head: bytes) -> str | None:
    """The sample as text (UTF-8, else Latin-1), or None if it holds control bytes (binary)."""
    if _CONTROL & set(head):
        return None
    try:
        return codecs.getincrementaldecoder("utf-8-sig")().decode(head, final=False)
    except UnicodeDecodeError:
        return head.decode("latin-1")


def _text_format(path: Path, text: str) -> str:
    """``"xyz"`` or ``"csv"`` from the first lines; the suffix decides an ambiguous text."""
    lines = [ln.strip() for ln in text.splitlines()[:_SAMPLE_LINES]]
    lines = [ln for ln in lines if ln]
    if any(ln.startswith("/") or RECORD_RE.match(ln) for ln in lines):
        return "xyz"
    first = next((ln for ln in lines if not ln.startswith("#")), "")
    if "," in first:
        return "csv"
    by_suffix = SUFFIXES.get(path.suffix.lower())
    if by_suffix in ("csv", "xyz"):
        return by_suffix
    raise file_error(
        path,
        "text, but neither CSV (a header row of comma-separated names) nor Geosoft XYZ "
        "('/' header lines naming the columns)",
    )
