"""Compensate a flight with one method and score it (the library side of ``aeromag compensate``).

Vector methods (``kf``, ``fakf``, ``rls``, ``sage-husa``, ``ding``, ``lsq``) estimate the
interference at the fluxgate from ``y = T_m − T``, with ``T`` the model Earth field: IGRF-14 at
the file's positions and date, plus the ``diurnal`` channel along the main-field direction when
present, rotated into body axes with the file's attitude. The scalar method ``tl`` fits the
Tolles–Lawson model to a scalar magnetometer using the fluxgate's direction cosines.

Non-finite samples: the filters skip them (predict only) and count them; ``lsq`` and ``tl`` leave
them out of the fit; outputs at those samples are NaN only where an input needed there is NaN.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from aeromag_env.compensation import metrics
from aeromag_env.compensation.dsp import is_all_pass
from aeromag_env.compensation.kalman import run_filter
from aeromag_env.compensation.least_squares import fit_vector_lsq
from aeromag_env.compensation.model import FilterConfig, interference_from_states
from aeromag_env.compensation.tolles_lawson import TollesLawson
from aeromag_env.configs import to_dict
from aeromag_env.errors import AeromagError
from aeromag_env.flight.data import Flight, vector_names
from aeromag_env.flight.earth_model import earth_model, earth_model_ned
from aeromag_env.flight.mounting import Mount
from aeromag_env.simulation.interference import VectorCoefficients

FILTER_METHODS = ("kf", "fakf", "rls", "sage-husa", "ding")
METHODS = (*FILTER_METHODS, "lsq", "tl")


@dataclass
class Compensation:
    """What one method produced for one flight.

    Attributes
    ----------
    method : str
    settings : dict (JSON-ready)
    coefficients : dict (JSON-ready): T_p, A, B (vector) or the 18 TL terms
    fields : dict[str, ndarray] — new channels (``flux_a_c_*``, ``interf_est_*`` or ``mag_1_c``…)
    total_before, total_after : (n,) uncompensated and compensated total field [nT]
    model_total : (n,) model Earth total field [nT], or None when the file has no position/date
    series : dict[str, ndarray] — filter diagnostics (ROR, QOQ, Q and R scales)
    divergences, nonfinite : int
    """

    method: str
    settings: dict[str, Any]
    coefficients: dict[str, Any]
    fields: dict[str, np.ndarray]
    total_before: np.ndarray
    total_after: np.ndarray
    model_total: np.ndarray | None = None
    series: dict[str, np.ndarray] = field(default_factory=dict)
    divergences: int = 0
    nonfinite: int = 0


def compensate_vector(
    flight: Flight,
    method: str,
    flux: str = "flux_a",
    filter_cfg: FilterConfig | None = None,
    calibration: np.ndarray | None = None,
    mount: Mount | None = None,
) -> Compensation:
    """Run a vector method; with ``calibration`` (bool mask), fit there and apply everywhere.

    ``mount`` rotates the fluxgate from its own axes into the body frame first
    (:mod:`aeromag_env.flight.mounting`); None takes the sensor axes for body axes.
    """
    cfg = replace(filter_cfg or FilterConfig(), method=method) if method != "lsq" else filter_cfg
    scheme = "central" if method == "lsq" else (cfg.rate_scheme if cfg else "backward")
    t_b, tdot_b = earth_model(flight, scheme)
    meas = flight.vector(flux) if mount is None else mount.to_body(flight.vector(flux))
    y = meas - t_b
    series: dict[str, np.ndarray] = {}
    divergences = 0
    if method == "lsq":
        fit = fit_vector_lsq(y, t_b, tdot_b, mask=calibration)
        state, est = fit.state, fit.predict(t_b, tdot_b)
        settings: dict[str, Any] = {"rate_scheme": scheme}
    else:
        assert cfg is not None
        y_fit = y if calibration is None else np.where(calibration[:, None], y, np.nan)
        res = run_filter(cfg, y_fit, t_b, tdot_b, store_states=False)
        state = res.final_state
        est = (
            res.interference
            if calibration is None
            else interference_from_states(state, t_b, tdot_b)
        )
        series = {"ror": res.ror, "qoq": res.qoq, "q_scale": res.q_scale, "r_scale": res.r_scale}
        divergences = res.divergences
        settings = to_dict(cfg)
    after = meas - est
    fields = dict(zip(vector_names(f"{flux}_c"), after.T, strict=True))
    fields.update(zip(vector_names("interf_est"), est.T, strict=True))
    nonfinite = int(np.sum(~np.all(np.isfinite(y) & np.isfinite(tdot_b), axis=1)))
    return Compensation(
        method=method,
        settings={
            **settings,
            "flux": flux,
            "calibration_samples": _count(calibration),
            **({} if mount is None else {"mount": mount.to_dict()}),
        },
        coefficients=VectorCoefficients.from_state(state).to_dict(),
        fields=fields,
        total_before=np.linalg.norm(meas, axis=1),
        total_after=np.linalg.norm(after, axis=1),
        model_total=np.linalg.norm(t_b, axis=1),
        series=series,
        divergences=divergences,
        nonfinite=nonfinite,
    )


def compensate_scalar(
    flight: Flight, flux: str, scalar: str, tl: TollesLawson, calibration: np.ndarray | None = None
) -> Compensation:
    """Tolles–Lawson fit of ``scalar`` with the direction cosines of ``flux`` (MagNav style)."""
    vec, mag = flight.vector(flux), flight[scalar]
    use = np.all(np.isfinite(vec), axis=1) & np.isfinite(mag)
    if calibration is not None:
        use &= calibration
    k = np.flatnonzero(use)
    filtering = tl.bandpass_hz is not None and not is_all_pass(
        flight.sample_rate_hz, *tl.bandpass_hz
    )
    if k.size == 0 or (filtering and k.size != k[-1] - k[0] + 1):
        raise AeromagError(
            f"tl: {scalar}/{flux} have non-finite samples inside the fit span; the band-pass "
            "filter needs a contiguous span (use --calibration-window or --tl-bandpass none)"
        )
    tl.fit(vec[k[0] : k[-1] + 1], mag[k[0] : k[-1] + 1], flight.sample_rate_hz)
    correction = tl.predict(np.where(np.isfinite(vec), vec, np.nan))
    after = mag - correction
    name = scalar.removesuffix("_uc") + "_c"
    return Compensation(
        method="tl",
        settings={
            "flux": flux,
            "scalar": scalar,
            "bandpass_hz": tl.bandpass_hz,
            "trim": tl.trim,
            "ridge": tl.ridge,
            "remove_mean": tl.remove_mean_,
            "calibration_samples": _count(calibration),
        },
        coefficients={"tolles_lawson": tl.coef_.tolist(), "residual_std_nt": tl.residual_std_nt_},
        fields={name: after},
        total_before=mag,
        total_after=after,
        model_total=_model_total(flight),
        nonfinite=int(np.sum(~use)) if calibration is None else int(np.sum(~np.isfinite(mag))),
    )


def _model_total(flight: Flight) -> np.ndarray | None:
    """|model Earth field| when the file has position and date (rotation-free), else None."""
    try:
        return np.linalg.norm(earth_model_ned(flight), axis=1)
    except KeyError:
        return None


def _count(mask: np.ndarray | None) -> int | None:
    return None if mask is None else int(mask.sum())


def score(flight: Flight, comp: Compensation) -> dict[str, Any]:
    """The ``metrics`` block of ``report.json``.

    Measured after convergence, so that online filters and offline fits compare fairly:
    ``compensation_rmse_nt`` (simulated files), ``residual_std_nt`` and ``improvement_ratio``
    over the second half of the flight; ``fom_nt`` on the last complete compensation box
    (windows ``12b + 1 … 12b + 12``; a one-box flight includes the filters' convergence).
    ``compensation_rmse_all_nt`` covers all samples.
    """
    n, fs = flight.n, flight.sample_rate_hz
    truth, est = _truth_and_estimate(flight, comp)
    half = slice(n // 2, n)
    second_half = np.arange(n) >= n // 2
    line = flight.fields.get("line")
    out: dict[str, Any] = {
        "compensation_rmse_nt": None,
        "compensation_rmse_all_nt": None,
        "residual_std_nt": metrics.residual_std(
            _residual(comp)[half], None if line is None else line[half]
        ),
        "improvement_ratio": _safe(
            metrics.improvement_ratio, comp.total_before[half], comp.total_after[half], fs
        ),
        "fom_nt": None,
        "fom_uncompensated_nt": None,
        "fom_windows": None,
        "nonfinite_samples": comp.nonfinite,
        "divergences": comp.divergences,
    }
    if truth is not None:
        out["compensation_rmse_nt"] = metrics.compensation_rmse(truth, est, second_half)
        out["compensation_rmse_all_nt"] = metrics.compensation_rmse(truth, est)
    box = _last_complete_box(flight)
    if box is not None:
        windows = range(12 * box + 1, 12 * box + 13)
        fom_args = (flight.tt, flight["maneuver"], fs, 0.05, windows)
        out["fom_nt"] = _safe(metrics.figure_of_merit, comp.total_after, *fom_args)
        out["fom_uncompensated_nt"] = _safe(metrics.figure_of_merit, comp.total_before, *fom_args)
        out["fom_windows"] = [windows.start, windows.stop - 1]
    for key in ("ror", "qoq"):
        if key in comp.series:
            out[key] = metrics.ratio_statistics(comp.series[key], second_half)
    return out


def _last_complete_box(flight: Flight) -> int | None:
    """Index b of the last box whose 12 windows ``12b + 1 … 12b + 12`` are all present."""
    ids = {m for m, _, _ in flight.maneuver_windows()}
    complete = [
        b
        for b in range(max(ids, default=0) // 12 + 1)
        if ids >= set(range(12 * b + 1, 12 * b + 13))
    ]
    return complete[-1] if complete else None


def _truth_and_estimate(flight: Flight, comp: Compensation) -> tuple[np.ndarray | None, np.ndarray]:
    if comp.method == "tl":
        scalar = comp.settings["scalar"]
        key = f"truth_interf_{scalar.removesuffix('_uc')}"
        est = comp.total_before - comp.total_after
        if key not in flight:
            return None, est
        # a band-passed TL fit cannot see the mean: score the interference with means removed
        truth = flight[key]
        if comp.settings["remove_mean"]:
            return truth - np.nanmean(truth), est - np.nanmean(est)
        return truth, est
    est = np.column_stack([comp.fields[nm] for nm in vector_names("interf_est")])
    return (flight.vector("truth_interf") if "truth_interf_x" in flight else None), est


def _residual(comp: Compensation) -> np.ndarray:
    """Compensated total field minus the model total field (or minus its mean if no model)."""
    if comp.model_total is not None:
        return comp.total_after - comp.model_total
    return comp.total_after - np.nanmean(comp.total_after)


def _safe(fn: Any, *args: Any) -> float | None:
    """A metric that cannot be computed on this flight (too short, gaps) is reported as null."""
    try:
        return float(fn(*args))
    except AeromagError:
        return None
