"""Fit a :class:`~aeromag_env.compensation.calibration_model.CalibrationModel` on a calibration
flight (:func:`fit_model`) and apply it to another flight (:func:`apply_model`).

Fitting is the package's own compensation (:func:`~aeromag_env.compensation.compensate.
compensate_scalar` for ``tl``, :func:`~aeromag_env.compensation.compensate.compensate_vector`
for the Kalman family) on the calibration flight or a part of it; the model keeps its result:
the Tolles–Lawson coefficients, or the filter's state, covariance, Q and R after the last sample.

Applying gives a :class:`~aeromag_env.compensation.compensate.Compensation` like a fit's, so the
jobs score and write it the same way:

* ``tl``: :func:`~aeromag_env.compensation.model_apply.apply_tl` (the same numbers as a stream);
* the Kalman family: the filter starts from the calibrated state and covariance (and Q, R) and
  keeps adapting over the flight, with the calibration's mount and settings.

Both also measure the residual the recalibrate check compares with the calibration's
(:mod:`aeromag_env.compensation.model_drift`), in ``Compensation.settings["drift"]``.
"""

from __future__ import annotations

import datetime as _dt
import itertools
from typing import Any

import numpy as np

from aeromag_env.compensation import metrics
from aeromag_env.compensation.calibration_model import CalibrationModel
from aeromag_env.compensation.compensate import (
    FILTER_METHODS,
    Compensation,
    compensate_scalar,
    compensate_vector,
    output_names,
)
from aeromag_env.compensation.kalman import FilterState
from aeromag_env.compensation.model import FilterConfig
from aeromag_env.compensation.model_apply import apply_tl
from aeromag_env.compensation.model_checks import GAP_FACTOR, segment_starts, spike_threshold_nt
from aeromag_env.compensation.model_drift import tl_residual, vector_residual
from aeromag_env.compensation.samples import flight_samples, vector_inputs
from aeromag_env.compensation.tolles_lawson import TollesLawson
from aeromag_env.configs import to_dict
from aeromag_env.errors import AeromagError
from aeromag_env.flight.data import Flight
from aeromag_env.flight.earth_model import earth_model
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
        if scalar is None:
            raise AeromagError("tl needs a scalar magnetometer (scalar=...)")
        tl = tl or TollesLawson()
        comp = compensate_scalar(flight, flux, scalar, tl, calibration)
        settings = {**_tl_settings(tl), "remove_mean": tl.remove_mean_}
        coefficients = {"tolles_lawson": tl.coef_.tolist(), "offset_nt": 0.0}
        channels: dict[str, str | None] = {"time": "tt", "flux": flux, "scalar": scalar}
    else:
        cfg = filter_cfg or FilterConfig(method=method)
        comp = compensate_vector(flight, method, flux, cfg, calibration, mount, check_mount=False)
        assert comp.filter_end is not None
        settings = {k: v for k, v in to_dict(cfg).items() if k != "method"}
        coefficients = {k: np.asarray(v).tolist() for k, v in comp.filter_end.items()}
        channels = {"time": "tt", "flux": flux, "scalar": None}
    model = CalibrationModel(
        method=method,
        settings=settings,
        coefficients=coefficients,
        channels=channels,
        sample_rate_hz=flight.sample_rate_hz,
        gap_factor=GAP_FACTOR,
        spike_threshold_nt=_thresholds(flight, flux, scalar),
        mount=None if mount is None or method == "tl" else mount.to_dict(),
        provenance=_provenance(provenance),
    )
    if method == "tl" and tl is not None and tl.remove_mean_:
        model = _with_offset(model, flight)
    return _with_calibration(model, flight, comp, calibration), comp


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
    _, correction, _ = apply_tl(model, *_tl_inputs(model, flight))
    finite = np.isfinite(correction)
    offset = float(np.mean(correction[finite])) if finite.any() else 0.0
    return _replace(model, coefficients={**model.coefficients, "offset_nt": offset})


def _replace(model: CalibrationModel, **changes: Any) -> CalibrationModel:
    from dataclasses import replace

    return replace(model, **changes)


def _tl_inputs(model: CalibrationModel, flight: Flight) -> tuple[np.ndarray, ...]:
    names = model.channels
    return flight.tt, flight.vector(names["flux"]), flight[names["scalar"]]


def _with_calibration(
    model: CalibrationModel, flight: Flight, comp: Compensation, calibration: np.ndarray | None
) -> CalibrationModel:
    """``model`` with its ``calibration`` block: what the fit saw, the FOM box by box, and the
    residual of the model applied to the calibration part (the recalibrate check's reference)."""
    part = np.ones(flight.n, bool) if calibration is None else calibration
    applied = apply_model(model, flight, residual_mask=part)
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
    return _replace(model, calibration=block)


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


def apply_model(
    model: CalibrationModel, flight: Flight, residual_mask: np.ndarray | None = None
) -> Compensation:
    """Compensate ``flight`` with a calibrated model (module docstring).

    ``residual_mask`` (n,) bool: the samples the recalibrate residual is measured on (None:
    all). A flight lacking one of the model's channels is a one-line error naming it.
    """
    missing = [nm for nm in model.input_channels() if nm not in flight]
    if missing:
        raise AeromagError(
            f"the flight lacks channel(s) {', '.join(missing)} that the {model.method} model "
            f"needs ({', '.join(model.input_channels())}); recalibrate with this flight's channels"
        )
    if model.method == "tl":
        return _apply_tl(model, flight, residual_mask)
    return _apply_filter(model, flight, residual_mask)


def _apply_tl(model: CalibrationModel, flight: Flight, mask: np.ndarray | None) -> Compensation:
    tt, flux, scalar = _tl_inputs(model, flight)
    after, _correction, flags = apply_tl(model, tt, flux, scalar)
    parts = _parts(flags.starts)
    shown = after if mask is None else np.where(mask, after, np.nan)
    drift = tl_residual(shown, flux, model.sample_rate_hz, parts)
    names = model.channels
    samples = flight_samples(flight, [names["flux"], names["scalar"]], [])
    return Compensation(
        method="tl",
        settings={**_applied(model), "scalar": names["scalar"], "drift": drift},
        coefficients=dict(model.coefficients),
        fields={output_names("tl", names["flux"], names["scalar"])[0]: after},
        total_before=np.asarray(scalar, float),
        total_after=after,
        model_total=None,
        nonfinite=int(np.sum(~flags.valid)),
        samples=_with_valid(samples, flags.valid, parts),
    )


def _parts(starts: np.ndarray) -> list[slice]:
    edges = [*np.flatnonzero(starts), starts.size]
    return [slice(int(a), int(b)) for a, b in itertools.pairwise(edges)]


def _with_valid(samples: Any, valid: np.ndarray, parts: list[slice]) -> Any:
    from dataclasses import replace

    return replace(samples, valid=valid, segments=parts)


def _applied(model: CalibrationModel) -> dict[str, Any]:
    """The settings block of an applied model: the method's, the model's provenance, and the
    same ``flux`` / ``remove_mean`` keys a fit's settings have."""
    return {
        **model.settings,
        "flux": model.channels["flux"],
        "remove_mean": bool(model.settings.get("remove_mean", False)),
        "model": {
            "provenance": model.provenance,
            "calibration_samples": model.calibration.get("samples"),
        },
    }


def _apply_filter(model: CalibrationModel, flight: Flight, mask: np.ndarray | None) -> Compensation:
    """The filter continued from the calibrated state over ``flight`` (it keeps adapting)."""
    cfg = model.filter_config()
    flux = model.channels["flux"]
    samples = flight_samples(flight, vector_inputs(flight, flux), [flux])
    t_b, tdot_b = earth_model(flight, cfg.rate_scheme, samples.segments)
    mount = model.mount_object()
    meas = flight.vector(flux) if mount is None else mount.to_body(flight.vector(flux))
    y = np.where(samples.valid[:, None], meas - t_b, np.nan)
    end = model.filter_end()
    state = continued_filter(cfg, end, y, t_b, tdot_b)
    state.advance(state.n)
    res = state.result()
    known = np.all(np.isfinite(t_b) & np.isfinite(tdot_b), axis=1)
    est = np.where(known[:, None], res.interference, np.nan)
    after = np.where(samples.valid[:, None], meas - est, np.nan)
    y_drift = y if mask is None else np.where(mask[:, None], y, np.nan)
    return Compensation(
        method=model.method,
        settings={**_applied(model), "drift": vector_residual(end["state"], y_drift, t_b, tdot_b)},
        coefficients={"state": res.final_state.tolist()},
        fields=dict(zip(output_names(model.method, flux), [*after.T, *est.T], strict=True)),
        total_before=np.linalg.norm(meas, axis=1),
        total_after=np.linalg.norm(after, axis=1),
        model_total=np.linalg.norm(t_b, axis=1),
        series={"ror": res.ror, "qoq": res.qoq, "q_scale": res.q_scale, "r_scale": res.r_scale},
        divergences=res.divergences,
        outliers_rejected=res.outliers_rejected,
        nonfinite=samples.n_nonfinite,
        samples=samples,
        filter_end={
            "state": res.final_state,
            "covariance": res.final_covariance,
            "process_noise": res.final_q,
            "measurement_noise": res.final_r,
        },
    )


def continued_filter(
    cfg: FilterConfig,
    end: dict[str, np.ndarray],
    y: np.ndarray,
    t_b: np.ndarray,
    tdot_b: np.ndarray,
) -> FilterState:
    """A :class:`FilterState` over ``y``, ``t_b``, ``tdot_b`` (n, 3) that starts where a
    calibration ended: its state, covariance, Q and R (``end``, physical units) in place of the
    configuration's initial ones. The innovation window starts empty."""
    state = FilterState(cfg, y, t_b, tdot_b, store_states=False)
    d = state.d
    state.z[:] = end["state"] / d  # the arrays are updated in place, never replaced
    state.z_good[:] = state.z
    state.p[:] = end["covariance"] / np.outer(d, d)
    state.qd[:] = end["process_noise"] / d**2
    state.rm[:] = end["measurement_noise"]
    return state
