import hashlib
import json

import numpy as np
import pytest

from aeromag_env.cli.main import main
from aeromag_env.compensation.compensate import METHODS
from aeromag_env.flight.data import Flight
from aeromag_env.flight.files import read_flight, write_flight
from aeromag_env.flight.validation import FlightFileWarning
from tests._flights import simulated

REPORT_METRICS = {
    "compensation_rmse_nt",
    "compensation_rmse_all_nt",
    "residual_std_nt",
    "improvement_ratio",
    "fom_nt",
    "nonfinite_samples",
    "divergences",
    "segments",
    "flagged_samples",
}


@pytest.fixture(scope="module")
def nominal_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("flight") / "nominal.h5"
    write_flight(simulated("nominal", 0), path)
    return path


def _sha(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.mark.parametrize("method", METHODS)
def test_every_method_runs_on_a_nominal_flight(nominal_file, tmp_path, capsys, method):
    before = _sha(nominal_file)
    assert main(["compensate", str(nominal_file), "--method", method, "--out", str(tmp_path)]) == 0
    assert capsys.readouterr().out.startswith(f"{method}: wrote")
    report = json.loads((tmp_path / "report.json").read_text())
    assert {"method", "settings", "coefficients", "metrics"} <= set(report)
    assert set(report["metrics"]) >= REPORT_METRICS
    m = report["metrics"]
    assert m["divergences"] == 0 and m["nonfinite_samples"] == 0
    out = read_flight(tmp_path / "compensated.h5")
    new = ["aeromag_mag_1_c"] if method == "tl" else ["aeromag_flux_a_c_x", "aeromag_interf_est_z"]
    assert all(nm in out for nm in [*new, "flux_a_x", "ins_yaw"])  # input fields kept
    assert (tmp_path / "compensation.png").stat().st_size > 10_000
    assert _sha(nominal_file) == before  # the input is untouched
    # every method removes most of the interference: the true RMSE after convergence is a
    # small fraction of the interference itself (hundreds of nT at the fluxgate, ~10 at the
    # stinger); sage-husa, the weakest, stays under 10 nT on this flight
    assert m["compensation_rmse_nt"] < (0.05 if method == "tl" else 10.0)
    assert m["fom_nt"] < m["fom_uncompensated_nt"]


def test_tl_needs_only_time_fluxgate_and_scalar(tmp_path):
    f = simulated("nominal", 1)
    slim = Flight({k: f[k] for k in ("tt", "flux_a_x", "flux_a_y", "flux_a_z", "mag_1_uc")})
    path = write_flight(slim, tmp_path / "slim.csv")
    assert main(["compensate", str(path), "--method", "tl", "--out", str(tmp_path / "o")]) == 0
    report = json.loads((tmp_path / "o" / "report.json").read_text())
    assert report["metrics"]["compensation_rmse_nt"] is None  # no truth in the file
    assert report["metrics"]["improvement_ratio"] > 10
    assert len(report["coefficients"]["tolles_lawson"]) == 18


def test_calibration_window_fits_there_and_applies_everywhere(nominal_file, tmp_path):
    args = ["compensate", str(nominal_file), "--method", "lsq", "--calibration-window", "0", "300"]
    assert main([*args, "--out", str(tmp_path)]) == 0
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["settings"]["calibration_samples"] == 3001
    out = read_flight(tmp_path / "compensated.h5")
    assert np.all(np.isfinite(out["aeromag_interf_est_x"]))  # applied to the whole flight


def test_a_filter_fitted_on_a_calibration_window_has_no_qoq_after_it(tmp_path):
    box = simulated("nominal", 0, trajectory__pattern="calibration", trajectory__duration_s=900.0)
    path = write_flight(box, tmp_path / "box.h5")
    args = ["compensate", str(path), "--method", "kf", "--calibration-window", "0", "300"]
    assert main([*args, "--out", str(tmp_path / "o")]) == 0  # crashed before issue 19
    report = json.loads((tmp_path / "o" / "report.json").read_text())
    assert report["metrics"]["qoq"] is None  # the filter never updates in the second half
    assert report["metrics"]["compensation_rmse_nt"] < 10.0  # [nT], as for the whole flight


def test_nonfinite_samples_are_skipped_and_counted(tmp_path, capsys):
    f = simulated("nominal", 2)
    fields = dict(f.fields)
    fields["flux_a_y"] = fields["flux_a_y"].copy()
    fields["flux_a_y"][1000:1010] = np.nan
    path = write_flight(Flight(fields, f.attrs), tmp_path / "gappy.h5")
    assert main(["compensate", str(path), "--method", "kf", "--out", str(tmp_path / "o")]) == 0
    assert "10 non-finite samples" in capsys.readouterr().out
    report = json.loads((tmp_path / "o" / "report.json").read_text())
    assert report["metrics"]["nonfinite_samples"] == 10
    assert any("flux_a_y: 10 of" in p for p in report["input_problems"])
    with pytest.warns(FlightFileWarning, match="flux_a_y: 10 of"):
        est = read_flight(tmp_path / "o" / "compensated.h5")["aeromag_interf_est_x"]
    assert np.all(np.isfinite(est))  # the estimate continues through the gap


def test_the_vendor_compensated_channel_is_kept(tmp_path):
    f = simulated("nominal", 1)
    vendor = f["mag_1_uc"] - f["truth_interf_mag_1"] + 0.5  # a vendor's own compensation
    path = write_flight(Flight({**f.fields, "mag_1_c": vendor}, f.attrs), tmp_path / "v.h5")
    assert main(["compensate", str(path), "--method", "tl", "--out", str(tmp_path / "o")]) == 0
    out = read_flight(tmp_path / "o" / "compensated.h5")
    np.testing.assert_array_equal(out["mag_1_c"], vendor)  # untouched
    assert np.nanstd(out["aeromag_mag_1_c"] - vendor) < 0.1  # ours is a channel of its own [nT]


def test_an_output_name_already_in_the_input_is_refused(tmp_path, capsys):
    f = simulated("nominal", 1)
    fields = {**f.fields, "aeromag_mag_1_c": f["mag_1_uc"]}
    path = write_flight(Flight(fields, f.attrs), tmp_path / "again.h5")
    assert main(["compensate", str(path), "--method", "tl", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "aeromag_mag_1_c" in err and "refusing to replace" in err and err.count("\n") == 1
    assert not (tmp_path / "o" / "compensated.h5").exists()


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--method", "ukf"], "invalid choice: 'ukf'"),
        (["--method", "tl", "--tl-bandpass", "0.9", "0.1"], "--tl-bandpass needs 0 ≤ LOW < HIGH"),
        (["--method", "tl", "--tl-bandpass", "x"], "--tl-bandpass takes LOW HIGH"),
        (["--method", "tl", "--tl-ridge", "-1"], "--tl-ridge must be ≥ 0"),
        (["--method", "kf", "--calibration-window", "5", "1"], "T0 < T1"),
        (["--method", "kf", "--calibration-window", "0", "1"], "holds 11 samples"),
        (["--method", "kf", "--flux", "flux_q"], "flux_q_x"),
    ],
)
def test_bad_options_one_line(nominal_file, tmp_path, capsys, extra, message):
    try:
        code = main(["compensate", str(nominal_file), "--out", str(tmp_path / "o"), *extra])
    except SystemExit as e:
        code = e.code
    err = capsys.readouterr().err
    assert code == 2 and message in err and err.count("\n") == 1
    assert not (tmp_path / "o" / "report.json").exists()


def test_output_folder_cannot_overwrite_the_input(tmp_path, capsys):
    path = write_flight(simulated("nominal", 0), tmp_path / "compensated.h5")
    before = _sha(path)
    assert main(["compensate", str(path), "--method", "lsq", "--out", str(tmp_path)]) == 2
    assert "is the input file" in capsys.readouterr().err
    assert _sha(path) == before


@pytest.mark.parametrize(
    ("suffix", "method"),
    [("h5", "vbakf"), ("csv", "vbakf-pr"), ("xyz", "imm"), ("mat", "vbakf")],
)
def test_the_new_filters_run_from_every_file_format_as_from_the_library(
    tmp_path, capsys, suffix, method
):
    """``aeromag compensate FILE --method M`` on a flight written as HDF5, CSV, Geosoft XYZ or
    MATLAB: its report's metrics are those :func:`aeromag_env.compensate` returns for the same
    file (one door)."""
    import aeromag_env

    path = write_flight(simulated("nominal", 3), tmp_path / f"flight.{suffix}")
    out = tmp_path / "out"
    assert main(["compensate", str(path), "--method", method, "--out", str(out)]) == 0
    report = json.loads((out / "report.json").read_text())
    assert report["method"] == method and method.replace("-", "_") in report["settings"]
    library = aeromag_env.compensate(path, method=method)
    for key in ("compensation_rmse_nt", "divergences", "outliers_rejected", "fom_nt"):
        assert report["metrics"][key] == library.metrics[key], key
    assert report["metrics"]["compensation_rmse_nt"] < 2.0  # 212 nT RMS of interference
