"""Apply a calibrated model to a flight file: ``aeromag compensate FILE --model model.json``.

:func:`run_with_model` is the part of :func:`aeromag_env.jobs.compensate.run_compensate` for a
request with a ``model``: read and check the file as ``compensate`` does, select the lines or
segment, apply the model (:func:`aeromag_env.compensation.model_fit.apply_model`: Tolles–Lawson
with the calibrated coefficients, or the filter continued from its calibrated state), score,
say when the model no longer fits (:func:`model_warnings`), and write the same output set.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from aeromag_env.compensation.calibration_model import CalibrationModel, load_model
from aeromag_env.compensation.compensate import score
from aeromag_env.compensation.model_drift import drift_warning
from aeromag_env.compensation.model_fit import apply_model
from aeromag_env.errors import AeromagError
from aeromag_env.flight.data import Flight
from aeromag_env.flight.selection import select
from aeromag_env.jobs.provenance import JobWarnings, file_sha256, input_format, load_source

#: A flight whose sample rate differs from the calibration's by more than this share gets the
#: recalibrate warning (``tl``'s eddy terms are per-sample differences: their coefficients
#: scale with the rate) [-].
RATE_TOLERANCE = 0.01


def model_of(req: Any) -> CalibrationModel:
    """The request's model: loaded from its file, or the one given."""
    model = req.model
    return model if isinstance(model, CalibrationModel) else load_model(model)


def check_model_request(req: Any) -> None:
    """One-line errors for a request with a model: an unreadable model file, a ``method``
    other than the model's, or options that only a fit takes (a calibration part)."""
    model = model_of(req)
    if req.method not in (model.method, "tl"):
        raise AeromagError(
            f"--method {req.method} differs from the model's method {model.method}; leave it out "
            "with --model"
        )
    if req.calibration_line is not None or req.calibration_window_s is not None:
        raise AeromagError(
            "--calibration-line and --calibration-window select what a fit sees; with --model "
            "nothing is fitted (calibrate on them with aeromag calibrate instead)"
        )


def model_warnings(
    model: CalibrationModel, flight: Flight, drift: dict[str, Any], what: str
) -> list[str]:
    """The recalibrate warnings of a model applied to ``flight``: its residual against the
    calibration's (:func:`~aeromag_env.compensation.model_drift.drift_warning`) and a sample
    rate other than the calibration's."""
    lines = []
    found = drift_warning(model.method, model.calibration.get("residual") or {}, drift, what)
    if found:
        lines.append(found)
    rate = flight.sample_rate_hz
    if abs(rate / model.sample_rate_hz - 1) > RATE_TOLERANCE:
        lines.append(
            f"{what} is sampled at {rate:g} Hz, the calibration at {model.sample_rate_hz:g} Hz: "
            "the calibrated coefficients do not carry over; recalibrate at this rate"
        )
    return lines


def run_with_model(req: Any, warn: JobWarnings) -> Any:
    """:func:`~aeromag_env.jobs.compensate.run_compensate` for a request with a model."""
    from aeromag_env.atomic import check_output_set
    from aeromag_env.jobs.compensate import (
        REPORT_VERSION,
        CompensationResult,
        _check_output_names,
        _nonfinite_policy,
        write_compensate_outputs,
    )

    model = model_of(req)
    if req.out is not None:
        check_output_set(req.out, req.outputs(), _inputs(req))
    needs = ("tt",) if model.method == "tl" else ("tt", "position", "attitude", "date")
    flight, problems, path = load_source(req.source, needs)
    chosen = select(flight, req.lines, req.segment_s, None, None)
    work = chosen.flight
    comp = apply_model(model, work)
    _check_output_names(flight, comp)
    what = str(path) if path is not None else "this flight"
    drift = comp.settings["drift"]
    for line in model_warnings(model, work, drift, what):
        warn(line)
    metrics_block = score(work, comp)
    report = {
        "report_version": REPORT_VERSION,
        "input": None if path is None else str(path),
        "input_sha256": None if path is None else file_sha256(path),
        "input_format": None if path is None else input_format(path),
        "method": comp.method,
        "settings": comp.settings,
        "coefficients": comp.coefficients,
        "metrics": metrics_block,
        "nonfinite_policy": _nonfinite_policy(comp),
        "input_problems": problems,
        "selection": chosen.report,
        "model": _model_block(req, model, drift),
        "warnings": list(warn.lines),
        "held_out": None,
    }
    kept = {name: values[chosen.keep] for name, values in flight.fields.items()}
    out_flight = Flight({**kept, **comp.fields}, {**flight.attrs, "compensation": comp.method})
    paths: tuple[Path, ...] = ()
    if req.out is not None:
        paths = write_compensate_outputs(req, out_flight, report, work, comp)
    return CompensationResult(
        method=comp.method,
        metrics=metrics_block,
        coefficients=comp.coefficients,
        report=report,
        warnings=tuple(warn.lines),
        paths=paths,
        compensation=comp,
        flight=out_flight,
    )


def _inputs(req: Any) -> list[Path]:
    """The files the run reads: the flight, the mount file, the model file."""
    model = [] if isinstance(req.model, CalibrationModel) else [Path(req.model)]
    return [*req.input_files(), *model]


def _model_block(req: Any, model: CalibrationModel, drift: dict[str, Any]) -> dict[str, Any]:
    """The report's ``model`` block: which model, the calibration's residual and this flight's."""
    return {
        "file": None if isinstance(req.model, CalibrationModel) else str(req.model),
        "method": model.method,
        "provenance": model.provenance,
        "calibration_residual": model.calibration.get("residual"),
        "flight_residual": {
            k: (None if isinstance(v, float) and not np.isfinite(v) else v)
            for k, v in drift.items()
        },
        "calibration_fom_nt": model.calibration.get("fom_nt"),
    }
