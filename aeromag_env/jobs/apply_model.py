"""What ``aeromag compensate FILE --model model.json`` adds to a compensation: reading and
checking the model (:func:`model_of`, :func:`check_model_request`), the fields it needs from the
file (:func:`model_needs`), the recalibrate warnings (:func:`model_warnings`) and the report's
``model`` block (:func:`model_block`). The run itself is the compensate job's
(:func:`aeromag_env.jobs.compensate.run_compensate`); the model is applied by
:meth:`CalibrationModel.apply <aeromag_env.compensation.calibration_model.CalibrationModel.
apply>`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from aeromag_env.compensation.calibration_model import CalibrationModel, load_model
from aeromag_env.compensation.model_drift import drift_warning
from aeromag_env.errors import ArgumentError
from aeromag_env.flight.data import Flight

#: A flight whose sample rate differs from the calibration's by more than this share gets the
#: recalibrate warning (``tl``'s eddy terms are per-sample differences: their coefficients
#: scale with the rate) [-].
RATE_TOLERANCE = 0.01


def model_of(model: str | Path | CalibrationModel) -> CalibrationModel:
    """The model given, or read from its file (a one-line error when it is not one)."""
    return model if isinstance(model, CalibrationModel) else load_model(model)


def check_model_request(
    model: CalibrationModel,
    method: str | None,
    calibration_line: str | None,
    calibration_window_s: tuple[float, float] | None,
) -> None:
    """One-line errors for options that contradict a model: a ``method`` other than the
    model's, or a calibration part (with a model nothing is fitted)."""
    if method is not None and method != model.method:
        raise ArgumentError(
            "method", f"is the model's, {model.method}, with a model (or leave it out)", method
        )
    for name, value in (
        ("calibration_line", calibration_line),
        ("calibration_window_s", calibration_window_s),
    ):
        if value is not None:
            raise ArgumentError(
                name,
                "selects what a fit sees; with a model nothing is fitted (calibrate on that "
                "part with calibrate instead)",
            )


def model_needs(model: CalibrationModel) -> tuple[str, ...]:
    """The fields a flight file must have for ``model`` besides its magnetometers."""
    return ("tt",) if model.method == "tl" else ("tt", "position", "attitude", "date")


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


def model_block(
    given: str | Path | CalibrationModel, model: CalibrationModel, drift: dict[str, Any]
) -> dict[str, Any]:
    """The report's ``model`` block: which model, the calibration's residual and this flight's."""
    return {
        "file": None if isinstance(given, CalibrationModel) else str(given),
        "method": model.method,
        "provenance": model.provenance,
        "calibration_residual": model.calibration.get("residual"),
        "flight_residual": {
            k: (None if isinstance(v, float) and not np.isfinite(v) else v)
            for k, v in drift.items()
        },
        "calibration_fom_nt": model.calibration.get("fom_nt"),
    }
