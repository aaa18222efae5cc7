"""Compiled per-sample loop of the recursive compensators (numba).

One loop serves every method of :data:`aeromag_env.compensation.model.METHODS`; it advances a filter
state from sample ``k0`` to ``k1`` so that a caller (the Gymnasium environment) can change Q and R
between decision windows. The plain-numpy reference in
:mod:`aeromag_env.compensation.kalman_reference` implements the same equations line by line and the
two are tested to agree.

Per sample k (normalised state ``z``, ``H_s = H diag(d)``):

* predict (eqs. 17–18): ``z⁻ = z``; ``P⁻ = P + Q`` (RLS: ``P⁻ = P / λ``)
* innovation (eq. 25): ``r = y − H_s z⁻``; ``S = H_s P⁻ H_sᵀ + R``; ``K = P⁻ H_sᵀ S⁻¹`` (eq. 19)
* update: ``z = z⁻ + K r``; Joseph form ``P = (I − K H) P⁻ (I − K H)ᵀ + K R Kᵀ`` (eq. 20 in a
  numerically stable form), expanded as ``P⁻ − K Gᵀ − G Kᵀ + K S Kᵀ`` with ``G = P⁻ H_sᵀ``
  (exact for any K, cost O(21²·3)), then symmetrised
* window statistics (eqs. 22–24): ``C_r`` = mean of ``r rᵀ`` over the last M samples,
  ``ROR = tr(C_r) / mean tr(S)``, ``QOQ = tr(K C_r Kᵀ) / tr(Q)`` in normalised coordinates
* adaptation every ``adapt_interval`` samples once the window is full (``fakf``: eq. 21 with the
  fuzzy scale; ``ding``: ``Q ← Q √α``, ``α = |tr(C_r) − tr R| / |mean tr S − tr R|``); Sage–Husa
  every sample (``R ← (1−d)R + d(e eᵀ + H P⁺ Hᵀ)`` from the post-fit residual ``e``;
  optionally ``Q ← Q + d·diag(K(r rᵀ − S)Kᵀ)``).
* divergence (a non-finite or absurd state — beyond 1e8 typical magnitudes —, a non-finite
  covariance, a non-positive variance, or — checked once per window — a failed Cholesky of P):
  counted, and the filter restarts from the last good state with ``P(0)``, ``Q(0)``, ``R(0)``;
  nothing non-finite is ever written out.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from aeromag_env.compensation.adaptive_rules import adapt, clamp_scales, sage_husa
from aeromag_env.compensation.kernel_layout import (
    ACC_C,
    ACC_RR,
    ACC_S,
    INT_COUNT,
    INT_DIV,
    INT_INTERVAL,
    INT_K,
    INT_POS,
    INT_SINCE,
    INT_SKIP,
    INT_WINDOW,
    MAX_STATE,
    PAR_FORGET,
    PAR_HI,
    PAR_LO,
)


@njit(cache=True)
def _h_row(
    t: np.ndarray, td: np.ndarray, k: int, d: np.ndarray, col: np.ndarray, hv: np.ndarray
) -> None:
    """Non-zeros of the 3 rows of ``H_s(k)``: columns ``col`` (3, 7), values ``hv`` (3, 7)."""
    for i in range(3):
        col[i, 0] = i
        hv[i, 0] = d[i]
        for j in range(3):
            ca = 3 + 3 * i + j
            cb = 12 + 3 * i + j
            col[i, 1 + j] = ca
            hv[i, 1 + j] = t[k, j] * d[ca]
            col[i, 4 + j] = cb
            hv[i, 4 + j] = td[k, j] * d[cb]


@njit(cache=True)
def _inv3(s: np.ndarray, out: np.ndarray) -> bool:
    """Inverse of a symmetric 3×3 matrix by cofactors; False if not positive definite."""
    a, b, c = s[0, 0], s[0, 1], s[0, 2]
    e, f, i = s[1, 1], s[1, 2], s[2, 2]
    c00 = e * i - f * f
    c01 = c * f - b * i
    c02 = b * f - c * e
    det = a * c00 + b * c01 + c * c02
    if not (det > 0.0 and a > 0.0 and a * e - b * b > 0.0):
        return False
    out[0, 0] = c00 / det
    out[0, 1] = out[1, 0] = c01 / det
    out[0, 2] = out[2, 0] = c02 / det
    out[1, 1] = (a * i - c * c) / det
    out[1, 2] = out[2, 1] = (b * c - a * f) / det
    out[2, 2] = (a * e - b * b) / det
    return True


@njit(cache=True)
def _psd(p: np.ndarray, work: np.ndarray) -> bool:
    """Cholesky test of positive definiteness (``work`` is scratch of P's shape)."""
    n = p.shape[0]
    for i in range(n):
        for j in range(i + 1):
            s = p[i, j]
            for m in range(j):
                s -= work[i, m] * work[j, m]
            if i == j:
                if not s > 0.0:
                    return False
                work[i, i] = np.sqrt(s)
            else:
                work[i, j] = s / work[j, j]
    return True


@njit(cache=True)
def _window_add(
    r: np.ndarray, trs: float, rbuf: np.ndarray, sbuf: np.ndarray, acc: np.ndarray, ints: np.ndarray
) -> None:
    """Push one innovation into the circular window and update the running sums."""
    m = ints[INT_WINDOW]
    pos = ints[INT_POS]
    if ints[INT_COUNT] == m:
        old = rbuf[pos]
        acc[ACC_RR] -= old[0] ** 2 + old[1] ** 2 + old[2] ** 2
        acc[ACC_S] -= sbuf[pos]
        for i in range(3):
            for j in range(3):
                acc[ACC_C + 3 * i + j] -= old[i] * old[j]
    rbuf[pos, :] = r
    sbuf[pos] = trs
    acc[ACC_RR] += r[0] ** 2 + r[1] ** 2 + r[2] ** 2
    acc[ACC_S] += trs
    for i in range(3):
        for j in range(3):
            acc[ACC_C + 3 * i + j] += r[i] * r[j]
    ints[INT_POS] = (pos + 1) % m
    ints[INT_COUNT] = min(ints[INT_COUNT] + 1, m)
    if ints[INT_POS] == 0:  # re-sum once per lap: no drift of the running sums
        acc[:] = 0.0
        for w in range(ints[INT_COUNT]):
            acc[ACC_RR] += rbuf[w, 0] ** 2 + rbuf[w, 1] ** 2 + rbuf[w, 2] ** 2
            acc[ACC_S] += sbuf[w]
            for i in range(3):
                for j in range(3):
                    acc[ACC_C + 3 * i + j] += rbuf[w, i] * rbuf[w, j]


@njit(cache=True)
def _qoq(kt: np.ndarray, acc: np.ndarray, count: int, qd: np.ndarray) -> float:
    """``tr(K C_r Kᵀ) / tr(Q)`` in normalised coordinates (NaN when tr Q = 0); ``kt`` is Kᵀ."""
    trq = qd.sum()
    if not trq > 0.0:
        return np.nan
    c = acc[ACC_C : ACC_C + 9]
    num = 0.0
    for a in range(kt.shape[1]):  # the diagonal of K C_r Kᵀ, row by row (independent rows)
        k0, k1, k2 = kt[0, a], kt[1, a], kt[2, a]
        num += (
            k0 * (c[0] * k0 + c[1] * k1 + c[2] * k2)
            + k1 * (c[3] * k0 + c[4] * k1 + c[5] * k2)
            + k2 * (c[6] * k0 + c[7] * k1 + c[8] * k2)
        )
    return num / count / trq


@njit(cache=True)
def _restart(
    z: np.ndarray,
    z_good: np.ndarray,
    p: np.ndarray,
    p0: np.ndarray,
    qd: np.ndarray,
    q0: np.ndarray,
    rm: np.ndarray,
    r0: np.ndarray,
    ints: np.ndarray,
) -> None:
    """Divergence: count it and restart from the last good state with P(0), Q(0), R(0)."""
    ints[INT_DIV] += 1
    z[:] = z_good
    p[:, :] = p0
    qd[:] = q0
    rm[:, :] = r0


@njit(cache=True)
def advance(
    mode: int,
    k0: int,
    k1: int,
    y: np.ndarray,
    t: np.ndarray,
    td: np.ndarray,
    valid: np.ndarray,
    d: np.ndarray,
    z: np.ndarray,
    p: np.ndarray,
    qd: np.ndarray,
    rm: np.ndarray,
    z_good: np.ndarray,
    p0: np.ndarray,
    q0: np.ndarray,
    r0: np.ndarray,
    rbuf: np.ndarray,
    sbuf: np.ndarray,
    acc: np.ndarray,
    ints: np.ndarray,
    par: np.ndarray,
    est: np.ndarray,
    innov: np.ndarray,
    ror: np.ndarray,
    qoq: np.ndarray,
    qscale: np.ndarray,
    rscale: np.ndarray,
    states: np.ndarray,
) -> None:
    """Advance the filter over samples ``k0 ≤ k < k1`` (see the module docstring).

    Inputs (n samples): ``y`` (n, 3) = T_m − T [nT]; ``t``, ``td`` (n, 3) = T [nT], Ṫ [nT/s];
    ``valid`` (n,) bool (False → predict only); ``d`` (21,) state normalisation.
    State (updated in place): ``z`` (21,), ``p`` (21, 21), ``qd`` (21,) diag Q, ``rm`` (3, 3),
    ``z_good``, ``p0``, ``q0``, ``r0`` (restart values), window buffers ``rbuf`` (M, 3),
    ``sbuf`` (M,), ``acc`` (11,), ``ints`` (8,) int64, parameters ``par`` (8,).
    Outputs written at rows k: ``est`` (n, 3) a-priori interference ``H(k) x(k|k−1)`` [nT],
    ``innov`` (n, 3), ``ror``, ``qoq``, ``qscale``, ``rscale`` (n,), ``states`` (n or 0, 21).
    """
    n_state = z.shape[0]
    col = np.empty((3, 7), np.int64)
    hv = np.empty((3, 7))
    # G = P⁻ H_sᵀ, K and K S stored transposed (3, n): the state index is contiguous, so the
    # loops over it vectorise; every sum keeps the order of the equations as written
    gt = np.empty((3, n_state))
    kt = np.zeros((3, n_state))
    kst = np.empty((3, n_state))
    s = np.empty((3, 3))
    sinv = np.empty((3, 3))
    r = np.empty(3)
    work = np.empty_like(p)
    lam = par[PAR_FORGET]
    trq0 = q0.sum()
    trr0 = r0[0, 0] + r0[1, 1] + r0[2, 2]
    for k in range(k0, k1):
        # predict (eqs. 17-18): Φ = I
        if mode == 2:
            p /= lam
        else:
            for a in range(n_state):
                p[a, a] += qd[a]
        _h_row(t, td, k, d, col, hv)
        for i in range(3):
            yhat = 0.0
            for m in range(7):
                yhat += hv[i, m] * z[col[i, m]]
            est[k, i] = yhat
        if not valid[k]:
            innov[k, :] = np.nan
            ints[INT_SKIP] += 1
        else:
            # Gᵀ[i, a] = Σ_m P⁻[a, c_im] h_im, read as P⁻[c_im, a] (P is kept exactly symmetric)
            gt[:, :] = 0.0
            for i in range(3):
                for m in range(7):
                    c, h = col[i, m], hv[i, m]
                    for a in range(n_state):
                        gt[i, a] += p[c, a] * h
            # S = H_s G + R
            for i in range(3):
                for j in range(3):
                    acc_s = rm[i, j]
                    for m in range(7):
                        acc_s += hv[i, m] * gt[j, col[i, m]]
                    s[i, j] = acc_s
                r[i] = y[k, i] - est[k, i]
            innov[k, :] = r
            ok = _inv3(s, sinv)
            if ok:
                for j in range(3):  # K = G S⁻¹ (eq. 19)
                    for a in range(n_state):
                        kt[j, a] = (
                            gt[0, a] * sinv[0, j] + gt[1, a] * sinv[1, j] + gt[2, a] * sinv[2, j]
                        )
                for a in range(n_state):
                    z[a] += kt[0, a] * r[0] + kt[1, a] * r[1] + kt[2, a] * r[2]
                for j in range(3):
                    for a in range(n_state):
                        kst[j, a] = kt[0, a] * s[0, j] + kt[1, a] * s[1, j] + kt[2, a] * s[2, j]
                # Joseph form, expanded: P = P⁻ − K Gᵀ − G Kᵀ + K S Kᵀ, on the lower triangle
                for a in range(n_state):
                    ka0, ka1, ka2 = kt[0, a], kt[1, a], kt[2, a]
                    g0, g1, g2 = gt[0, a], gt[1, a], gt[2, a]
                    s0, s1, s2 = kst[0, a], kst[1, a], kst[2, a]
                    for b in range(a + 1):
                        v = 0.0
                        v += -ka0 * gt[0, b] - g0 * kt[0, b] + s0 * kt[0, b]
                        v += -ka1 * gt[1, b] - g1 * kt[1, b] + s1 * kt[1, b]
                        v += -ka2 * gt[2, b] - g2 * kt[2, b] + s2 * kt[2, b]
                        p[a, b] += v
                for a in range(n_state):  # then mirrored: P exactly symmetric
                    for b in range(a):
                        p[b, a] = p[a, b]
                trs = s[0, 0] + s[1, 1] + s[2, 2]
                _window_add(r, trs, rbuf, sbuf, acc, ints)
                if mode == 3:
                    sage_husa(r, s, sinv, kt, rm, qd, q0, ints[INT_K], par)
            healthy = ok
            for a in range(n_state):
                if not (abs(z[a]) < MAX_STATE and p[a, a] > 0.0 and np.isfinite(p[a, a])):
                    healthy = False
            if healthy and ints[INT_POS] == 0 and not _psd(p, work):
                healthy = False
            if not healthy:
                _restart(z, z_good, p, p0, qd, q0, rm, r0, ints)
            else:
                z_good[:] = z
        count = ints[INT_COUNT]
        ror[k] = acc[ACC_RR] / acc[ACC_S] if count > 0 and acc[ACC_S] > 0.0 else np.nan
        qoq[k] = _qoq(kt, acc, count, qd) if count > 0 and valid[k] else np.nan
        ints[INT_SINCE] += 1
        if (
            (mode == 1 or mode == 4)
            and count == ints[INT_WINDOW]
            and ints[INT_SINCE] >= ints[INT_INTERVAL]
        ):
            adapt(mode, ror[k], qoq[k], acc, ints, qd, rm, par)
            clamp_scales(qd, q0, rm, r0, par[PAR_LO], par[PAR_HI])
            ints[INT_SINCE] = 0
        elif mode == 3:
            clamp_scales(qd, q0, rm, r0, par[PAR_LO], par[PAR_HI])
        qscale[k] = qd.sum() / trq0 if trq0 > 0.0 else np.nan
        rscale[k] = (rm[0, 0] + rm[1, 1] + rm[2, 2]) / trr0
        if states.shape[0] > 0:
            for a in range(n_state):
                states[k, a] = z[a] * d[a]
        ints[INT_K] += 1
