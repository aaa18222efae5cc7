"""The calibrate, compensate-with-a-model and stream jobs, end to end on files."""

from __future__ import annotations

import dataclasses
import functools
import io

import numpy as np
import pytest

from aeromag_env.compensation.calibration_model import load_model
from aeromag_env.errors import AeromagError, AeromagWarning, ArgumentError
from aeromag_env.flight.data import Flight
from aeromag_env.flight.files import write_flight
from aeromag_env.jobs.calibrate import calibrate
from aeromag_env.jobs.compensate import compensate
from aeromag_env.jobs.stream import stream
from aeromag_env.simulation.config import AircraftConfig, preset, with_overrides
from aeromag_env.simulation.simulate import simulate_flight
from tests._helpers import assert_one_line_error


@functools.cache
def flights(kind: str) -> Flight:
    base = preset("nominal")
    survey = with_overrides(base, {"trajectory.pattern": "survey", "trajectory.duration_s": 300.0})
    plane = AircraftConfig(seed=21)
    made = {
        "calibration": (base, plane, 30),
        "survey": (survey, plane, 31),
        "other": (survey, AircraftConfig(seed=22), 31),
        "changed": (
            survey,
            AircraftConfig(
                seed=21, permanent_shift_nt=(60, -40, 30), scalar_permanent_shift_nt=(20, -15, 10)
            ),
            31,
        ),
    }
    cfg, aircraft, seed = made[kind]
    return simulate_flight(dataclasses.replace(cfg, aircraft=aircraft), seed)


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory):
    folder = tmp_path_factory.mktemp("cal")
    write_flight(flights("calibration"), folder / "cal.h5")
    out = {m: calibrate(folder / "cal.h5", m, out=folder / m) for m in ("tl", "kf")}
    return folder, out


def test_calibrate_writes_the_model_and_its_report(calibrated):
    folder, out = calibrated
    result = out["tl"]
    assert [p.name for p in result.paths] == ["model.json", "report.json", "report.html"]
    model = load_model(folder / "tl" / "model.json")
    assert model.provenance["input_sha256"] == result.report["provenance"]["input_sha256"]
    boxes = result.report["calibration"]["fom_boxes"]
    assert len(boxes) == 1 and boxes[0]["fom_nt"] < 0.1 * boxes[0]["fom_uncompensated_nt"]
    assert "Figure of merit, box by box" in (folder / "tl" / "report.html").read_text()


@pytest.mark.parametrize("method", ["tl", "kf"])
@pytest.mark.parametrize(
    ("kind", "warned"), [("survey", False), ("other", True), ("changed", True)]
)
def test_recalibrate_warning_names_its_evidence(calibrated, method, kind, warned):
    folder, _ = calibrated
    result = compensate(flights(kind), model=folder / method / "model.json")
    said = [w for w in result.warnings if "recalibrate" in w]
    assert bool(said) == warned, result.warnings
    if warned:
        assert "at calibration" in said[0] and "nT" in said[0]
        assert result.report["warnings"] == list(result.warnings)


def test_compensate_with_a_model_refuses_a_calibration_part_or_another_method(calibrated):
    folder, _ = calibrated
    model = folder / "tl" / "model.json"
    with pytest.raises(ArgumentError) as e:
        compensate(flights("survey"), model=model, calibration_line="auto")
    assert e.value.argument == "calibration_line"
    assert_one_line_error(e, "nothing is fitted")
    with pytest.raises(ArgumentError) as e:
        compensate(flights("survey"), "kf", model=model)
    assert e.value.argument == "method"
    assert_one_line_error(e, "the model's, tl")


def test_stream_of_a_converted_csv_equals_compensate_with_the_model(calibrated, tmp_path):
    folder, _ = calibrated
    csv_path = write_flight(flights("survey"), tmp_path / "survey.csv")  # with its #@ line
    assert csv_path.read_text().startswith("#@")
    ref = compensate(csv_path, model=folder / "tl" / "model.json").flight["aeromag_mag_1_c"]
    out, said = io.StringIO(), []
    with open(csv_path) as lines:
        summary = stream(load_model(folder / "tl" / "model.json"), lines, out, warn=said.append)
    rows = out.getvalue().splitlines()
    assert rows[0] == "tt,aeromag_mag_1_c"
    values = np.array([[float(c) for c in r.split(",")] for r in rows[1:]])
    assert summary.samples_out == values.shape[0] == np.isfinite(ref).sum()
    np.testing.assert_allclose(values[:, 1], ref[np.isfinite(ref)], rtol=0, atol=1e-9)  # the claim
    assert said == []


def test_stream_reports_and_skips_bad_lines(calibrated):
    folder, _ = calibrated
    f = flights("survey")
    head = "tt,flux_a_x,flux_a_y,flux_a_z,mag_1_uc\n"
    rows = [
        ",".join(repr(float(v)) for v in (f.tt[k], *f.vector("flux_a")[k], f["mag_1_uc"][k]))
        for k in range(20)
    ]
    rows[5] = "1.0,2.0"  # too few cells
    rows[8] = rows[8].replace(rows[8].split(",")[4], "abc")  # not a number
    rows[11] = rows[10]  # time not after the previous
    out, said = io.StringIO(), []
    summary = stream(
        folder / "tl" / "model.json", [head, *[r + "\n" for r in rows]], out, warn=said.append
    )
    assert summary.skipped == 3 and summary.samples_out == 17
    assert any("line 7" in s and "cells" in s for s in said)
    assert any("line 10" in s and "not a number" in s for s in said)
    assert any("line 13" in s and "not after" in s for s in said)


def test_stream_without_the_models_channels_is_one_line_error(calibrated):
    folder, _ = calibrated
    with pytest.raises(AeromagError) as e:
        stream(folder / "tl" / "model.json", ["tt,flux_a_x\n"], io.StringIO(), warn=print)
    assert_one_line_error(e, "mag_1_uc")


def test_stream_of_a_filter_model_equals_compensate_with_the_model(calibrated, tmp_path):
    """A kf model's stream of the CSV ``aeromag convert`` writes (its date read from the ``#@``
    line) gives compensate --model's values."""
    folder, _ = calibrated
    model = folder / "kf" / "model.json"
    csv_path = write_flight(flights("survey"), tmp_path / "survey.csv")
    ref = compensate(csv_path, model=model).flight
    names = ("aeromag_flux_a_c_x", "aeromag_flux_a_c_y", "aeromag_flux_a_c_z")
    out, said = io.StringIO(), []
    with open(csv_path) as lines:
        stream(model, lines, out, warn=said.append)
    rows = out.getvalue().splitlines()
    assert rows[0] == "tt," + ",".join(names)
    values = np.array([[float(c) for c in r.split(",")] for r in rows[1:]])
    whole = np.column_stack([ref[n] for n in names])
    kept = np.all(np.isfinite(whole), axis=1)
    np.testing.assert_array_equal(values[:, 0], ref.tt[kept])
    np.testing.assert_allclose(values[:, 1:], whole[kept], rtol=0, atol=1e-9)  # the claim
    assert said == []


def test_a_fleet_with_a_model(calibrated, tmp_path):
    from aeromag_env.jobs.fleet import fleet

    folder, _ = calibrated
    for kind in ("survey", "changed"):
        write_flight(flights(kind), tmp_path / "flights" / f"{kind}.h5")
    with pytest.warns(AeromagWarning, match="changed.h5: the calibrated kf model no longer fits"):
        result = fleet(tmp_path / "flights", tmp_path / "out", model=folder / "kf" / "model.json")
    rows = {r["file"].split("/")[-1]: r for r in result.rows}
    assert [r["status"] for r in rows.values()] == ["ok", "ok"]
    assert rows["survey.h5"]["method"] == "kf" and rows["survey.h5"]["warnings"] == 0
    assert "no longer fits" in rows["changed.h5"]["warning_text"]
    assert "recalibrate" in rows["changed.h5"]["warning_lines"][0]


def test_calibrate_fits_the_filter_it_names_with_the_requests_settings():
    result = calibrate(flights("calibration"), "fakf", r_std_nt=2.0, html=False)
    assert result.compensation.method == result.model.method == "fakf"
    cfg = result.model.filter_config()
    assert cfg.method == "fakf" and cfg.r_std_nt == 2.0
    assert result.model.coefficients["samples"] == flights("calibration").n
