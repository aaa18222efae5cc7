"""Damaged flight files of every format: read, or refused in one line with exit 2; never an
internal error, a traceback or a crash.

Each reader gets a clean file of its format, written here the way other programs write it
(plain h5py with old-style groups, ``libver="earliest"``, and with new-style ones; our writer;
a CSV and a Geosoft XYZ file; MATLAB v5 as scipy writes it, plain and compressed; v7.3 as
MATLAB lays it out), then damaged at fixed offsets: two bytes overwritten (``00 03``, the
bytes of the HDF5 case that made h5py raise RuntimeError, and ``ff ff``), a 64-byte block
zeroed, the file cut short. The offsets are the structure areas, where the damage reaches
the reader rather than a sample's value: a stride over the first 2 KiB (HDF5's superblock,
root group, B-tree, local heap and first symbol-table node; MATLAB's header and first tags;
the text formats' attribute and header lines), every HDF5 signature (``TREE``, ``HEAP``,
``SNOD``, ``OHDR``…) and the fields after it, every MAT v5 variable's tags, and a fixed-seed
sample of the whole file. The library answers through :func:`load_flight`; a refusal per
reader and damage kind goes through ``aeromag info``, ``compensate`` and ``convert`` and the
fault suite's checker (:mod:`tests.faults.suite`). A wider scan of the fault suite's full-size
files is marked slow.
"""

from __future__ import annotations

import contextlib
import faulthandler
import re
import struct
import tempfile
import warnings
import zlib
from collections.abc import Callable, Iterator
from functools import cache, partial
from pathlib import Path

import h5py
import numpy as np
import pytest
import scipy.io

from aeromag_env.errors import FlightFileError
from aeromag_env.flight.data import Flight
from aeromag_env.flight.files import load_flight, write_flight
from aeromag_env.flight.formats.mat5_check import DATA_TYPES
from tests._helpers import assert_one_line_error
from tests.faults.cases import Case, base, setup, write
from tests.faults.suite import run_case
from tests.flight.test_formats import write_mat73

#: The channels of the small clean flight (what ``compensate --method tl`` needs), its length
#: [samples] and attributes: a small file, so that its structures fill most of it.
CHANNELS = ("tt", "flux_a_x", "flux_a_y", "flux_a_z", "mag_1_uc")
SAMPLES, ATTRIBUTES = 64, ("date",)
#: Each clean file's writer: (suffix, write(path, fields, attrs)).
Writer = Callable[[Path, dict[str, np.ndarray], dict[str, object]], None]
#: Where the structure of every format sits in a small file [bytes], and the stride over it.
HEAD_BYTES, STRIDE = 2048, 64
#: Offsets drawn over the whole file, from a fixed seed.
SAMPLED, SEED = 8, 49
#: HDF5's signatures of its structures (superblock, B-trees v1 and v2, local and fractal
#: heaps, symbol-table nodes, object headers v2, free-space managers, shared messages) and the
#: offsets after each where its version, type, sizes and addresses sit [bytes].
H5_SIGNATURES = (b"\x89HDF", b"TREE", b"HEAP", b"SNOD", b"OHDR", b"OCHK", b"FRHP", b"FHDB")
H5_SIGNATURES += (b"FHIB", b"BTHD", b"BTIN", b"BTLF", b"FSHD", b"FSSE", b"SMTB", b"SMLI")
AFTER_SIGNATURE = (0, 5, 8, 16, 24, 40)
#: After a MAT v5 variable's tag: its size, the array flags, dimensions, name and data tags
#: [bytes].
AFTER_TAG = (0, 4, 8, 16, 24, 40, 48)
#: A read that takes longer ends the test process with the stack where it hangs: an endless
#: loop inside a library's C code is out of reach of any Python time limit [s].
HANG_S = 120.0
#: Damage: two bytes overwritten, a block zeroed; a file cut short at the same offsets.
OVERWRITES = {"bytes_00_03": b"\x00\x03", "bytes_ff_ff": b"\xff\xff", "zeroed_64": bytes(64)}


def _h5py_writer(libver: str) -> Writer:
    def write_h5(path: Path, fields: dict, attrs: dict) -> None:
        with h5py.File(path, "w", libver=libver) as f:
            for name, values in fields.items():
                f[name] = values
            f.attrs.update({k: str(v) for k, v in attrs.items()})

    return write_h5


def _ours(path: Path, fields: dict, attrs: dict) -> None:
    write_flight(Flight(dict(fields), dict(attrs)), path)


def _suite_writer(path: Path, fields: dict, attrs: dict) -> None:
    write(path, list(fields.items()), attrs)


def _mat73(path: Path, fields: dict, attrs: dict) -> None:
    write_mat73(path, {k: v.reshape(-1, 1) for k, v in fields.items()})


READERS: dict[str, tuple[str, Writer]] = {
    "hdf5_old_style_groups": (".h5", _h5py_writer("earliest")),
    "hdf5_new_style_groups": (".h5", _h5py_writer("latest")),
    "hdf5_our_writer": (".h5", _ours),
    "csv": (".csv", _suite_writer),
    "xyz": (".xyz", _suite_writer),
    "mat5": (".mat", _suite_writer),
    "mat5_compressed": (".mat", _ours),
    "mat73": (".mat", _mat73),
}


@cache
def clean(reader: str, samples: int | None = SAMPLES) -> bytes:
    """The clean file of ``reader`` (:data:`READERS`): the fault suite's 120-s flight, its
    :data:`CHANNELS` cut to ``samples`` and its :data:`ATTRIBUTES` (None: every channel, sample
    and attribute, as the suite has them)."""
    fields, attrs = base(120.0)
    if samples is not None:
        fields = {name: fields[name][:samples] for name in CHANNELS}
        attrs = {name: attrs[name] for name in ATTRIBUTES}
    suffix, writer = READERS[reader]
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp, "clean" + suffix)
        writer(path, fields, attrs)
        return path.read_bytes()


def _anchors(data: bytes) -> set[int]:
    """The offsets of the format's own structures: after every HDF5 signature, after every
    MAT v5 variable's tag (walked from byte 128, little-endian as scipy writes)."""
    found = {
        m.start() + d
        for sig in H5_SIGNATURES
        for m in re.finditer(re.escape(sig), data)
        for d in AFTER_SIGNATURE
    }
    if data.startswith(b"MATLAB 5.0"):
        at = 128
        while at + 8 <= len(data):
            found |= {at + d for d in AFTER_TAG}
            at += 8 + struct.unpack_from("<I", data, at + 4)[0]
    return found


def offsets(data: bytes, head: int = HEAD_BYTES, stride: int = STRIDE, sampled: int = SAMPLED):
    """The damaged offsets of a file: a stride over its head, its structures' anchors, and
    ``sampled`` offsets drawn from a fixed seed."""
    drawn = np.random.default_rng(SEED).integers(0, len(data), sampled).tolist()
    chosen = set(range(0, min(head, len(data)), stride)) | _anchors(data) | set(drawn)
    return sorted(k for k in chosen if k < len(data))


def damaged(data: bytes, at: list[int]) -> list[tuple[str, int, bytes]]:
    """(kind, offset, bytes) of every damage of :data:`OVERWRITES` at ``at``, and of the file
    cut at every other one of them."""
    found = [
        (kind, k, data[:k] + new + data[k + len(new) :])
        for kind, new in OVERWRITES.items()
        for k in at
    ]
    return found + [("cut", k, data[:k]) for k in at[1::2]]


@contextlib.contextmanager
def hang_guard() -> Iterator[None]:
    """Stop the process with a traceback after :data:`HANG_S` (a hang fails, loudly)."""
    faulthandler.dump_traceback_later(HANG_S, exit=True)
    try:
        yield
    finally:
        faulthandler.cancel_dump_traceback_later()


def answers(suffix: str, variants: list[tuple[str, int, bytes]]) -> tuple[list[str], dict]:
    """Each damaged file through :func:`load_flight`: what is neither read nor refused with a
    one-line :class:`FlightFileError` naming the file, and the first refused file per kind."""
    wrong, refused = [], {}
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp, "damaged" + suffix)
        for kind, at, data in variants:
            path.write_bytes(data)
            try:
                with warnings.catch_warnings(), hang_guard():
                    warnings.simplefilter("ignore", UserWarning)  # the reader's notes
                    load_flight(path)
            except FlightFileError as exc:
                assert_one_line_error(exc, str(path))
                refused.setdefault(kind, data)
            except Exception as exc:  # the test's point: nothing else may escape
                wrong.append(f"{kind} at byte {at}: {type(exc).__name__}: {exc}")
    return wrong, refused


COMMANDS = {
    "info": ("info", "@/IN"),
    "compensate": ("compensate", "@/IN", "--method", "tl", "--out", "@/out"),
    "convert": ("convert", "@/IN", "@/out.h5"),
}


def _through_the_commands(suffix: str, kind: str, data: bytes, tmp_path: Path) -> list[str]:
    """The fault suite's checker on ``aeromag info``, ``compensate`` and ``convert`` of a
    refused file: exit 2, one ``aeromag … error:`` line, nothing written."""
    failures = []
    for command, argv in COMMANDS.items():
        argv = tuple(a.replace("IN", "in" + suffix) for a in argv)
        make = partial(setup, ops=(f"data:in{suffix}",), make=lambda: data)
        case = Case("damaged", f"{kind}/{command}", argv, make, "refused")
        result = run_case(case, tmp_path / command)
        failures += [f"{case.name}: {k}: {d}" for k, d in result.failures]
    return failures


@pytest.mark.parametrize("reader", READERS)
def test_a_damaged_file_is_read_or_refused_in_one_line(reader: str, tmp_path: Path) -> None:
    suffix, data = READERS[reader][0], clean(reader)
    variants = damaged(data, offsets(data))
    wrong, refused = answers(suffix, variants)
    assert not wrong, f"{len(wrong)} of {len(variants)} damaged files:\n" + "\n".join(wrong)
    assert set(refused) == {*OVERWRITES, "cut"}  # every kind of damage reached the reader
    failures = _through_the_commands(suffix, "bytes_00_03", refused["bytes_00_03"], tmp_path)
    assert not failures, "\n".join(failures)


@pytest.mark.slow
@pytest.mark.parametrize("reader", READERS)
def test_a_wide_scan_of_full_size_damaged_files(reader: str) -> None:
    """The fault suite's full-size flight (every channel and attribute, 1200 samples)
    damaged every 32 bytes over its first 8 KiB, at every anchor and at 128 drawn offsets
    (about 2000 files a reader, a minute or two each)."""
    suffix, data = READERS[reader][0], clean(reader, samples=None)
    variants = damaged(data, offsets(data, head=8192, stride=32, sampled=128))
    wrong, _ = answers(suffix, variants)
    assert not wrong, f"{len(wrong)} of {len(variants)} damaged files:\n" + "\n".join(wrong)


# ---------------------------------------------------------------------------------------------
# What the scan found, one case each


def test_the_old_style_group_case_of_the_fault_suite_is_refused_in_one_line(tmp_path) -> None:
    """Two bytes of the root group's symbol-table entry in the fault suite's HDF5 file
    (offset 1175): h5py raised RuntimeError "unknown symbol table entry cache type". The
    library's doors answer with the one-line error, as the commands do (exit 2)."""
    import aeromag_env
    from tests.faults.cases import clean_bytes

    data = clean_bytes("h5")
    path = tmp_path / "in.h5"
    path.write_bytes(data[:1175] + b"\x00\x03" + data[1177:])
    for read in (aeromag_env.read_flight, partial(aeromag_env.compensate, out=tmp_path / "out")):
        with pytest.raises(FlightFileError) as exc:
            read(path)
        assert_one_line_error(
            exc, str(path), "cannot read as HDF5: damaged or unreadable file", "symbol table"
        )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.h5"]  # nothing written


def _mat5_with_data_type(code: int, compressed: bool, tmp_path: Path) -> Path:
    """A MAT v5 file of one double vector whose data element claims type ``code``."""
    path = tmp_path / f"code{code}.mat"
    scipy.io.savemat(path, {"tt": np.arange(4.0).reshape(-1, 1)}, do_compression=compressed)
    data = bytearray(path.read_bytes())
    if not compressed:  # tag 128, flags 136, dims 152, name 168 (small element), data tag 176
        struct.pack_into("<I", data, 176, code)
        path.write_bytes(bytes(data))
        return path
    size = struct.unpack_from("<I", data, 132)[0]
    inner = bytearray(zlib.decompress(bytes(data[136 : 136 + size])))
    struct.pack_into("<I", inner, 48, code)  # the same layout, 128 bytes earlier
    packed = zlib.compress(bytes(inner))
    path.write_bytes(bytes(data[:128]) + struct.pack("<II", 15, len(packed)) + packed)
    return path


#: Type codes scipy's table has no type for (0, 8, 10, 11, 14, 15, 19, past its 20 slots):
#: its reader followed them into a crash of the process (a segmentation fault).
CRASHING_CODES = (0, 8, 10, 11, 14, 15, 19, 20, 255, 65535)


@pytest.mark.parametrize("compressed", [False, True], ids=["plain", "compressed"])
def test_a_mat5_type_code_that_would_crash_scipy_is_refused(tmp_path, compressed) -> None:
    for code in CRASHING_CODES:
        path = _mat5_with_data_type(code, compressed, tmp_path)
        with pytest.raises(FlightFileError) as exc:
            load_flight(path)
        assert_one_line_error(exc, str(path), "cannot read as MAT v5", f"type code {code},")


@pytest.mark.parametrize("compressed", [False, True], ids=["plain", "compressed"])
def test_mat5_data_stored_in_a_smaller_type_still_reads(tmp_path, compressed) -> None:
    """MATLAB stores a double array of small integers as miUINT8 (2) or miINT16 (3) data:
    every code with a type in scipy's table passes the check (the values then differ)."""
    assert {1, 2, 3, 4, 5, 6, 7, 9, 12, 13, 16, 17, 18} == DATA_TYPES
    for code in (2, 3, 9):
        path = _mat5_with_data_type(code, compressed, tmp_path)
        try:
            load_flight(path)
        except FlightFileError as exc:  # scipy's own refusal (the sizes no longer fit)
            assert "type code" not in str(exc)


@pytest.mark.parametrize("suffix", [".h5", ".mat"])
def test_an_hdf5_global_heap_the_library_would_loop_on_is_refused(tmp_path, suffix) -> None:
    """The free space of the collection holding a string attribute the reader reads (a file
    attribute; a MATLAB class stored as a variable-length string) given size 0: HDF5 took it
    as a step of 0 bytes and never returned (HDF5 and MAT v7.3 alike)."""
    path = tmp_path / f"in{suffix}"
    if suffix == ".mat":
        write_mat73(path, {"tt": np.arange(5.0).reshape(-1, 1)})
        with h5py.File(path, "a") as f:
            f["tt"].attrs["MATLAB_class"] = "double"  # kept in a global heap
    else:
        write_flight(Flight({"tt": np.arange(5.0)}, {"note": "kept in a global heap"}), path)
    data = bytearray(path.read_bytes())
    at = data.index(b"GCOL") + 16  # the collection's header: signature, version, size
    while struct.unpack_from("<H", data, at)[0] != 0:  # to the free-space object
        at += 16 + -(-struct.unpack_from("<Q", data, at + 8)[0] // 8) * 8
    struct.pack_into("<Q", data, at + 8, 0)
    path.write_bytes(bytes(data))
    with pytest.raises(FlightFileError) as exc, hang_guard():
        load_flight(path)
    assert_one_line_error(exc, str(path), "global heap", f"size 0 at byte {at}")


def test_a_csv_quote_left_open_is_refused_in_one_line(tmp_path) -> None:
    """A ``"`` at a cell's start swallows the rest of the file into one cell: Python's csv
    module raised its own Error beyond 131 072 characters."""
    from tests.faults.cases import clean_bytes

    data = clean_bytes("csv")
    at = data.index(b",", 5000) + 1
    path = tmp_path / "in.csv"
    path.write_bytes(data[:at] + b'"' + data[at + 1 :])
    with pytest.raises(FlightFileError) as exc:
        load_flight(path)
    assert_one_line_error(exc, str(path), "cannot read as CSV", "field limit")


def test_an_hdf5_item_that_cannot_be_opened_is_skipped_by_name(tmp_path) -> None:
    """A link to nothing (as a damaged object header also gives): the item is skipped with a
    note naming it, and a needed field among such items is missing by name."""
    path = write_flight(Flight({"tt": np.arange(5.0), "lat": np.full(5, 45.0)}), tmp_path / "a.h5")
    with h5py.File(path, "a") as f:
        f["flux_a_x"] = h5py.SoftLink("/nowhere")
    _, notes = load_flight(path)
    assert "skipped item(s) that cannot be opened (a link to nothing, or damaged): flux_a_x" in (
        notes
    )
    with pytest.raises(FlightFileError) as exc:
        load_flight(path, needs=("tt", "flux_a"))
    assert_one_line_error(exc, "flux_a_x")
