"""Plain-numpy reference of the recursive compensators, written for reading, not speed.

It mirrors :mod:`aeromag_env.compensation.kernels` (and
:mod:`aeromag_env.compensation.adaptive_rules`) equation by equation with dense matrices and the
factored Joseph form, so the compiled loop is tested against an independent transcription.
Pure functions (``kf_predict``, ``kf_update``) follow filterpy's procedural style.
"""

from __future__ import annotations

import numpy as np

from aeromag_env.compensation.fuzzy import fis_scale_reference
from aeromag_env.compensation.kalman import FilterResult
from aeromag_env.compensation.model import STATE_SCALE, FilterConfig, measurement_rows
from aeromag_env.simulation.interference import N_STATES


def kf_predict(x: np.ndarray, p: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eqs. 17–18 with ``Φ = I``: ``x⁻ = x``, ``P⁻ = P + Q``."""
    return x.copy(), p + q  # P⁻ = Φ P Φᵀ + Q


def kf_update(
    x: np.ndarray, p: np.ndarray, y: np.ndarray, h: np.ndarray, r: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Eqs. 19–20, Joseph form. Returns ``x⁺, P⁺, innovation, S, K``.

    Shapes: x (21,), p (21, 21), y (3,), h (3, 21), r (3, 3).
    """
    innov = y - h @ x  # r = y − H x⁻
    s = h @ p @ h.T + r  # S = H P⁻ Hᵀ + R
    k = p @ h.T @ np.linalg.inv(s)  # K = P⁻ Hᵀ S⁻¹
    i_kh = np.eye(x.size) - k @ h
    p_new = i_kh @ p @ i_kh.T + k @ r @ k.T  # Joseph: (I − KH) P⁻ (I − KH)ᵀ + K R Kᵀ
    return x + k @ innov, 0.5 * (p_new + p_new.T), innov, s, k


def run_reference(
    cfg: FilterConfig, y: np.ndarray, t_b: np.ndarray, tdot_b: np.ndarray
) -> FilterResult:
    """Same contract as :func:`aeromag_env.compensation.kalman.run_filter` (no divergence
    restarts)."""
    n, d = y.shape[0], STATE_SCALE
    h_all = measurement_rows(t_b, tdot_b) * d  # H_s = H diag(d)
    z = cfg.initial_state() / d
    p = cfg.initial_covariance() / np.outer(d, d)
    q = np.diag(cfg.process_noise() / d**2)
    q0, r0 = q.copy(), cfg.measurement_noise()
    r = r0.copy()
    window: list[tuple[np.ndarray, float]] = []
    out = {k: np.full(n, np.nan) for k in ("ror", "qoq", "q_scale", "r_scale")}
    est, innovations = np.full((n, 3), np.nan), np.full((n, 3), np.nan)
    states = np.zeros((n, N_STATES))
    skipped, since = 0, 0
    for k in range(n):
        if cfg.method == "rls":
            p = p / cfg.forgetting  # RLS with forgetting: P⁻ = P / λ
        else:
            z, p = kf_predict(z, p, q)
        est[k] = h_all[k] @ z
        gain = None
        if not (np.all(np.isfinite(y[k])) and np.all(np.isfinite(h_all[k]))):
            skipped += 1
        else:
            z, p, innov, s, gain = kf_update(z, p, y[k], h_all[k], r)
            innovations[k] = innov
            window = ([*window, (innov, float(np.trace(s)))])[-cfg.window :]
            if cfg.method == "sage-husa":
                post_fit = y[k] - h_all[k] @ z  # e = y − H x⁺
                hph_post = h_all[k] @ p @ h_all[k].T  # H P⁺ Hᵀ
                r, q = _sage_husa(cfg, k, innov, s, gain, r, q, q0, post_fit, hph_post)
        if window:
            c_r = np.mean([np.outer(v, v) for v, _ in window], axis=0)  # eq. 24
            out["ror"][k] = np.trace(c_r) / np.mean([t for _, t in window])  # eq. 22
            if gain is not None and np.trace(q) > 0:
                out["qoq"][k] = np.trace(gain @ c_r @ gain.T) / np.trace(q)
        since += 1
        if (
            cfg.method in ("fakf", "ding")
            and len(window) == cfg.window
            and since >= cfg.adapt_interval
        ):
            r, q = _adapt(cfg, out["ror"][k], out["qoq"][k], window, r, q)
            r, q = _clamp(cfg, r, q, r0, q0)
            since = 0
        elif cfg.method == "sage-husa":
            r, q = _clamp(cfg, r, q, r0, q0)
        out["q_scale"][k] = np.trace(q) / np.trace(q0) if np.trace(q0) > 0 else np.nan
        out["r_scale"][k] = np.trace(r) / np.trace(r0)
        states[k] = z * d
    return FilterResult(
        est, innovations, out["ror"], out["qoq"], out["q_scale"], out["r_scale"],
        states, z * d, p * np.outer(d, d), r, np.diag(q) * d**2, 0, skipped,
    )  # fmt: skip


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
