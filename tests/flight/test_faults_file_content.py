"""Bad content in a readable flight file (issue 20, fault suite items C, G, H, I, J): a date the
Earth-field model cannot use, boolean datasets, latitude and longitude in radians, ±inf attitude
samples, an all-NaN position channel.

The flights are a 120-s simulated calibration (nominal preset) with one fault injected, written
here; the independent truths are the fault's definition (a two-digit year is 26, a boolean is
not a measurement), ppigrf's coefficient file (IGRF-14's dates) and the same computation on the
finite samples alone (±inf attitude).
"""

from __future__ import annotations

import datetime as dt
import warnings
from pathlib import Path

import h5py
import numpy as np
import pytest
import scipy.io

from aeromag_env.cli.main import main
from aeromag_env.flight.data import Flight
from aeromag_env.flight.earth_model import MODEL_MISMATCH_FRACTION, model_mismatch
from aeromag_env.flight.files import load_flight, write_flight
from aeromag_env.flight.info import describe
from aeromag_env.geo.earth import IGRF_FIRST_DATE, IGRF_LAST_DATE, ModelDateError
from aeromag_env.geo.frames import dcm_from_euler
from aeromag_env.jobs.provenance import choose_inputs
from tests._flights import simulated

#: What every message about IGRF-14's range names.
VALID_YEARS = "IGRF-14's valid years 1900–2030"


def _short(preset_name: str = "nominal", seed: int = 0) -> Flight:
    """A fresh copy of a 120-s simulated calibration flight (fields and attributes)."""
    f = simulated(preset_name, seed, trajectory__duration_s=120.0)
    return Flight({k: v.copy() for k, v in f.fields.items()}, dict(f.attrs))


def _changed(path: Path, **fields: np.ndarray) -> Path:
    """The short flight with ``fields`` replaced and no ``date`` attribute (the date then
    comes from ``year`` and ``doy``), written to ``path``."""
    f = _short()
    f.fields.update(fields)
    del f.attrs["date"]
    return write_flight(f, path)


def _run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    """``aeromag ARGV``: exit status, stdout, and stderr with the Python warnings it raised."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err + "".join(f"{w.category.__name__}: {w.message}\n" for w in caught)


def _compensate(path: Path, method: str, capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    code, _, err = _run(
        ["compensate", str(path), "--method", method, "--out", str(path.parent / f"out_{method}")],
        capsys,
    )
    return code, err


# ---------------------------------------------------------------------------------------------
# C. A date outside IGRF-14's years, a NaN year


def test_igrf_dates_are_those_of_the_coefficient_file() -> None:
    from ppigrf.ppigrf import read_shc

    g, _ = read_shc()
    assert (g.index[0], g.index[-1]) == (IGRF_FIRST_DATE, IGRF_LAST_DATE)


def test_a_two_digit_year_names_the_field_the_value_and_igrf_years() -> None:
    f = Flight({"tt": np.arange(3.0), "year": np.full(3, 26.0), "doy": np.full(3, 152.0)})
    with pytest.raises(ModelDateError, match="year 26, doy 152") as info:
        f.date()
    assert VALID_YEARS in str(info.value) and "0026-06-01" in str(info.value)


def test_a_date_attribute_beyond_igrf_is_refused_by_name() -> None:
    f = Flight({"tt": np.arange(3.0)}, {"date": "2031-03-01"})
    with pytest.raises(ModelDateError, match=r"date attribute '2031-03-01'.*1900–2030"):
        f.date()


def test_a_nan_year_is_an_unreadable_date_naming_the_field() -> None:
    f = Flight({"tt": np.arange(3.0), "year": np.full(3, np.nan), "doy": np.full(3, 152.0)})
    with pytest.raises(ValueError, match="year nan, doy 152 at the first sample: not a date"):
        f.date()


@pytest.mark.parametrize("method", ["lsq", "kf"])
def test_methods_needing_igrf_refuse_a_two_digit_year_in_one_line(tmp_path, capsys, method):
    path = _changed(tmp_path / "in.h5", year=_short()["year"] - 2000.0)
    code, err = _compensate(path, method, capsys)
    assert code == 2
    assert err.count("\n") == 1 and "error: " in err and "Warning" not in err
    assert "year 26" in err and VALID_YEARS in err


@pytest.mark.parametrize("year", ["two_digits", "all_nan"])
def test_tl_runs_with_a_date_igrf_cannot_use(tmp_path, capsys, year):
    """tl never evaluates the Earth-field model for its fit: the date is only reported."""
    years = _short()["year"]
    bad = years - 2000.0 if year == "two_digits" else np.full_like(years, np.nan)
    path = _changed(tmp_path / "in.h5", year=bad)
    code, err = _compensate(path, "tl", capsys)
    assert code == 0, err
    assert "Warning" not in err  # no Python warning (IGRF's date warning) on stderr


def test_info_lists_a_two_digit_year_as_a_problem_not_a_python_warning(tmp_path, capsys):
    path = _changed(tmp_path / "in.h5", year=_short()["year"] - 2000.0)
    code, out, err = _run(["info", str(path)], capsys)
    assert code == 0 and err == ""
    report = describe(path)
    assert report.usable
    assert [p for p in report.problems if p.startswith("unusable date") and VALID_YEARS in p]
    assert "date: unusable (see problems)" in out


# ---------------------------------------------------------------------------------------------
# G. Boolean datasets


def _write_h5(path: Path, f: Flight) -> Path:
    with h5py.File(path, "w") as h5:
        for name, values in f.fields.items():
            h5[name] = values
        h5["flag"] = np.array(True)  # a 0-D boolean: an attribute, as before
        h5.attrs.update({k: str(v) for k, v in f.attrs.items()})
    return path


def _with_bool(name: str) -> Flight:
    f = _short()
    f.fields[name] = f[name] > np.median(f[name])  # type: ignore[assignment]
    return f


@pytest.mark.parametrize("name", ["lat", "ins_roll", "flux_a_x"])
def test_a_boolean_hdf5_dataset_is_skipped_with_a_note(tmp_path, name):
    flight, problems = load_flight(_write_h5(tmp_path / "in.h5", _with_bool(name)))
    assert name not in flight and flight.attrs["flag"] is True
    assert f"skipped boolean (true/false) item(s), not numbers: {name}" in problems


@pytest.mark.parametrize("name", ["lat", "ins_roll", "flux_a_x"])
def test_a_matlab_logical_is_skipped_with_a_note(tmp_path, name):
    f = _with_bool(name)
    path = tmp_path / "in.mat"
    scipy.io.savemat(path, {k: v.reshape(-1, 1) for k, v in f.fields.items()})
    flight, problems = load_flight(path)
    assert name not in flight and "tt" in flight
    assert f"skipped boolean (true/false) item(s), not numbers: {name}" in problems


def test_a_logical_in_a_struct_is_skipped_and_a_complex_one_still_is(tmp_path):
    """MagNav.jl's layout (one struct); a complex vector stays skipped, not cast to real."""
    f = _short()
    traj = {"tt": f["tt"], "lat": f["lat"] > 45.0, "lon": f["lon"] + 1j, "line": f["line"]}
    scipy.io.savemat(tmp_path / "in.mat", {"traj": traj, "N": np.array([[f.n]], np.int32)})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        flight, problems = load_flight(tmp_path / "in.mat")
    assert flight.names == ["tt", "line"] and flight.attrs["N"] == f.n
    assert "skipped boolean (true/false) item(s), not numbers: traj.lat" in problems
    assert "skipped item(s) that are not vectors: traj.lon" in problems


def test_a_matlab_73_logical_is_skipped_and_a_one_element_logical_kept(tmp_path):
    from tests.flight.test_formats import write_mat73

    path = write_mat73(tmp_path / "in.mat", {"tt": np.arange(4.0).reshape(4, 1)})
    logical = np.bytes_(b"logical")
    with h5py.File(path, "r+") as h5:  # MATLAB stores a logical as uint8, class "logical"
        for name, data in (("lat", [[1, 0, 1, 1]]), ("ok", [[1]])):
            h5.create_dataset(name, data=np.array(data, np.uint8)).attrs["MATLAB_class"] = logical
    flight, problems = load_flight(path)
    assert "lat" not in flight and flight.attrs["ok"] is True
    assert "skipped boolean (true/false) item(s), not numbers: lat" in problems


@pytest.mark.parametrize("name", ["lat", "ins_roll"])
def test_lsq_refuses_a_boolean_channel_it_needs(tmp_path, capsys, name):
    path = _write_h5(tmp_path / "in.h5", _with_bool(name))
    code, err = _compensate(path, "lsq", capsys)
    assert code == 2 and name in err.splitlines()[-1]


# ---------------------------------------------------------------------------------------------
# H. The measured field against IGRF-14 at the file's position and date


def _radians(path: Path | None = None) -> Flight:
    f = _short()
    f.fields["lat"], f.fields["lon"] = np.deg2rad(f["lat"]), np.deg2rad(f["lon"])
    if path is not None:
        write_flight(f, path)
    return f


@pytest.mark.parametrize("scalar", ["mag_1_uc", None])
def test_lat_lon_in_radians_disagree_with_igrf(scalar):
    message = model_mismatch(_radians(), scalar, "flux_a")
    assert message is not None
    assert message.startswith(scalar or "flux_a") and "lat and lon are in degrees" in message


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("preset_name", ["nominal", "paper", "noise_free"])
def test_clean_flights_agree_with_igrf(preset_name, seed):
    """No warning on clean flights, scalar or fluxgate: their magnitudes are within 1 % of
    IGRF-14 (the aircraft's interference), the threshold is 20 %."""
    f = _short(preset_name, seed)
    scalar = "mag_1_uc" if "mag_1_uc" in f else None
    assert model_mismatch(f, scalar, "flux_a") is None
    assert model_mismatch(f, None, "flux_a") is None


def test_the_threshold_sits_between_interference_and_radians():
    """A clean flight with a 15 % scale error in its scalar passes, 25 % is flagged [-]."""
    assert MODEL_MISMATCH_FRACTION == 0.2
    f = _short()
    for scale, flagged in ((1.15, False), (1.25, True)):
        scaled = Flight({**f.fields, "mag_1_uc": f["mag_1_uc"] * scale}, f.attrs)
        assert (model_mismatch(scaled, "mag_1_uc", "flux_a") is not None) is flagged


def test_compensate_warns_about_radians_through_choose_inputs(tmp_path):
    said: list[str] = []
    choose_inputs(_radians(), tmp_path / "in.h5", require=("fluxgate",), warn=said.append)
    assert any("IGRF-14" in s and "lat and lon" in s for s in said), said
    said.clear()
    choose_inputs(_short(), tmp_path / "in.h5", require=("fluxgate",), warn=said.append)
    assert not any("IGRF-14" in s for s in said), said


def test_info_lists_the_disagreement_among_its_problems(tmp_path):
    _radians(tmp_path / "in.h5")
    report = describe(tmp_path / "in.h5")
    assert report.usable and any("IGRF-14" in p and "lat and lon" in p for p in report.problems)
    clean = describe(write_flight(_short(), tmp_path / "clean.h5"))
    assert not [p for p in clean.problems if "IGRF-14" in p]


# ---------------------------------------------------------------------------------------------
# I. ±inf attitude samples


def test_inf_attitude_gives_nan_rotations_without_a_warning():
    rng = np.random.default_rng(4)
    roll, pitch, yaw = rng.uniform(-np.pi, np.pi, (3, 50))
    clean = dcm_from_euler(roll, pitch, yaw)
    roll[[3, 7]], pitch[10], yaw[20] = [np.inf, -np.inf], np.inf, -np.inf
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        c = dcm_from_euler(roll, pitch, yaw)
    bad = np.zeros(50, bool)
    bad[[3, 7, 10, 20]] = True
    assert np.isnan(c[bad]).any(axis=(1, 2)).all()
    np.testing.assert_array_equal(c[~bad], clean[~bad])  # finite samples: bit for bit


def test_info_and_lsq_on_an_inf_attitude_burst_print_no_runtime_warning(tmp_path, capsys):
    f = _short()
    f.fields["ins_roll"][600:610] = np.inf
    path = write_flight(f, tmp_path / "in.h5")
    for argv in (
        ["info", str(path)],
        ["compensate", str(path), "--method", "lsq", "--out", str(tmp_path / "o")],
    ):
        code, _, err = _run(argv, capsys)
        assert code == 0 and "RuntimeWarning" not in err, err


# ---------------------------------------------------------------------------------------------
# J. tl on a flight whose position is all NaN


@pytest.mark.parametrize("name", ["lat", "lon", "alt"])
def test_tl_runs_when_a_position_channel_is_all_nan(tmp_path, capsys, name):
    f = _short()
    f.fields[name][:] = np.nan
    code, err = _compensate(write_flight(f, tmp_path / "in.h5"), "tl", capsys)
    assert code == 0, err


def test_the_flight_date_stays_readable_for_a_clean_file():
    assert _short().date() == dt.datetime(2026, 6, 1, 14)


# ---------------------------------------------------------------------------------------------
# K. A replay of a file in the wrong units: the simulator would fly the wrong track silently


@pytest.mark.parametrize("preset_name", ["nominal", "paper"])
def test_the_ground_speed_of_a_clean_flight_is_its_configured_speed(preset_name):
    from aeromag_env.flight.quality import ground_speed_problem

    f = _short(preset_name)
    assert ground_speed_problem(f) is None
    f.fields["lat"][100:150] = np.nan  # a hole changes nothing
    assert ground_speed_problem(f) is None


@pytest.mark.parametrize(
    ("change", "said"),
    [("tt_ms", "median ground speed 0.0"), ("radians", "median ground speed 1.1")],
)
def test_time_in_ms_or_position_in_radians_is_too_slow_to_fly(change, said):
    """Time in ms: the speed (65 m/s here, the preset's) is 1000× lower; lat/lon in radians read
    as degrees: 57× lower."""
    from aeromag_env.flight.quality import ground_speed_problem

    f = _short() if change == "tt_ms" else _radians()
    if change == "tt_ms":
        f.fields["tt"] = f["tt"] * 1e3
    message = ground_speed_problem(f)
    assert message is not None and message.startswith(said), message
    assert "tt is in seconds and lat and lon in degrees" in message


def test_the_ground_speed_crosses_the_antimeridian():
    from aeromag_env.flight.quality import ground_speed_problem

    tt = np.arange(100.0)
    lon = 179.99 + tt * 65.0 / (np.deg2rad(1.0) * 6_378_137.0)  # 65 m/s east along the equator
    f = Flight({"tt": tt, "lat": np.zeros(100), "lon": (lon + 180.0) % 360.0 - 180.0})
    assert ground_speed_problem(f) is None
    f.fields["tt"] = tt * 100.0  # 0.65 m/s
    assert "0.65 m/s" in str(ground_speed_problem(f))


@pytest.mark.parametrize("fault", ["tt_ms", "radians", "alt_feet"])
def test_a_replay_warns_of_a_file_in_the_wrong_units(tmp_path, capsys, fault):
    f = _short() if fault != "radians" else _radians()
    if fault == "tt_ms":
        f.fields["tt"] = f["tt"] * 1e3
    if fault == "alt_feet":
        f.fields["utm_z"], f.fields["alt"] = f["alt"].copy(), f["alt"] * 3.28084
    path = write_flight(f, tmp_path / "in.h5")
    code, _, err = _run(
        ["simulate", "--replay", str(path), "--out", str(tmp_path / "s.h5"), "--quiet"], capsys
    )
    assert code == 0
    expected = {"tt_ms": "ground speed", "radians": "IGRF-14", "alt_feet": "alt looks like feet"}
    assert expected[fault] in err and "aeromag simulate: warning:" in err, err
    clean = write_flight(_short(), tmp_path / "clean.h5")
    code, _, err = _run(
        ["simulate", "--replay", str(clean), "--out", str(tmp_path / "c.h5"), "--quiet"], capsys
    )
    assert code == 0 and "warning" not in err, err


def test_an_applied_mount_says_what_the_truth_rmse_includes(tmp_path, capsys):
    """flux_a turned 45° about z: the mount is estimated and applied; the vector RMSE against
    the simulated truth (body axes) then holds the fit's share of the mount's residual error
    and the line says so, while IR stays that of the aligned file (within 5 %)."""
    from scipy.spatial.transform import Rotation

    from aeromag_env.cli.summaries import MOUNT_RMSE_NOTE

    f = simulated("nominal", 3, trajectory__duration_s=600.0)
    turned = {k: v.copy() for k, v in f.fields.items()}
    v = f.vector("flux_a") @ Rotation.from_euler("z", 45, degrees=True).as_matrix().T
    for i, axis in enumerate("xyz"):
        turned[f"flux_a_{axis}"] = v[:, i]
    lines = {}
    for name, fields in (("aligned", dict(f.fields)), ("turned", turned)):
        path = write_flight(Flight(fields, dict(f.attrs)), tmp_path / f"{name}.h5")
        code, out, _ = _run(
            ["compensate", str(path), "--method", "lsq", "--out", str(tmp_path / name)], capsys
        )
        assert code == 0
        lines[name] = out
    assert MOUNT_RMSE_NOTE in lines["turned"] and MOUNT_RMSE_NOTE not in lines["aligned"]
    ir = {k: float(v.split("; IR ")[1].split(";")[0].split()[0]) for k, v in lines.items()}
    assert abs(ir["turned"] / ir["aligned"] - 1.0) < 0.05, ir
