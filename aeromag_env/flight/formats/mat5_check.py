"""A walk over a v5 MAT-file's data elements before scipy reads it.

scipy's v5 reader takes the type code of an element holding numbers or characters from the
file and looks it up in a table of 20 slots without checking it: a code with no type there
(0, 8, 10, 11, 14, 15, 19, or 20 and above, as one damaged byte makes them) crashes the
process instead of raising. An array class it does not know (0, or above 17) ends in its own
UnboundLocalError. :func:`check_data_types` walks the variables as scipy will, down to each
numeric, character and sparse array's data elements, and refuses either with a one-line
:class:`~aeromag_env.errors.FlightFileError` first. Everything else that is wrong with the file
is left to scipy, which raises on it.

Layout (MATLAB's "MAT-File Format", version 5): a 128-byte header whose last two bytes tell
the byte order (``IM`` little-endian, ``MI`` big-endian), then elements, each an 8-byte tag
(type code, byte count) and its data padded to 8 bytes, or a small element whose byte count
(at most 4) sits in the upper half of the tag's first word and whose data fills its second.
A variable is an ``miMATRIX`` element (or one inside a zlib-compressed ``miCOMPRESSED``
element): array flags (the class in the low byte, bit 11 complex), dimensions, name, then by
class the real and imaginary parts, the characters, the sparse indices and values, or the
field names and nested ``miMATRIX`` elements of a cell, struct or object.
"""

from __future__ import annotations

import mmap
import struct
import zlib
from pathlib import Path

from aeromag_env.flight.formats.common import damaged

HEADER_BYTES = 128
MI_MATRIX, MI_COMPRESSED = 14, 15
#: Type codes scipy has a type for: miINT8 … miSINGLE (1-7), miDOUBLE (9), miINT64,
#: miUINT64 (12, 13), miUTF8, miUTF16, miUTF32 (16-18).
DATA_TYPES = frozenset({1, 2, 3, 4, 5, 6, 7, 9, 12, 13, 16, 17, 18})
#: Array classes whose data elements scipy reads by type code: characters, sparse (row indices,
#: column starts, real and imaginary values) and the numeric classes 6-15 (real and imaginary
#: parts).
CHAR_CLASS, SPARSE_CLASS = 4, 5
#: Classes holding nested ``miMATRIX`` elements, and how many elements come before them
#: (cell: none; struct: field-name length and names; object: class name too; function: none).
CONTAINER_CLASSES = {1: 0, 2: 2, 3: 3, 16: 0}
OPAQUE_CLASS = 17
#: The array classes scipy reads (mxCELL_CLASS 1 … mxOPAQUE_CLASS 17).
CLASSES = range(1, 18)
#: Deeper nesting is not walked (no flight file nests so deep; scipy reads it unchecked).
MAX_DEPTH = 32


class _Elements:
    """The elements of ``buf[start:end]``, one by one (``order``: ``<`` or ``>``)."""

    def __init__(self, buf: bytes | mmap.mmap, start: int, end: int, order: str) -> None:
        self.buf, self.pos, self.end, self.order = buf, start, min(end, len(buf)), order

    def next(self) -> tuple[int, int, int] | None:
        """(type code, byte count, where its data starts) of the next element, or None when
        no whole element is left."""
        if self.pos + 8 > self.end:
            return None
        first, second = struct.unpack_from(self.order + "II", self.buf, self.pos)
        if first >> 16:  # small element: 4 bytes of tag, 4 of data
            code, size, data = first & 0xFFFF, first >> 16, self.pos + 4
            self.pos += 8
        else:
            code, size, data = first, second, self.pos + 8
            self.pos = data + size + (-size % 8)
        return (code, size, data) if data + size <= self.end else None


def check_data_types(path: Path) -> None:
    """Refuse a v5 MAT-file with a data element or array class that would crash scipy's reader.

    Raises
    ------
    FlightFileError
        ``<path>: cannot read as MAT v5: damaged or unreadable file (…)``, naming the variable,
        the code and where it is (a byte offset in the file, or in a compressed variable).
    """
    with open(path, "rb") as fh, mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) as buf:
        order = ">" if buf[HEADER_BYTES - 2 : HEADER_BYTES] == b"MI" else "<"
        pos, number = HEADER_BYTES, 0
        while pos + 8 <= len(buf):
            code, size = struct.unpack_from(order + "II", buf, pos)
            start, pos, number = pos + 8, pos + 8 + size, number + 1
            bad, within = None, "of the file"
            if code == MI_MATRIX:
                bad = _matrix(buf, start, start + size, order, 0)
            elif code == MI_COMPRESSED:
                bad, within = _compressed(bytes(buf[start : start + size]), order), "inflated"
            if bad is not None:
                what, at = bad
                raise damaged(path, "mat5", f"variable {number}: {what} at byte {at} {within}")


def _compressed(payload: bytes, order: str) -> tuple[str, int] | None:
    """What is bad in a compressed variable, and where; a stream zlib cannot inflate is left
    to scipy, which refuses it."""
    try:
        inner = zlib.decompressobj().decompress(payload)
    except zlib.error:
        return None
    head = _Elements(inner, 0, len(inner), order).next()
    if head is None or head[0] != MI_MATRIX:
        return None
    return _matrix(inner, head[2], head[2] + head[1], order, 0)


def _matrix(
    buf: bytes | mmap.mmap, start: int, end: int, order: str, depth: int
) -> tuple[str, int] | None:
    """What in the ``miMATRIX`` body ``buf[start:end]`` (nested ones too) scipy's reader has no
    entry for (an array class, a data element's type code), and its offset; or None."""
    elements = _Elements(buf, start, end, order)
    flags = elements.next()
    if flags is None or flags[1] < 4 or depth > MAX_DEPTH:
        return None
    (word,) = struct.unpack_from(order + "I", buf, flags[2])
    mclass, is_complex = word & 0xFF, bool(word >> 11 & 1)
    if mclass not in CLASSES:
        return f"array class {mclass}, which no MATLAB array has,", flags[2]
    if mclass == OPAQUE_CLASS or elements.next() is None or elements.next() is None:
        return None  # dimensions and name read; an opaque object is not walked
    if mclass in CONTAINER_CLASSES:
        return _nested(elements, CONTAINER_CLASSES[mclass], depth)
    parts = {CHAR_CLASS: 1, SPARSE_CLASS: 4 if is_complex else 3}.get(mclass)
    if parts is None:
        parts = 2 if is_complex else 1
    for _ in range(parts):
        tag_at = elements.pos
        element = elements.next()
        if element is None:
            return None
        empty_text = mclass == CHAR_CLASS and element[1] == 0  # read as blanks, no type needed
        if element[0] not in DATA_TYPES and not empty_text:
            return f"type code {element[0]}, where numbers or text should be,", tag_at
    return None


def _nested(elements: _Elements, before: int, depth: int) -> tuple[str, int] | None:
    """The first bad thing in the ``miMATRIX`` elements of a cell, struct, object or function
    handle, after its ``before`` elements of names."""
    for _ in range(before):
        elements.next()
    while (nested := elements.next()) is not None:
        code, size, data = nested
        found = code == MI_MATRIX and _matrix(
            elements.buf, data, data + size, elements.order, depth + 1
        )
        if found:
            return found
    return None
