"""A look at an HDF5 file's global heap collections before the HDF5 library reads them.

Variable-length data (the string attributes that h5py, MATLAB and our writer store) lives in
global heap collections. The library walks a collection's objects by their sizes, and takes a
free-space object (index 0) of size 0 as a step of 0 bytes: on a damaged collection it loops
forever, inside C, where no signal or time limit of Python reaches. :func:`check_global_heaps`
walks every collection the way the library does and refuses that one case with a one-line
:class:`~aeromag_env.errors.FlightFileError`. Every other damage is left to the library, which
raises on it.

Layout (HDF5 file format specification, version 3, "Global Heap"): a collection is the
signature ``GCOL``, a version byte (1), 3 reserved bytes and the collection's size (a length,
of the size the superblock gives: 8 bytes in files h5py and MATLAB write), then objects, each
a 2-byte heap index, a 2-byte reference count, 4 reserved bytes and its size (a length), its
data padded to 8 bytes; the free space is the object of index 0, its size counting its header.
The collections are found by their signature: a collection is not otherwise reachable without
following the attributes that point into it.
"""

from __future__ import annotations

import mmap
import struct
from pathlib import Path

from aeromag_env.flight.formats.common import damaged

SIGNATURE = b"\x89HDF\r\n\x1a\n"
COLLECTION = b"GCOL"
#: Where the superblock may start: 0, then 512 bytes doubling (behind a user block).
_FIRST_USER_BLOCK = 512
#: The byte of the superblock holding the size of lengths [bytes], by superblock version.
_SIZE_OF_LENGTHS_AT = {0: 14, 1: 14, 2: 10, 3: 10}
_LENGTH_FORMATS = {2: "H", 4: "I", 8: "Q"}


def check_global_heaps(path: Path, kind: str = "hdf5") -> None:
    """Refuse an HDF5 file with a global heap collection the library would loop on forever.

    Parameters
    ----------
    path : Path
    kind : str
        The format named in the message (``"hdf5"``, ``"mat73"``).

    Raises
    ------
    FlightFileError
        ``<path>: cannot read as HDF5: damaged or unreadable file (global heap … at byte N …)``.
    """
    with open(path, "rb") as fh, mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) as buf:
        length = _size_of_lengths(buf)
        if length is None:
            return  # no superblock found, or lengths of a size we do not walk: the library says
        at = buf.find(COLLECTION)
        while at >= 0:
            stuck = _stuck_object(buf, at, length)
            if stuck is not None:
                raise damaged(
                    path,
                    kind,
                    f"the global heap collection at byte {at} has a free-space object of size "
                    f"0 at byte {stuck}, which the HDF5 library would loop on forever",
                )
            at = buf.find(COLLECTION, at + 1)


def _size_of_lengths(buf: mmap.mmap) -> int | None:
    """The superblock's size of lengths [bytes], if it is one we walk."""
    at = 0
    while at + 16 <= len(buf):
        if buf[at : at + 8] == SIGNATURE:
            where = _SIZE_OF_LENGTHS_AT.get(buf[at + 8])
            size = buf[at + where] if where is not None else None
            return size if size in _LENGTH_FORMATS else None
        at = _FIRST_USER_BLOCK if at == 0 else 2 * at
    return None


def _stuck_object(buf: mmap.mmap, start: int, length: int) -> int | None:
    """The offset of a free-space object of size 0 in the collection at ``start``, walked as
    the library walks it, or None (another version, or nothing the walk would stop on)."""
    header = 8 + length  # signature, version, reserved, collection size
    if start + header > len(buf) or buf[start + 4] != 1:
        return None
    fmt = "<" + _LENGTH_FORMATS[length]
    (size,) = struct.unpack_from(fmt, buf, start + 8)
    end = min(start + size, len(buf))
    at, object_header = start + header, 8 + length  # index, references, reserved, size
    while at + object_header <= end:
        index = struct.unpack_from("<H", buf, at)[0]
        (object_size,) = struct.unpack_from(fmt, buf, at + 8)
        if index == 0 and object_size == 0:
            return at
        at += object_size if index == 0 else object_header + object_size + (-object_size % 8)
    return None
