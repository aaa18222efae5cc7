"""Fit a :class:`~aeromag_env.compensation.calibration_model.CalibrationModel` on a calibration
flight (:func:`fit_model`).

Fitting is the package's own compensation (:func:`~aeromag_env.compensation.compensate.
compensate_scalar` for ``tl``, :func:`~aeromag_env.compensation.compensate.compensate_vector`
for the Kalman family) on the calibration flight or a part of it; the model keeps its result:
the Tolles–Lawson coefficients, or the filter's state, covariance, Q and R after the last sample
(and the samples it processed). The model then measures itself on the calibration part
(:meth:`CalibrationModel.apply <aeromag_env.compensation.calibration_model.CalibrationModel.
apply>`): the figure of merit box by box (:func:`fom_boxes`) and the residual the recalibrate
check compares other flights' with (:mod:`aeromag_env.compensation.model_drift`).
"""

from __future__ import annotations

import datetime as _dt
from dataclasses import replace
from typing import Any

import numpy as np

from aeromag_env.compensation import metrics
from aeromag_env.compensation.calibration_model import CalibrationModel
from aeromag_env.compensation.compensate import (
    FILTER_METHODS,
    Compensation,
    compensate_scalar,
    compensate_vector,
)
from aeromag_env.compensation.model import FilterConfig
from aeromag_env.compensation.model_apply import apply_tl
from aeromag_env.compensation.model_checks import GAP_FACTOR, segment_starts, spike_threshold_nt
from aeromag_env.compensation.tolles_lawson import TollesLawson
from aeromag_env.configs import to_dict
from aeromag_env.errors import AeromagError
from aeromag_env.flight.data import Flight
from aeromag_env.flight.mounting import Mount
from aeromag_env.flight.quality import segments

#: The methods :func:`fit_model` fits: Tolles–Lawson and the recursive filters.
FIT_METHODS = ("tl", *FILTER_METHODS)


def fit_model(
    flight: Flight,
    method: str,
    *,
    flux: str,
    scalar: str | None = None,
    mount: Mount | None = None,
    calibration: np.ndarray | None = None,
    tl: TollesLawson | None = None,
    filter_cfg: FilterConfig | None = None,
    provenance: dict[str, Any] | None = None,
) -> tuple[CalibrationModel, Compensation]:
    """Fit a model on a calibration flight.

    Parameters
    ----------
    flight : Flight
        The calibration flight (or the selected part of it).
    method : str
        One of :data:`FIT_METHODS`.
    flux, scalar : str
        The fluxgate prefix and (``tl``) the scalar magnetometer.
    mount : Mount or None
        The fluxgate's mount into body axes (vector methods; None: sensor axes are body axes).
    calibration : (n,) bool or None
        Fit on these samples only (a calibration line or window); None: all.
    tl : TollesLawson or None
        ``tl``'s settings (default: MagNav's band-pass 0.1–0.9 Hz, trim 20, λ = 0).
    filter_cfg : FilterConfig or None
        The filter's settings (default: the package's).
    provenance : dict or None
        ``input``, ``input_sha256`` of the calibration file; ``created`` and ``package_version``
        are added.

    Returns
    -------
    (CalibrationModel, Compensation)
        The model, and the compensation of the calibration flight the fit made.
    """
    if method not in FIT_METHODS:
        raise AeromagError(f"method must be one of {', '.join(FIT_METHODS)}, got {method!r}")
    if method == "tl":
        tl = tl or TollesLawson()
        comp, settings, coefficients = _fit_tl(flight, flux, scalar, tl, calibration)
    else:
        cfg = replace(filter_cfg or FilterConfig(), method=method)
        comp, settings, coefficients = _fit_filter(flight, flux, cfg, calibration, mount)
    model = CalibrationModel(
        method=method,
        settings=settings,
        coefficients=coefficients,
        channels={"time": "tt", "flux": flux, "scalar": scalar if method == "tl" else None},
        sample_rate_hz=flight.sample_rate_hz,
        gap_factor=GAP_FACTOR,
        spike_threshold_nt=_thresholds(flight, flux, scalar),
        mount=None if mount is None or method == "tl" else mount.to_dict(),
        provenance=_provenance(provenance),
    )
    if method == "tl" and tl is not None and tl.remove_mean_:
        model = _with_offset(model, flight)
    return _with_calibration(model, flight, comp, calibration), comp


def _fit_tl(
    flight: Flight, flux: str, scalar: str | None, tl: TollesLawson, calibration: np.ndarray | None
) -> tuple[Compensation, dict[str, Any], dict[str, Any]]:
    """The Tolles–Lawson fit: its compensation, settings and coefficients (the offset is set
    by :func:`_with_offset`)."""
    if scalar is None:
        raise AeromagError("tl needs a scalar magnetometer (scalar=...)")
    comp = compensate_scalar(flight, flux, scalar, tl, calibration)
    settings = {**_tl_settings(tl), "remove_mean": tl.remove_mean_}
    return comp, settings, {"tolles_lawson": tl.coef_.tolist(), "offset_nt": 0.0}


def _fit_filter(
    flight: Flight,
    flux: str,
    cfg: FilterConfig,
    calibration: np.ndarray | None,
    mount: Mount | None,
) -> tuple[Compensation, dict[str, Any], dict[str, Any]]:
    """A recursive filter run over the calibration flight: its compensation, settings and end
    (state, covariance, Q, R and the samples it processed)."""
    comp = compensate_vector(flight, cfg.method, flux, cfg, calibration, mount, check_mount=False)
    assert comp.filter_end is not None
    settings = {k: v for k, v in to_dict(cfg).items() if k != "method"}
    coefficients = {k: np.asarray(v).tolist() for k, v in comp.filter_end.items()}
    return comp, settings, {**coefficients, "samples": int(flight.n)}


def _tl_settings(tl: TollesLawson) -> dict[str, Any]:
    band = None if tl.bandpass_hz is None else list(tl.bandpass_hz)
    return {"bandpass_hz": band, "trim": tl.trim, "ridge": tl.ridge, "bt_scale_nt": tl.bt_scale_nt}


def _thresholds(flight: Flight, flux: str, scalar: str | None) -> dict[str, float]:
    """The spike thresholds the calibration flight sets, per magnetometer [nT]."""
    starts = segment_starts(flight.tt, GAP_FACTOR / flight.sample_rate_hz)
    out = {flux: spike_threshold_nt(flight.vector(flux), starts)}
    if scalar is not None:
        out[scalar] = spike_threshold_nt(flight[scalar], starts)
    return out


def _provenance(given: dict[str, Any] | None) -> dict[str, Any]:
    created = _dt.datetime.now(_dt.UTC).replace(microsecond=0).isoformat()
    return {
        "input": None,
        "input_sha256": None,
        **(given or {}),
        "created": created,
        "package_version": (given or {}).get("package_version"),
    }


def _with_offset(model: CalibrationModel, flight: Flight) -> CalibrationModel:
    """``model`` with ``offset_nt`` the mean correction over the calibration flight (a
    band-passed fit cannot see the constant part; MagNav removes the mean correction)."""
    tl = model.calibrated_tl()
    _, correction, _ = apply_tl(tl, flight.tt, flight.vector(tl.flux), flight[tl.scalar])
    finite = np.isfinite(correction)
    offset = float(np.mean(correction[finite])) if finite.any() else 0.0
    return replace(model, coefficients={**model.coefficients, "offset_nt": offset})


def _with_calibration(
    model: CalibrationModel, flight: Flight, comp: Compensation, calibration: np.ndarray | None
) -> CalibrationModel:
    """``model`` with its ``calibration`` block: what the fit saw, the FOM box by box, and the
    residual of the model applied to the calibration part (the recalibrate check's reference)."""
    part = np.ones(flight.n, bool) if calibration is None else calibration
    applied = model.apply(flight, residual_mask=part)
    k = np.flatnonzero(part)
    block = {
        "samples": int(part.sum()),
        "span_s": [float(flight.tt[k[0]]), float(flight.tt[k[-1]])] if k.size else None,
        "fit_residual_std_nt": comp.coefficients.get("residual_std_nt"),
        "fom_boxes": fom_boxes(flight, applied.total_before, applied.total_after),
        "residual": applied.settings["drift"],
    }
    done = [b["fom_nt"] for b in block["fom_boxes"] if b["fom_nt"] is not None]
    block["fom_nt"] = done[-1] if done else None
    return replace(model, calibration=block)


def fom_boxes(flight: Flight, before: np.ndarray, after: np.ndarray) -> list[dict[str, Any]]:
    """The figure of merit of each complete calibration box of ``flight`` (windows
    ``12b + 1 … 12b + 12`` of its ``maneuver`` labels), compensated and not [nT]."""
    ids = {m for m, _, _ in flight.maneuver_windows()}
    boxes = sorted(
        b for b in {(m - 1) // 12 for m in ids} if ids >= set(range(12 * b + 1, 12 * b + 13))
    )
    parts = segments(flight.tt)
    out = []
    for b in boxes:
        windows = range(12 * b + 1, 12 * b + 13)
        args = (flight.tt, flight.maneuver_ids(), flight.sample_rate_hz, 0.05, windows, parts)
        out.append(
            {
                "box": b + 1,
                "windows": [windows.start, windows.stop - 1],
                "fom_nt": _safe(metrics.figure_of_merit, after, *args),
                "fom_uncompensated_nt": _safe(metrics.figure_of_merit, before, *args),
            }
        )
    return out


def _safe(fn: Any, *args: Any) -> float | None:
    try:
        value = float(fn(*args))
    except AeromagError:
        return None
    return value if np.isfinite(value) else None
