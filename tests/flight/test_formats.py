"""Flight-file formats: Geosoft XYZ, MATLAB v5/v7.3, the SGL/MagNav HDF5 layouts, the aliases,
detection by content and ``aeromag convert``.

Every vendor file here is written by the test itself, by hand, in the layout the vendor
documents (no real data on this machine): the Geosoft XYZ columns of SGL's export
(MagNav.jl ``readmes/Data-readme.txt``), the SGL 2020/2021 HDF5 field lists
(``readmes/sgl_20*_fields_readme.txt``), MagNav.jl's first reader's names (``get_flight_data``)
and MATLAB's v7.3 layout (HDF5 behind a 512-byte header, vectors as (n, 1) or (1, n)).
"""

from __future__ import annotations

import hashlib
import itertools
import tempfile
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pytest
import scipy.io
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from aeromag_env.cli.main import main
from aeromag_env.errors import FlightFileError
from aeromag_env.flight import aliases
from aeromag_env.flight.aliases import apply_aliases, canonical_name
from aeromag_env.flight.data import Flight
from aeromag_env.flight.files import convert_flight, load_flight, write_flight
from tests._helpers import examples
from tests._synthetic_flights import turning_flight, with_fields
from tests.flight.test_flightfile import assert_bit_identical, assert_one_line_error

SUFFIXES = (".h5", ".csv", ".xyz", ".mat")
TEXT_SUFFIXES = (".csv", ".xyz")

# A Geosoft XYZ export as SGL delivers it: '/' header and remark lines (one in Latin-1), the
# column names on the last '/' line before the data, '//' remarks after it, Line/Tie records,
# '*' dummies, ragged blanks and a tab.
SGL_XYZ = (
    "/ ------------------------------------------\n"
    "/ XYZ EXPORT [03/20/2021]\n"
    "/ DATABASE [.\\Flt1002.gdb] Soci\xe9t\xe9\n"
    "/ ------------------------------------------\n"
    "/\n"
    "/      TIME       LAT        LONG    UTM-Z  UNCOMPMAG1  COMPMAG1  FLUXA_X   FLUXA_Y"
    "   FLUXA_Z  PITCH  ROLL  AZIMUTH   BARO  DIURNAL  CUR_COM1\n"
    "//Flight 1002\n"
    "//Date 2020/06/20\n"
    "Line 1002.01\n"
    " 45100.0  45.30  -75.70  400.0  52314.6  52300.1  10000.0  -2000.0  50000.0"
    "  1.0  2.0  90.0  380.0  5.0  0.5\n"
    " 45100.1  45.30  -75.70  400.1        *  52300.2  10001.0  -2001.0  50001.0"
    "  1.1  2.1  90.1  380.1    *\t0.5\n"
    "Tie 5\n"
    " 45100.2  45.31  -75.71  400.2  52314.8  52300.3  10002.0  -2002.0  50002.0"
    "  1.2  2.2  90.2  380.2  5.2  0.6\n"
    "LINE L1003:2\n"
    " 45100.3  45.31  -75.71  400.3  52314.9  52300.4  10003.0  -2003.0  50003.0"
    "  1.3  2.3  90.3  380.3  5.3  0.6\n"
).encode("latin-1")


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def renamed_note(notes: list[str]) -> str:
    """The warning line that lists the aliases applied (exactly one)."""
    lines = [n for n in notes if n.startswith("renamed by alias")]
    assert len(lines) == 1, notes
    return lines[0]


def write_mat73(path: Path, variables: dict[str, Any], struct: str | None = None) -> Path:
    """A MAT-file v7.3 as MATLAB writes it: HDF5 behind a 512-byte header, MATLAB_class
    attributes, character arrays as uint16, a ``#refs#`` group; optionally inside one struct."""
    with h5py.File(path, "w", userblock_size=512) as f:
        group = f.create_group(struct) if struct else f
        if struct:
            group.attrs["MATLAB_class"] = np.bytes_(b"struct")
        for name, value in variables.items():
            if isinstance(value, str):
                codes = np.array([[ord(c)] for c in value], dtype=np.uint16)
                group.create_dataset(name, data=codes).attrs["MATLAB_class"] = np.bytes_(b"char")
            else:
                group.create_dataset(name, data=value).attrs["MATLAB_class"] = np.bytes_(b"double")
        f.create_group("#refs#").create_dataset("a", data=np.zeros((2, 2)))
    text = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jun 22 10:00:00 2020 HDF5 "
    header = (text + b"schema 1.00 .").ljust(116) + b"\x00" * 8 + b"\x00\x02" + b"IM"
    with open(path, "r+b") as fh:
        fh.write(header)
    return path


def awkward_flight() -> Flight:
    """A flight whose every value and attribute is hard to carry: NaN, ±inf, −0.0, a subnormal,
    a line field with NaN runs and a tie line, unicode, ints, lists."""
    flight = turning_flight()
    flux = flight["flux_a_x"].copy()
    flux[[3, 4, 500]] = [np.nan, np.inf, -np.inf]
    cur = flight["cur_strb"].copy()
    cur[:3] = [-0.0, 5e-324, 0.1 + 0.2]
    line = np.repeat([1002.01, np.nan, 7.0, 1002.01], flight.n // 4)
    flight = with_fields(flight, flux_a_x=flux, cur_strb=cur, line=line)
    flight.attrs.update(
        {"source": "unit test ✓", "count": 3, "axes": [1, 2, 3], "tie_lines": [7.0]}
    )
    return flight


# --- Geosoft XYZ ------------------------------------------------------------------------------


def test_xyz_in_the_sgl_layout_reads_under_our_names(tmp_path: Path) -> None:
    path = tmp_path / "Flt1002.xyz"
    path.write_bytes(SGL_XYZ)
    flight, notes = load_flight(path, needs=("tt", "flux_a", "mag_1_uc", "attitude"))
    assert flight.names == [
        "tt",
        "lat",
        "lon",
        "utm_z",
        "mag_1_uc",
        "mag_1_c",
        "flux_a_x",
        "flux_a_y",
        "flux_a_z",
        "ins_pitch",
        "ins_roll",
        "ins_yaw",
        "baro",
        "diurnal",
        "cur_com_1",
        "line",
    ]
    np.testing.assert_array_equal(flight["tt"], [45100.0, 45100.1, 45100.2, 45100.3])
    assert np.isnan(flight["mag_1_uc"][1]) and np.isnan(flight["diurnal"][1])
    assert flight["mag_1_uc"][2] == 52314.8 and flight["cur_com_1"][1] == 0.5  # after the tab
    np.testing.assert_array_equal(flight["line"], [1002.01, 1002.01, 5.0, 1003.0])
    assert flight.attrs["tie_lines"] == [5.0]
    assert flight.attrs["aliases"]["mag_1_uc"] == "UNCOMPMAG1"
    assert flight.attrs["aliases"]["ins_yaw"] == "AZIMUTH"
    assert flight.attrs["aliases"]["utm_z"] == "UTM-Z"
    note = renamed_note(notes)
    assert "UNCOMPMAG1 → mag_1_uc" in note and "FLUXA_X → flux_a_x" in note
    assert "COMPMAG1 → mag_1_c" in note and "LONG → lon" in note


def test_xyz_line_column_agreeing_with_records_is_kept_alone(tmp_path: Path) -> None:
    head = "/ LINE TIME UNCOMPMAG1\n"
    agree = tmp_path / "agree.xyz"
    agree.write_text(head + "LINE 10\n10 0.0 5e4\n10 0.1 5e4\nTIE 11\n11 0.2 5e4\n")
    flight, notes = load_flight(agree)
    assert flight.names == ["line", "tt", "mag_1_uc"] and flight.attrs["tie_lines"] == [11.0]
    np.testing.assert_array_equal(flight["line"], [10, 10, 11])
    disagree = tmp_path / "disagree.xyz"
    disagree.write_text(head + "LINE 10\n10 0.0 5e4\n10 0.1 5e4\n12 0.2 5e4\n")
    flight, notes = load_flight(disagree)
    np.testing.assert_array_equal(flight["xyz_line_record"], [10, 10, 10])
    assert any("disagree with the LINE column at 1 of 3 rows" in n for n in notes)


def test_xyz_without_records_has_no_line_and_skips_text_columns(tmp_path: Path) -> None:
    path = tmp_path / "plain.xyz"
    path.write_text("/ tt DATE mag_1_uc\n0 2020/06/20 5e4\n1 2020/06/20 *\n")
    flight, notes = load_flight(path)
    assert flight.names == ["tt", "mag_1_uc"] and np.isnan(flight["mag_1_uc"][1])
    assert any("skipped non-numeric column(s): DATE" in n for n in notes)


def test_xyz_remarks_and_record_words_are_passed_over(tmp_path: Path) -> None:
    path = tmp_path / "remarks.xyz"
    path.write_text("/ @ SGL export\n/ tt x\nLine 3 (repeat line)\n0 1\n1 *\n")
    flight, notes = load_flight(path)
    assert flight.names == ["tt", "x", "line"] and flight.attrs == {}
    assert len(notes) == 1 and "non-finite" in notes[0]
    np.testing.assert_array_equal(flight["line"], [3.0, 3.0])


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("0 1\n1 2\n", ["neither CSV", "XYZ"]),  # whitespace table, no header: .txt suffix
        ("/ tt x\n0 1\n1 2 3\n", ["line 3 has 3 values", "names 2"]),
        ("/ tt x\nLINE abc\n0 1\n", ["line 2", "line id 'abc'"]),
        ("/ written 2020\n0 1\n", ["no '/' header line", "2 values"]),
        ("/ tt tt\n0 1\n", ["duplicate", "tt"]),
        ("/ @ [1, 2]\n/ tt\n0\n", ["/ @", "JSON object"]),
        ("/ tt x\n", ["no samples"]),
    ],
)
def test_bad_xyz_gives_one_line_errors(tmp_path: Path, text: str, words: list[str]) -> None:
    path = tmp_path / ("bad.txt" if "neither CSV" in words else "bad.xyz")
    path.write_text(text)
    with pytest.raises(FlightFileError) as exc:
        load_flight(path)
    assert_one_line_error(exc, str(path), *words)


def test_truncated_xyz_names_the_cut_row(tmp_path: Path) -> None:
    whole = write_flight(awkward_flight(), tmp_path / "whole.xyz").read_bytes()
    cut = tmp_path / "cut.xyz"
    cut.write_bytes(whole[: len(whole) // 2 + 7])
    with pytest.raises(FlightFileError) as exc:
        load_flight(cut)
    assert_one_line_error(exc, "values but the header names 14")


def test_xyz_writer_layout(tmp_path: Path) -> None:
    flight = awkward_flight()
    lines = write_flight(flight, tmp_path / "f.xyz").read_text(encoding="utf-8").splitlines()
    assert lines[0].startswith("/ ") and lines[1].startswith("/ @ {")
    assert lines[2] == "/ " + " ".join(flight.names)
    records = [ln for ln in lines if ln.startswith(("LINE", "TIE"))]
    assert records == ["LINE 1002.01", "LINE *", "TIE 7", "LINE 1002.01"]
    assert "*" in lines[4 + 3].split()  # the NaN fluxgate sample of row 3
    assert len(lines) == 3 + len(records) + flight.n


# --- MATLAB -----------------------------------------------------------------------------------


def test_mat5_single_struct_in_magnav_layout(tmp_path: Path) -> None:
    n = 5
    traj = {
        "tt": np.arange(n) / 10.0,
        "lat": np.full(n, 45.0),
        "lon": np.full(n, -75.0),
        "alt": np.full(n, 3000.0),
        "roll": np.linspace(0, 1, n),
        "pitch": np.zeros(n),
        "yaw": np.linspace(0, 90, n),
        "Cnb": np.zeros((3, 3, n)),
        "dt": 0.1,
    }
    path = tmp_path / "traj.mat"
    with open(path, "wb") as fh:
        scipy.io.savemat(
            fh, {"traj": {k: np.atleast_2d(v).T if np.ndim(v) == 1 else v for k, v in traj.items()}}
        )
    flight, notes = load_flight(path, needs=("position", "attitude"))
    assert flight.names == ["tt", "lat", "lon", "alt", "ins_roll", "ins_pitch", "ins_yaw"]
    np.testing.assert_array_equal(flight["ins_yaw"], traj["yaw"])
    assert flight.attrs["dt"] == 0.1 and flight.attrs["mat_struct"] == "traj"
    assert flight.attrs["aliases"] == {"ins_roll": "roll", "ins_pitch": "pitch", "ins_yaw": "yaw"}
    assert "yaw → ins_yaw" in renamed_note(notes)
    assert any("skipped" in n and "traj.Cnb" in n for n in notes)


def test_mat5_top_level_variables_and_char_attribute(tmp_path: Path) -> None:
    path = tmp_path / "flight.mat"
    with open(path, "wb") as fh:
        variables = {
            "tt": np.arange(4.0),
            "mag_1_uc": np.full(4, 5e4),
            "N": 4,
            "info": "Flt2001",
            "cells": np.array([1, "a"], dtype=object),
        }
        scipy.io.savemat(fh, variables)
    flight, notes = load_flight(path)
    assert flight.names == ["tt", "mag_1_uc"]
    assert flight.attrs == {"N": 4, "info": "Flt2001"}
    assert any("skipped" in n and "cells" in n for n in notes)


def test_mat73_written_with_h5py(tmp_path: Path) -> None:
    n = 6
    columns = {
        "tt": np.arange(n, dtype=float).reshape(n, 1),  # (n, 1)
        "utmZ": np.full((1, n), 400.0),  # (1, n), MagNav.jl's older name
        "mag_1_uc": np.linspace(5e4, 5.1e4, n).reshape(n, 1),
        "dt": np.array([[0.1]]),
        "info": "Flt1003",
    }
    for struct in (None, "xyz"):
        path = write_mat73(tmp_path / f"v73_{struct}.mat", columns, struct)
        flight, notes = load_flight(path)
        assert flight.names == ["mag_1_uc", "tt", "utm_z"]  # HDF5 lists names alphabetically
        np.testing.assert_array_equal(flight["utm_z"], np.full(n, 400.0))
        assert flight.attrs["dt"] == 0.1 and flight.attrs["info"] == "Flt1003"
        assert flight.attrs["aliases"] == {"utm_z": "utmZ"} and "utmZ → utm_z" in notes[0]
        assert not any("#refs#" in note for note in notes)
        assert flight.attrs.get("mat_struct") == struct


@settings(max_examples=examples(25), deadline=None)
@given(values=hnp.arrays(np.float64, st.integers(1, 30)))
def test_mat5_round_trip_keeps_every_bit(values: np.ndarray) -> None:
    flight = Flight({"tt": np.arange(values.size, dtype=float), "value": values}, {"k": [1, 2]})
    with tempfile.TemporaryDirectory() as folder:
        back, _ = load_flight(write_flight(flight, Path(folder) / "f.mat"))
    assert_bit_identical(flight, back)
    assert back.attrs == flight.attrs


@settings(max_examples=examples(40), deadline=None)
@given(
    values=hnp.arrays(
        np.float64, st.integers(1, 30), elements=st.floats(allow_nan=True, allow_infinity=True)
    ),
    line=hnp.arrays(np.float64, 30, elements=st.sampled_from([1.0, 2.5, np.nan])),
)
def test_xyz_round_trip_arbitrary_floats_and_lines(values: np.ndarray, line: np.ndarray) -> None:
    n = values.size
    flight = Flight({"tt": np.arange(n, dtype=float), "value": values, "line": line[:n]})
    with tempfile.TemporaryDirectory() as folder:
        back, notes = load_flight(write_flight(flight, Path(folder) / "f.xyz"))
    assert_bit_identical(flight, back, nan_payload=False)
    assert not any("disagree" in note for note in notes)


# --- HDF5: SGL 2021 and MagNav.jl's older names -------------------------------------------------


def test_h5_sgl_2021_layout_with_column_datasets(tmp_path: Path) -> None:
    n = 8
    path = tmp_path / "Flt2001_train.h5"
    with h5py.File(path, "w") as f:
        f["tt"] = (69396.0 + np.arange(n) / 10.0).reshape(n, 1)  # (n, 1) datasets
        f["mag_1_uc"] = np.full((1, n), 5.2e4)  # (1, n)
        f["flux_d_x"] = np.arange(n, dtype=np.float32)
        f["N"] = n  # scalars as 0-D datasets
        f["dt"] = np.array([[0.1]])  # and as a (1, 1) dataset
        f["info"] = b"Flt2001"
    flight, notes = load_flight(path)
    assert flight.names == ["flux_d_x", "mag_1_uc", "tt"] and flight.n == n
    assert flight.attrs == {"N": n, "dt": 0.1, "info": "Flt2001"}
    assert "aliases" not in flight.attrs and not notes  # the 2021 names are the 2020 ones


def test_h5_magnav_older_names_and_a_clash(tmp_path: Path) -> None:
    n = 5
    path = tmp_path / "old.h5"
    with h5py.File(path, "w") as f:
        for name in ("tt", "tie_line", "utmZ", "ins_azim", "ins_yaw", "pitch_rt", "vol_servo"):
            f[name] = np.arange(n, dtype=float) + len(name)
    flight, notes = load_flight(path)
    assert flight.names == ["ins_azim", "ins_yaw", "pitch_rate", "line", "tt", "utm_z", "vol_srvo"]
    assert flight.attrs["aliases"] == {
        "pitch_rate": "pitch_rt",
        "line": "tie_line",
        "utm_z": "utmZ",
        "vol_srvo": "vol_servo",
    }
    np.testing.assert_array_equal(flight["ins_yaw"], np.arange(n) + 7.0)  # canonical kept
    assert any("both ins_yaw and its alias ins_azim present" in n for n in notes)


# --- aliases ----------------------------------------------------------------------------------


def test_alias_table_is_consistent() -> None:
    for name in (*aliases.SGL_2020_FIELDS, *aliases.EXTRA_FIELDS, "truth_interf_x", "cur_x"):
        assert canonical_name(name) == name, name  # ours are never renamed
    for row in aliases.ALIASES:
        original = row.original.replace("<n>", "3").replace("<s>", "B")
        expected = row.canonical.replace("<n>", "3").replace("<s>", "b")
        assert canonical_name(original) == expected, row
        assert aliases.is_canonical(expected), row  # every target is one of our names
    table = aliases.alias_table_markdown().splitlines()
    assert len(table) == 2 + len(aliases.ALIASES) + 1


@pytest.mark.parametrize(
    ("original", "canonical"),
    [
        ("TT", "tt"),
        ("Lat", "lat"),
        ("UNCOMPMAG12", "mag_12_uc"),
        ("FluxC_Tot", "flux_c_t"),
        ("V_RESn", "vol_res_n"),
        ("utmz", "utm_z"),
        ("unknown_channel", "unknown_channel"),
    ],
)
def test_alias_matching_ignores_case(original: str, canonical: str) -> None:
    assert canonical_name(original) == canonical


def test_two_aliases_of_one_name_keep_the_first_and_warn() -> None:
    fields = {"AZIMUTH": np.zeros(2), "ins_azim": np.ones(2)}
    out, attrs, notes = apply_aliases(fields, {"aliases": {"tt": "TIME"}})
    assert list(out) == ["ins_yaw", "ins_azim"] and attrs["aliases"]["ins_yaw"] == "AZIMUTH"
    assert attrs["aliases"]["tt"] == "TIME"  # an earlier renaming is kept
    assert any("AZIMUTH and ins_azim are both aliases of ins_yaw" in n for n in notes)


def test_csv_with_upper_case_names(tmp_path: Path) -> None:
    path = tmp_path / "upper.csv"
    path.write_text("TIME,LAT,LONG,UTM-Z\n0,45,-75,400\n1,45,-75,401\n")
    flight, notes = load_flight(path, needs=("position",))
    assert flight.names == ["tt", "lat", "lon", "utm_z"] and "TIME → tt" in notes[0]


# --- detection by content ---------------------------------------------------------------------


@pytest.mark.parametrize(
    ("written", "named"),
    [
        (".h5", ".csv"),
        (".csv", ".xyz"),
        (".xyz", ".csv"),
        (".mat", ".h5"),
        (".csv", ".dat"),
        (".h5", ""),
    ],
)
def test_format_is_found_from_the_content(tmp_path: Path, written: str, named: str) -> None:
    flight = awkward_flight()
    path = write_flight(flight, tmp_path / f"f{written}").rename(tmp_path / f"misnamed{named}")
    back, notes = load_flight(path)
    assert_bit_identical(flight, back, nan_payload=written not in TEXT_SUFFIXES)
    said = [n for n in notes if "as the suffix says" in n]
    assert len(said) == (1 if named in SUFFIXES else 0), notes


def test_mat73_named_h5_reads_as_mat(tmp_path: Path) -> None:
    path = write_mat73(tmp_path / "f.h5", {"tt": np.arange(3.0).reshape(3, 1)})
    flight, notes = load_flight(path)
    assert flight.names == ["tt"] and "content is MAT v7.3, not HDF5" in notes[0]


@pytest.mark.parametrize(
    ("make", "suffix", "words"),
    [
        (lambda good: good[: len(good) // 2], ".mat", ["cannot read as MAT v5"]),
        (lambda good: b"MATLAB 5.0 MAT-file" + b"\x00" * 200, ".mat", ["cannot read as MAT v5"]),
        (lambda good: b"\x89PNG\r\n\x1a\n" + b"\x00" * 64, ".mat", ["unknown content"]),
        (lambda good: b"", ".xyz", ["empty"]),
        (lambda good: b"", ".mat", ["empty"]),
    ],
)
def test_bad_mat_and_empty_files_give_one_line_errors(
    tmp_path: Path, make: Any, suffix: str, words: list[str]
) -> None:
    good = write_flight(awkward_flight(), tmp_path / "good.mat").read_bytes()
    path = tmp_path / f"bad{suffix}"
    path.write_bytes(make(good))
    with pytest.raises(FlightFileError) as exc:
        load_flight(path)
    assert_one_line_error(exc, str(path), *words)


@pytest.mark.parametrize("keep", [2000, 300])  # inside the data; inside the MATLAB header
def test_truncated_mat73_gives_one_line_error(tmp_path: Path, keep: int) -> None:
    good = write_mat73(tmp_path / "good.mat", {"tt": np.arange(5000.0).reshape(-1, 1)})
    cut = tmp_path / "cut.mat"
    cut.write_bytes(good.read_bytes()[:keep])
    with pytest.raises(FlightFileError) as exc:
        load_flight(cut)
    assert_one_line_error(exc, "cannot read as MAT v7.3")


@pytest.mark.parametrize(
    ("name", "suffix", "words"),
    [
        ("UTM-Z", ".mat", ["MAT", "UTM-Z"]),
        ("two words", ".xyz", ["XYZ", "two words"]),
        ("aeromag_attrs", ".mat", ["aeromag_attrs"]),
    ],
)
def test_writers_refuse_names_their_format_cannot_hold(
    tmp_path: Path, name: str, suffix: str, words: list[str]
) -> None:
    flight = Flight({"tt": np.arange(3.0), name: np.zeros(3)})
    with pytest.raises(FlightFileError) as exc:
        write_flight(flight, tmp_path / f"f{suffix}")
    assert_one_line_error(exc, "invalid field name", *words)
    assert list(tmp_path.iterdir()) == []


# --- aeromag convert --------------------------------------------------------------------------


@pytest.mark.parametrize(("src", "dst"), list(itertools.product(SUFFIXES, SUFFIXES)))
def test_convert_round_trips_between_every_pair(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], src: str, dst: str
) -> None:
    flight = awkward_flight()
    source = write_flight(flight, tmp_path / f"in{src}")
    before = sha256(source)
    target = tmp_path / f"out{dst}"
    assert main(["convert", str(source), str(target)]) == 0
    out = capsys.readouterr()
    assert out.out.strip() == f"wrote {target}: {flight.n} samples, {len(flight.names)} fields"
    assert "non-finite" in out.err and "Traceback" not in out.err
    back, _ = load_flight(target)
    assert_bit_identical(flight, back, nan_payload=not {src, dst} & set(TEXT_SUFFIXES))
    assert back.attrs == flight.attrs
    assert sha256(source) == before


def test_convert_from_vendor_xyz_keeps_the_originals_recorded(tmp_path: Path) -> None:
    source = tmp_path / "Flt1002.xyz"
    source.write_bytes(SGL_XYZ)
    flight, notes = convert_flight(source, tmp_path / "Flt1002.h5")
    assert renamed_note(notes).startswith("renamed by alias")
    back, back_notes = load_flight(tmp_path / "Flt1002.h5")
    assert back.names == flight.names and back.attrs["aliases"] == flight.attrs["aliases"]
    assert not any(n.startswith("renamed") for n in back_notes)  # already our names


@pytest.mark.parametrize(
    ("out_name", "words"),
    [
        ("in.h5", ["is the input file"]),
        ("out.txt", ["unsupported output type '.txt'"]),
        ("missing/../in.h5", ["is the input file"]),
    ],
)
def test_convert_refuses_to_overwrite_or_guess(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], out_name: str, words: list[str]
) -> None:
    source = write_flight(turning_flight(), tmp_path / "in.h5")
    before = sha256(source)
    assert main(["convert", str(source), str(tmp_path / out_name)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("aeromag convert: error:") and "\n" not in err
    assert all(w in err for w in words), err
    assert sha256(source) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.h5"]


def test_convert_of_an_unreadable_file_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    source = tmp_path / "junk.xyz"
    source.write_bytes(b"\x00\x01\x02")
    assert main(["convert", str(source), str(tmp_path / "out.h5")]) == 2
    err = capsys.readouterr().err.strip()
    assert "unknown content" in err and "\n" not in err
    assert not (tmp_path / "out.h5").exists()
