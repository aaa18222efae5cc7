"""Compensate a flight with one method and score it (the library side of ``aeromag compensate``).

Vector methods (the recursive filters of :data:`FILTER_METHODS` — ``kf``, ``fakf``, ``rls``,
``sage-husa``, ``ding``, ``vbakf``, ``vbakf-pr``, ``imm`` — and ``lsq``) estimate the
interference at the fluxgate from ``y = T_m − T``, with ``T`` the model Earth field: IGRF-14 at
the file's positions and date, plus the ``diurnal`` channel along the main-field direction when
present, rotated into body axes with the file's attitude. The scalar method ``tl`` fits the
Tolles–Lawson model to a scalar magnetometer using the fluxgate's direction cosines.

Gaps, spikes and missing values (:mod:`aeromag_env.compensation.samples` decides, in one place):
the Earth-field rate, the band-passes and the design's differences run on each continuous segment
(and each run of finite samples) on its own; flagged samples — a non-finite input the method needs
(fluxgate, attitude, position; scalar for ``tl``), or a spike in the fluxgate or scalar used — are
skipped by the filters' update (predict only) and left out of the ``lsq`` and ``tl`` fits, and
their compensated output is NaN. The interference estimate is NaN only where the model field it
is built from is unknown (non-finite attitude or position).

Our channels are named :data:`OUTPUT_PREFIX` + what they are (:func:`output_names`), a prefix no
vendor uses, so they never replace an input field such as the vendor's ``mag_1_c``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from aeromag_env.compensation import metrics
from aeromag_env.compensation.kalman import run_filter
from aeromag_env.compensation.least_squares import fit_vector_lsq
from aeromag_env.compensation.model import METHODS as RECURSIVE_METHODS
from aeromag_env.compensation.model import FilterConfig, interference_from_states
from aeromag_env.compensation.samples import Samples, flight_samples, vector_inputs, within
from aeromag_env.compensation.tolles_lawson import TollesLawson
from aeromag_env.configs import to_dict
from aeromag_env.errors import AeromagError, warn
from aeromag_env.flight.data import Flight, vector_names
from aeromag_env.flight.earth_model import earth_model, earth_model_ned
from aeromag_env.flight.mounting import Mount, mount_warning, solve_wahba
from aeromag_env.simulation.interference import VectorCoefficients

#: The recursive filters (:data:`aeromag_env.compensation.model.METHODS`).
FILTER_METHODS = RECURSIVE_METHODS
METHODS = (*FILTER_METHODS, "lsq", "tl")
#: Prefix of every channel a compensator writes [-]: ``aeromag_flux_a_c_x``, ``aeromag_mag_1_c``.
OUTPUT_PREFIX = "aeromag_"
#: The vector methods' interference estimate, ``aeromag_interf_est_x/y/z`` [nT].
INTERFERENCE = f"{OUTPUT_PREFIX}interf_est"


def output_names(method: str, flux: str = "flux_a", scalar: str = "mag_1_uc") -> tuple[str, ...]:
    """The channels ``method`` writes: the compensated fluxgate and the interference estimate
    (vector methods), or the compensated scalar (``tl``), each with :data:`OUTPUT_PREFIX`."""
    if method == "tl":
        return (f"{OUTPUT_PREFIX}{scalar.removesuffix('_uc')}_c",)
    return (*vector_names(f"{OUTPUT_PREFIX}{flux}_c"), *vector_names(INTERFERENCE))


@dataclass
class Compensation:
    """What one method produced for one flight.

    Attributes
    ----------
    method : str
    settings : dict (JSON-ready)
    coefficients : dict (JSON-ready): T_p, A, B (vector) or the 18 TL terms
    fields : dict[str, ndarray] — new channels, named by :func:`output_names`
    total_before, total_after : (n,) uncompensated and compensated total field [nT]
    model_total : (n,) model Earth total field [nT], or None when the file has no position/date
    series : dict[str, ndarray] — filter diagnostics (ROR, QOQ, Q and R scales)
    divergences : int, the recursive filter's restarts
        (:class:`~aeromag_env.compensation.kalman.FilterResult`)
    outliers_rejected : int, samples the recursive filter's outlier gate rejected (predict only)
    nonfinite : int
    samples : the segments and flagged samples the method worked with
    filter_end : dict[str, ndarray] or None — a recursive filter's ``state`` (21,),
        ``covariance`` (21, 21), ``process_noise`` (21, Q's diagonal) and ``measurement_noise``
        (3, 3) after the last sample, physical units (what a calibrated model continues from)
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
    outliers_rejected: int = 0
    nonfinite: int = 0
    samples: Samples | None = None
    filter_end: dict[str, np.ndarray] | None = None


#: Fewest samples a vector method accepts: 7 coefficients per axis (T_p, a row of A, a row of
#: B), four samples each, as the batch fit (``lsq``) asks; a recursive filter given fewer only
#: returns its prior.
MIN_VECTOR_SAMPLES = 28


def check_long_enough(flight: Flight, method: str, tl: TollesLawson | None = None) -> None:
    """One-line error when ``flight`` is too short for ``method`` (``tl``: its band-pass, trim
    and coefficients at the flight's sample rate), naming the minimum."""
    if tl is not None:
        tl.check_length(flight.n, flight.sample_rate_hz)
    elif flight.n < MIN_VECTOR_SAMPLES:
        raise AeromagError(
            f"{method} needs a flight of at least {MIN_VECTOR_SAMPLES} samples (7 coefficients "
            f"per axis, 4 samples each); this one has {flight.n}"
        )


def compensate_vector(
    flight: Flight,
    method: str,
    flux: str = "flux_a",
    filter_cfg: FilterConfig | None = None,
    calibration: np.ndarray | None = None,
    mount: Mount | None = None,
    *,
    check_mount: bool = True,
) -> Compensation:
    """Run a vector method; with ``calibration`` (bool mask), fit there and apply everywhere.

    ``mount`` rotates the fluxgate from its own axes into the body frame first
    (:mod:`aeromag_env.flight.mounting`); None takes the sensor axes for body axes. A flight
    shorter than :data:`MIN_VECTOR_SAMPLES` is refused.

    Without a mount (and with ``check_mount``), the mount is estimated from the data
    (:func:`check_body_aligned`): a fluxgate more than
    :data:`~aeromag_env.flight.mounting.WARN_ANGLE_DEG` from the body axes issues an
    :class:`~aeromag_env.errors.AeromagWarning` naming the angle and the fix (the method would
    fit the rotation as induced field: errors of thousands of nT). ``check_mount=False`` is for
    callers that chose the mount themselves (:func:`aeromag_env.compensate` does).
    """
    check_long_enough(flight, method)
    cfg = replace(filter_cfg or FilterConfig(), method=method) if method != "lsq" else filter_cfg
    scheme = "central" if method == "lsq" else (cfg.rate_scheme if cfg else "backward")
    samples = flight_samples(flight, vector_inputs(flight, flux), [flux])
    t_b, tdot_b = earth_model(flight, scheme, samples.segments)
    meas = flight.vector(flux) if mount is None else mount.to_body(flight.vector(flux))
    if mount is None and check_mount:
        check_body_aligned(meas[samples.valid], t_b[samples.valid], flux)
    y = np.where(samples.valid[:, None], meas - t_b, np.nan)  # flagged: predict only / no fit
    state, est, series, counts, settings, end = _estimate(method, cfg, y, t_b, tdot_b, calibration)
    known = np.all(np.isfinite(t_b) & np.isfinite(tdot_b), axis=1)  # the model field is known
    est = np.where(known[:, None], est, np.nan)
    after = np.where(samples.valid[:, None], meas - est, np.nan)
    names = output_names(method, flux)
    return Compensation(
        method=method,
        settings={
            **settings,
            "flux": flux,
            "calibration_samples": _count(calibration),
            **({} if mount is None else {"mount": mount.to_dict()}),
        },
        coefficients=VectorCoefficients.from_state(state).to_dict(),
        fields=dict(zip(names, [*after.T, *est.T], strict=True)),
        total_before=np.linalg.norm(meas, axis=1),
        total_after=np.linalg.norm(after, axis=1),
        model_total=np.linalg.norm(t_b, axis=1),
        series=series,
        divergences=counts[0],
        outliers_rejected=counts[1],
        nonfinite=samples.n_nonfinite,
        samples=samples,
        filter_end=end,
    )


def check_body_aligned(m_sensor: np.ndarray, t_body: np.ndarray, flux: str) -> float | None:
    """Warn when a fluxgate's readings look rotated from the body axes.

    Parameters
    ----------
    m_sensor : ndarray, shape (n, 3)
        The fluxgate's readings, taken for body axes [nT].
    t_body : ndarray, shape (n, 3)
        The model Earth field in body axes at the same samples [nT].
    flux : str
        The fluxgate's id, for the message.

    Returns
    -------
    float or None
        The angle of the estimated mount from the body axes [deg]; None when the data cannot
        tell (too few samples, too little attitude variation: no warning then).

    Warns
    -----
    AeromagWarning
        The angle is more than :data:`~aeromag_env.flight.mounting.WARN_ANGLE_DEG`.
    """
    try:
        estimate = solve_wahba(m_sensor, t_body)
    except AeromagError:
        return None
    message = mount_warning(Mount.identity(), estimate, flux)
    if message:
        warn(
            f"{message}; pass mount=estimate_mount(flight, {flux!r}) (aeromag_env.flight."
            "mounting) or use aeromag_env.compensate, which estimates and applies it"
        )
    return Mount.identity().angle_to_deg(estimate)


def _estimate(
    method: str,
    cfg: FilterConfig | None,
    y: np.ndarray,
    t_b: np.ndarray,
    tdot_b: np.ndarray,
    calibration: np.ndarray | None,
) -> tuple[
    np.ndarray,
    np.ndarray,
    dict[str, np.ndarray],
    tuple[int, int],
    dict[str, Any],
    dict[str, np.ndarray] | None,
]:
    """Final state (21,), interference estimate (n, 3) [nT], filter series, (divergences,
    outliers rejected), settings and the filter's end (:attr:`Compensation.filter_end`; None
    for ``lsq``) of a vector method on ``y = T_m − T`` (NaN rows: skipped / left out)."""
    if method == "lsq":
        fit = fit_vector_lsq(y, t_b, tdot_b, mask=calibration)
        return fit.state, fit.predict(t_b, tdot_b), {}, (0, 0), {"rate_scheme": "central"}, None
    assert cfg is not None
    y_fit = y if calibration is None else np.where(calibration[:, None], y, np.nan)
    res = run_filter(cfg, y_fit, t_b, tdot_b, store_states=False)
    est = (
        res.interference
        if calibration is None
        else interference_from_states(res.final_state, t_b, tdot_b)
    )
    series = {"ror": res.ror, "qoq": res.qoq, "q_scale": res.q_scale, "r_scale": res.r_scale}
    counts = (res.divergences, res.outliers_rejected)
    end = {
        "state": res.final_state,
        "covariance": res.final_covariance,
        "process_noise": res.final_q,
        "measurement_noise": res.final_r,
    }
    return res.final_state, est, series, counts, to_dict(cfg), end


def compensate_scalar(
    flight: Flight, flux: str, scalar: str, tl: TollesLawson, calibration: np.ndarray | None = None
) -> Compensation:
    """Tolles–Lawson fit of ``scalar`` with the direction cosines of ``flux`` (MagNav style).

    The design and the band-pass run on each run of valid samples (both channels finite, no
    spike in either) inside each continuous segment, trimmed per run; the correction is built
    on each run of valid fluxgate samples; the output is NaN where either channel is flagged.
    A flight shorter than ``tl`` needs (:meth:`TollesLawson.length_needed`) is refused.
    """
    check_long_enough(flight, "tl", tl)
    vec, mag = flight.vector(flux), flight[scalar]
    samples = flight_samples(flight, [flux, scalar], [flux, scalar])
    use = samples.valid if calibration is None else samples.valid & calibration
    fit_runs = samples.runs(use)
    if not fit_runs:
        raise AeromagError(f"tl: {scalar}/{flux} have no valid sample to fit")
    tl.fit(vec, mag, flight.sample_rate_hz, runs=fit_runs)
    flux_ok = ~(samples.nonfinite[flux] | samples.spikes[flux])
    correction = tl.predict(vec, runs=samples.runs(flux_ok))
    after = np.where(samples.valid, mag - correction, np.nan)
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
        fields={output_names("tl", flux, scalar)[0]: after},
        total_before=mag,
        total_after=after,
        model_total=_model_total(flight),
        nonfinite=samples.n_nonfinite,
        samples=samples,
    )


def _model_total(flight: Flight) -> np.ndarray | None:
    """|model Earth field| when the file has position and date (rotation-free), else None.

    None too when no sample has a finite position (an all-NaN ``lat``, ``lon`` or ``alt``): the
    residual is then taken about its mean, as without position.
    """
    try:
        total = np.linalg.norm(earth_model_ned(flight), axis=1)
    except KeyError:
        return None
    return total if np.isfinite(total).any() else None


def _count(mask: np.ndarray | None) -> int | None:
    return None if mask is None else int(mask.sum())


def score(flight: Flight, comp: Compensation) -> dict[str, Any]:
    """The ``metrics`` block of ``report.json``.

    Measured after convergence, so that online filters and offline fits compare fairly:
    ``compensation_rmse_nt`` (simulated files), ``residual_std_nt`` and ``improvement_ratio``
    over the second half of the flight; ``fom_nt`` on the last complete compensation box
    (windows ``12b + 1 … 12b + 12``; a one-box flight includes the filters' convergence).
    ``compensation_rmse_all_nt`` covers all samples. Band-passes run on each continuous segment
    and flagged (NaN) samples are left out; ``segments`` and ``flagged_samples`` say what those
    were (:meth:`aeromag_env.compensation.samples.Samples.report`); ``divergences`` and
    ``outliers_rejected`` are the recursive filter's restarts and rejected samples
    (:mod:`aeromag_env.compensation.consistency`), 0 for the fits.
    """
    n, fs = flight.n, flight.sample_rate_hz
    samples = comp.samples or flight_samples(flight, [], [])
    truth, est = _truth_and_estimate(flight, comp)
    half = slice(n // 2, n)
    second_half = np.arange(n) >= n // 2
    line = flight.fields.get("line")
    band_args = (fs, (0.1, 0.9), within(samples.segments, n // 2, n))
    out: dict[str, Any] = {
        "compensation_rmse_nt": None,
        "compensation_rmse_all_nt": None,
        "residual_std_nt": metrics.residual_std(
            _residual(comp)[half], None if line is None else line[half]
        ),
        "improvement_ratio": _safe(
            metrics.improvement_ratio, comp.total_before[half], comp.total_after[half], *band_args
        ),
        "fom_nt": None,
        "fom_uncompensated_nt": None,
        "fom_windows": None,
        "nonfinite_samples": comp.nonfinite,
        "divergences": comp.divergences,
        "outliers_rejected": comp.outliers_rejected,
        **samples.report(),
    }
    if truth is not None:
        out["compensation_rmse_nt"] = metrics.compensation_rmse(truth, est, second_half)
        out["compensation_rmse_all_nt"] = metrics.compensation_rmse(truth, est)
    box = _last_complete_box(flight)
    if box is not None:
        windows = range(12 * box + 1, 12 * box + 13)
        fom_args = (flight.tt, flight.maneuver_ids(), fs, 0.05, windows, samples.segments)
        out["fom_nt"] = _safe(metrics.figure_of_merit, comp.total_after, *fom_args)
        out["fom_uncompensated_nt"] = _safe(metrics.figure_of_merit, comp.total_before, *fom_args)
        out["fom_windows"] = [windows.start, windows.stop - 1]
    for key in ("ror", "qoq"):
        if key in comp.series:  # null when the filter never updated there (calibration window)
            out[key] = _safe_dict(metrics.ratio_statistics, comp.series[key], second_half)
    return out


def held_out_rmse(flight: Flight, comp: Compensation, mask: np.ndarray) -> float | None:
    """RMSE of the interference estimate against the simulator's truth over ``mask`` (the
    samples a fit did not see) [nT]; None without truth or samples."""
    truth, est = _truth_and_estimate(flight, comp)
    if truth is None or not mask.any():
        return None
    return _safe(metrics.compensation_rmse, truth, est, mask)


def _last_complete_box(flight: Flight) -> int | None:
    """Index b of the last box whose 12 windows ``12b + 1 … 12b + 12`` are all present."""
    ids = {m for m, _, _ in flight.maneuver_windows()}
    # only the boxes some id falls in: a corrupt id (2**33) must not make this loop 10**9 times
    boxes = {(m - 1) // 12 for m in ids}
    complete = [b for b in boxes if ids >= set(range(12 * b + 1, 12 * b + 13))]
    return max(complete, default=None)


def _truth_and_estimate(flight: Flight, comp: Compensation) -> tuple[np.ndarray | None, np.ndarray]:
    if comp.method == "tl":
        scalar = comp.settings["scalar"]
        key = f"truth_interf_{scalar.removesuffix('_uc')}"
        est = comp.total_before - comp.total_after
        if key not in flight:
            return None, est
        # a band-passed TL fit cannot see the mean: score the interference with means removed,
        # over the samples both have
        both = np.isfinite(flight[key]) & np.isfinite(est)
        truth, est = np.where(both, flight[key], np.nan), np.where(both, est, np.nan)
        if comp.settings["remove_mean"]:
            return truth - np.nanmean(truth), est - np.nanmean(est)
        return truth, est
    est = np.column_stack([comp.fields[nm] for nm in vector_names(INTERFERENCE)])
    return (flight.vector("truth_interf") if "truth_interf_x" in flight else None), est


def _residual(comp: Compensation) -> np.ndarray:
    """Compensated total field minus the model total field (or minus its mean if no model)."""
    if comp.model_total is not None:
        return comp.total_after - comp.model_total
    return comp.total_after - np.nanmean(comp.total_after)


def _safe_dict(fn: Any, *args: Any) -> dict[str, float] | None:
    """:func:`_safe` for a metric that is a dict of figures."""
    try:
        return dict(fn(*args))
    except AeromagError:
        return None


def _safe(fn: Any, *args: Any) -> float | None:
    """A metric that cannot be computed on this flight (too short, gaps) is reported as null."""
    try:
        return float(fn(*args))
    except AeromagError:
        return None
