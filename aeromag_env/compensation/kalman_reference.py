"""Plain-numpy reference of the recursive compensators, written for reading, not speed.

It mirrors :mod:`aeromag_env.compensation.kernels` (and
:mod:`aeromag_env.compensation.adaptive_rules`, :mod:`aeromag_env.compensation.consistency`)
equation by equation with dense matrices and the factored Joseph form, so the compiled loop is
tested against an independent transcription.
The Kalman steps and the consistency checks it shares with the transcriptions of the
variational filters and the bank (:mod:`aeromag_env.compensation.adaptive_reference`, which
:func:`run_reference` runs for those methods) are in
:mod:`aeromag_env.compensation.reference_steps`.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from aeromag_env.compensation.adaptive_reference import ADAPTIVE_METHODS, run_adaptive_reference
from aeromag_env.compensation.fuzzy import fis_scale_reference
from aeromag_env.compensation.kalman import FilterResult
from aeromag_env.compensation.model import STATE_SCALE, FilterConfig, measurement_rows
from aeromag_env.compensation.reference_steps import Consistency, kf_predict, kf_update, runaway
from aeromag_env.simulation.interference import N_STATES

#: The methods whose own rules move Q and R: a runaway makes them the plain KF.
ADAPTIVE = ("fakf", "ding", "sage-husa")


def run_reference(
    cfg: FilterConfig, y: np.ndarray, t_b: np.ndarray, tdot_b: np.ndarray
) -> FilterResult:
    """Same contract as :func:`aeromag_env.compensation.kalman.run_filter`; of the divergence
    restarts only those of the consistency checks (a sustained shift, an adaptive filter's
    runaway), not those of a non-finite or indefinite covariance. The variational filters and
    the bank are transcribed in :mod:`aeromag_env.compensation.adaptive_reference`."""
    if cfg.method in ADAPTIVE_METHODS:
        return run_adaptive_reference(cfg, y, t_b, tdot_b)
    n, d = y.shape[0], STATE_SCALE
    h_all = measurement_rows(t_b, tdot_b) * d  # H_s = H diag(d)
    valid = np.all(np.isfinite(y), axis=1) & np.all(np.isfinite(h_all), axis=(1, 2))
    z = cfg.initial_state() / d
    p0 = cfg.initial_covariance() / np.outer(d, d)
    q0, r0 = np.diag(cfg.process_noise() / d**2), cfg.measurement_noise()
    p, q, r = p0.copy(), q0.copy(), r0.copy()
    window: list[tuple[np.ndarray, float]] = []
    out = {k: np.full(n, np.nan) for k in ("ror", "qoq", "q_scale", "r_scale")}
    est, innovations = np.full((n, 3), np.nan), np.full((n, 3), np.nan)
    states = np.zeros((n, N_STATES))
    counts = {"skipped": 0, "divergences": 0, "outliers": 0}
    since, gate = 0, Consistency(cfg.window)
    for k in range(n):
        if cfg.method == "rls":
            p = p / cfg.forgetting  # RLS with forgetting: P⁻ = P / λ
        else:
            z, p = kf_predict(z, p, q)
        est[k] = h_all[k] @ z
        gain, rejected, restart = None, False, False
        if not valid[k]:
            counts["skipped"] += 1
        else:
            innovations[k] = y[k] - h_all[k] @ z  # r = y − H x⁻
            s = h_all[k] @ p @ h_all[k].T + r  # S = H P⁻ Hᵀ + R
            rejected = gate.outlier(innovations[k], s, window)
            if rejected:  # predict only; a whole window that shifts the data: restart
                counts["outliers"] += 1
                restart = gate.reject(innovations[k])
            else:
                z, p, q, r, window, gain, restart = _accept(
                    cfg, k, (z, p, q, r), q0, (y, h_all, est, valid), window, gate
                )
        if restart:
            counts["divergences"] += 1
            if cfg.method in ADAPTIVE and not rejected:  # a runaway: go on as the plain KF
                cfg = replace(cfg, method="kf")
            p, q, r, window = p0.copy(), q0.copy(), r0.copy(), []
            gate.clear()
        if window:
            out["ror"][k], out["qoq"][k] = _ratios(window, gain, q)
        if not rejected:  # a rejected sample leaves the window as it was: nothing to adapt to
            since += 1
            r, q, since = _adapted(cfg, k, out, window, r, q, r0, q0, since)
        out["q_scale"][k] = np.trace(q) / np.trace(q0) if np.trace(q0) > 0 else np.nan
        out["r_scale"][k] = np.trace(r) / np.trace(r0)
        states[k] = z * d
    return FilterResult(
        est,
        innovations,
        out["ror"],
        out["qoq"],
        out["q_scale"],
        out["r_scale"],
        states,
        z * d,
        p * np.outer(d, d),
        r,
        np.diag(q) * d**2,
        counts["divergences"],
        counts["skipped"],
        counts["outliers"],
    )


def _ratios(window: list, gain: np.ndarray | None, q: np.ndarray) -> tuple[float, float]:
    """ROR (eq. 22) and QOQ of the window (NaN without a gain or with Q = 0)."""
    c_r = np.mean([np.outer(v, v) for v, _ in window], axis=0)  # eq. 24
    ror = np.trace(c_r) / np.mean([t for _, t in window])
    if gain is None or not np.trace(q) > 0:
        return float(ror), np.nan
    return float(ror), float(np.trace(gain @ c_r @ gain.T) / np.trace(q))


def _accept(cfg, k, filt, q0, data, window, gate):
    """The update with sample k (and Sage–Husa's R, Q) of the filter ``filt = (z, p, q, r)`` on
    ``data = (y, h_all, est, valid)``: ``z, p, q, r, window, gain`` and whether an adaptive
    filter's runaway restarts it (then ``z`` is the last good state)."""
    (z, p, q, r), (y, h_all, est, valid) = filt, data
    z_prior = z
    z, p, innov, s, gain = kf_update(z, p, y[k], h_all[k], r)
    window = ([*window, (innov, float(np.trace(s)))])[-cfg.window :]
    lap = gate.added(window)
    if cfg.method == "sage-husa":
        post_fit = y[k] - h_all[k] @ z  # e = y − H x⁺
        hph_post = h_all[k] @ p @ h_all[k].T  # H P⁺ Hᵀ
        r, q = _sage_husa(cfg, k, innov, s, gain, r, q, q0, post_fit, hph_post)
    restart = cfg.method in ADAPTIVE and lap and runaway(k, cfg.window, y, est, valid)
    return (z_prior if restart else z), p, q, r, window, gain, restart


def _adapted(cfg, k, out, window, r, q, r0, q0, since):
    """The windowed adaptation (fakf, ding) when due, and the clamp: ``r, q, since``."""
    if cfg.method in ("fakf", "ding") and len(window) == cfg.window and since >= cfg.adapt_interval:
        r, q = _adapt(cfg, out["ror"][k], out["qoq"][k], window, r, q)
        return (*_clamp(cfg, r, q, r0, q0), 0)
    if cfg.method == "sage-husa":
        return (*_clamp(cfg, r, q, r0, q0), since)
    return r, q, since


def _adapt(cfg: FilterConfig, ror: float, qoq: float, window: list, r: np.ndarray, q: np.ndarray):
    if cfg.method == "fakf":  # eq. 21 with s = s_FIS ** b
        s_r = 1.0 if np.isnan(ror) else fis_scale_reference(ror, cfg.epsilon) ** cfg.zoom_r
        s_a = 1.0 if np.isnan(qoq) else fis_scale_reference(qoq, cfg.eta) ** cfg.zoom_q
        return r * s_r, q * s_a
    trr = np.trace(r)  # Ding et al. 2007: α = |tr(C_r) − tr R| / |tr(H P⁻ Hᵀ)|
    c_trace = np.mean([v @ v for v, _ in window])
    denom = abs(np.mean([t for _, t in window]) - trr)
    alpha = abs(c_trace - trr) / denom if denom > 0 else 0.0
    return r, (q * np.sqrt(alpha) if alpha > 0 else q)


def _sage_husa(cfg, k, innov, s, gain, r, q, q0, post_fit, hph_post):
    """R from the post-fit residual (always positive definite), optional Q (as
    :func:`aeromag_env.compensation.adaptive_rules.sage_husa`)."""
    dk = (1 - cfg.sage_husa_b) / (1 - cfg.sage_husa_b ** (k + 1))
    if cfg.sage_husa_form == "innovation":
        r_new = (1 - dk) * r + dk * (np.outer(innov, innov) - (s - r))
        if not np.all(np.linalg.eigvalsh(r_new) > 0):  # biased, positive definite fallback
            r_new = (1 - dk) * r + dk * np.outer(innov, innov)
    else:
        r_new = (1 - dk) * r + dk * (np.outer(post_fit, post_fit) + hph_post)
    if not cfg.sage_husa_q:
        return r_new, q
    dq = np.diag(gain @ (np.outer(innov, innov) - s) @ gain.T)
    return r_new, np.diag(np.maximum(np.diag(q) + dk * dq, cfg.scale_bounds[0] * np.diag(q0)))


def _clamp(cfg, r, q, r0, q0):
    lo, hi = cfg.scale_bounds
    if np.trace(q0) > 0:
        ratio = np.trace(q) / np.trace(q0)
        q = q * (np.clip(ratio, lo, hi) / ratio)
    ratio = np.trace(r) / np.trace(r0)
    return r * (np.clip(ratio, lo, hi) / ratio), q
