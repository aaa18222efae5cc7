"""What ``report.json`` says a run used (input hash and format, channels, mount, segments, flagged
samples, flight date, Earth model) and the real-data accuracy blocks (``headline``,
``vendor_comparison``), checked against independent computations: hashlib over the file's bytes,
importlib.metadata for ppigrf's version, scipy's Butterworth band-pass for the spreads."""

from __future__ import annotations

import hashlib
import importlib.metadata
import json
from pathlib import Path

import numpy as np
import pytest
from scipy.signal import butter, sosfiltfilt

from aeromag_env.cli.main import main
from aeromag_env.compensation.real_metrics import bandpassed, spreads, vendor_comparison
from aeromag_env.flight.data import Flight
from aeromag_env.flight.files import read_flight, write_flight
from aeromag_env.jobs.compensate import REPORT_VERSION
from tests._flights import simulated

FS_HZ = 10.0


def _vendor_flight(seed: int = 0) -> Flight:
    """A simulated flight with a vendor's compensated scalar: the truth minus 0.05 nT noise."""
    f = simulated("nominal", seed)
    rng = np.random.default_rng(7)
    vendor = f["mag_1_uc"] - f["truth_interf_mag_1"] + rng.normal(0.0, 0.05, f.n)
    return Flight({**f.fields, "mag_1_c": vendor}, dict(f.attrs))


def _run(path: Path, out: Path, *extra: str) -> dict:
    assert main(["compensate", str(path), "--out", str(out), *extra]) == 0
    return json.loads((out / "report.json").read_text())


def _scipy_std(x: np.ndarray, span: slice) -> float:
    """Independent band-passed std: scipy's 4-pole Butterworth, zero phase, over ``span``."""
    sos = butter(4, [0.1, 0.9], btype="bandpass", fs=FS_HZ, output="sos")
    return float(np.std(sosfiltfilt(sos, x)[span]))


@pytest.fixture(scope="module")
def vendor_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_flight(_vendor_flight(), tmp_path_factory.mktemp("vendor") / "vendor.h5")


def test_report_records_what_the_run_used(vendor_file: Path, tmp_path: Path) -> None:
    report = _run(vendor_file, tmp_path, "--method", "kf")
    assert report["report_version"] == REPORT_VERSION == 2
    assert report["input_sha256"] == hashlib.sha256(vendor_file.read_bytes()).hexdigest()
    assert report["input_format"] == "hdf5"
    channels = report["channels"]
    assert [channels[k]["name"] for k in ("fluxgate", "scalar", "altitude")] == [
        "flux_a",
        "mag_1_uc",
        "alt",
    ]
    assert all(channels[k]["reason"] for k in channels)
    mount = report["mount"]
    assert mount["fluxgate"] == "flux_a" and mount["mode"] == "auto" and not mount["applied"]
    assert mount["estimate"]["angle_from_body_deg"] < 1.0 and mount["warning"] is None
    assert report["flight_date"]["source"] == "file attribute 'date'"
    assert report["flight_date"]["iso"].startswith(read_flight(vendor_file).attrs["date"][:10])
    assert report["earth_model"] == {
        "name": "IGRF-14",
        "package": "ppigrf",
        "package_version": importlib.metadata.version("ppigrf"),
        "used": True,
        "diurnal": True,
    }
    for key in ("segments", "flagged_samples"):  # once: in metrics or at the top
        assert (key in report) != (key in report["metrics"]), key


def test_vendor_comparison_against_scipy_and_the_vendor_field_kept(
    vendor_file: Path, tmp_path: Path
) -> None:
    report = _run(vendor_file, tmp_path, "--method", "tl")
    block = report["vendor_comparison"]
    assert block["scalar"] == "mag_1_uc" and block["vendor_channel"] == "mag_1_c"
    assert block["ours_sensor"] == "mag_1_uc" and block["segment_count"] == 1
    f = read_flight(vendor_file)
    half = slice(f.n // 2, f.n)
    # the same band-pass (scipy's, run here on the whole segment); 1e-6 relative [-]: filtering
    # a 5e4 nT series to a few hundredths of a nT leaves rounding at ~1e-9 of the result
    assert block["std_uncompensated_nt"] == pytest.approx(_scipy_std(f["mag_1_uc"], half), 1e-6)
    assert block["std_vendor_nt"] == pytest.approx(_scipy_std(f["mag_1_c"], half), 1e-6)
    out = read_flight(tmp_path / "compensated.h5")
    np.testing.assert_array_equal(out["mag_1_c"], f["mag_1_c"])  # the vendor's field kept
    ours = [nm for nm in out.names if nm not in f.names]
    assert len(ours) == 1  # TL writes one channel of its own
    assert block["std_ours_nt"] == pytest.approx(_scipy_std(out[ours[0]], half), 1e-6)
    # the vendor's field is the truth plus 0.05 nT of white noise, a fraction of which is in
    # the 0.1-0.9 Hz band; TL on this flight is within a few hundredths of a nT of it [nT]
    assert block["std_vendor_nt"] < 0.05 and block["std_ours_nt"] < 0.1
    ratio = block["std_uncompensated_nt"] / block["std_vendor_nt"]
    assert block["improvement_ratio_vendor"] == pytest.approx(ratio)
    assert block["improvement_ratio_ours"] > 10


def test_spreads_run_per_segment_and_never_across_a_gap() -> None:
    f = simulated("nominal", 1)
    keep = np.ones(f.n, bool)
    keep[3000:3300] = False  # a 30-s gap
    gappy = Flight({k: v[keep] for k, v in f.fields.items()}, dict(f.attrs))
    x = gappy["mag_1_uc"]
    s = spreads(gappy, {"uc": x})
    assert s["segment_count"] == 2 and s["samples"] == gappy.n
    first, second = slice(0, 3000), slice(3000, gappy.n)
    for seg, row in zip((first, second), s["segments"], strict=True):
        assert row["std_nt"]["uc"] == pytest.approx(_scipy_std(x[seg], slice(None)), 1e-6)
    bp = bandpassed(gappy, x)
    whole = sosfiltfilt(butter(4, [0.1, 0.9], btype="bandpass", fs=FS_HZ, output="sos"), x)
    assert not np.allclose(bp[2990:3010], whole[2990:3010])  # not filtered across the gap


def test_headline_of_an_unlabelled_box_finds_the_maneuvers_from_attitude(tmp_path: Path) -> None:
    f = _vendor_flight(2)
    fields = {k: v for k, v in f.fields.items() if k not in ("maneuver", "mag_1_c")}
    attrs = {k: v for k, v in f.attrs.items() if k != "date"}  # the date from year/doy
    path = write_flight(Flight(fields, attrs), tmp_path / "unlabelled.h5")
    report = _run(path, tmp_path / "o", "--method", "lsq")
    assert report["metrics"]["fom_nt"] is None  # the metrics block needs labels
    head = report["headline"]
    assert head["bandpass_hz"] == [0.1, 0.9] and head["span"] == "second half of the flight"
    assert head["fom_source"] == "manoeuvres detected from the attitude"
    assert len(head["fom_windows"]) == 12 and head["fom_nt"] < head["fom_uncompensated_nt"]
    labelled = _run(write_flight(f, tmp_path / "labelled.h5"), tmp_path / "l", "--method", "lsq")
    # the same 12 windows, found up to 1 s wider than labelled: within 10 % [-]
    assert head["fom_nt"] == pytest.approx(labelled["metrics"]["fom_nt"], rel=0.10)
    assert labelled["headline"]["fom_source"].startswith("labelled")
    assert head["improvement_ratio"] == pytest.approx(
        head["std_uncompensated_nt"] / head["std_compensated_nt"]
    )
    assert head["improvement_ratio"] > 5 and head["whole_flight"]["samples"] == f.n
    assert report["vendor_comparison"] is None
    assert report["flight_date"]["source"] == "fields 'year' and 'doy' (first sample)"


def test_a_slim_tl_file_says_no_earth_model_and_no_mount_estimate(tmp_path: Path) -> None:
    f = simulated("nominal", 1)
    slim = Flight({k: f[k] for k in ("tt", "flux_a_x", "flux_a_y", "flux_a_z", "mag_1_uc")})
    path = write_flight(slim, tmp_path / "slim.csv")
    report = _run(path, tmp_path / "o", "--method", "tl")
    assert report["input_format"] == "csv" and report["channels"]["altitude"] is None
    assert report["earth_model"]["used"] is False and report["flight_date"]["iso"] is None
    assert report["mount"]["estimate"] is None and not report["mount"]["applied"]
    assert "no attitude, position, date in the file" in report["mount"]["reason"]


def test_vendor_comparison_leaves_scalar_spikes_out() -> None:
    """A 1e6 nT spike in the uncompensated scalar, in the scored half: without the flags it
    would dominate the band-passed std; with them the figures are the clean flight's."""
    f = _vendor_flight(0)
    spiky = f["mag_1_uc"].copy()
    spiky[4000] += 1e6
    g = Flight({**f.fields, "mag_1_uc": spiky}, dict(f.attrs))
    ours = f["mag_1_c"] + 0.01  # any compensated series: not what is tested here
    clean = vendor_comparison(f, "mag_1_uc", f["mag_1_uc"], ours, "mag_1_uc")
    flagged = vendor_comparison(g, "mag_1_uc", spiky, ours, "mag_1_uc")
    assert clean is not None and flagged is not None
    assert flagged["samples"] < clean["samples"]  # the spike and its band-pass edges left out
    # the rest of the flight is the same: within 5 % [-] (the band-pass restarts at the hole)
    for key in ("std_uncompensated_nt", "std_vendor_nt"):
        assert flagged[key] == pytest.approx(clean[key], rel=0.05), key
