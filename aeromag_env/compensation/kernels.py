"""Compiled per-sample loop of the recursive compensators (numba).

One loop serves every method of :data:`aeromag_env.compensation.model.METHODS` (coded by
:class:`~aeromag_env.compensation.model.FilterMode`); it advances a filter's arrays
(:class:`aeromag_env.compensation.arrays.FilterArrays`) from sample ``k0`` to ``k1`` so that a
caller (the Gymnasium environment) can change Q and R between decision windows. The plain-numpy
reference in :mod:`aeromag_env.compensation.kalman_reference` implements the same equations line
by line and the two are tested to agree.

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
  optionally ``Q ← Q + d·diag(K(r rᵀ − S)Kᵀ)``); these rules are in
  :mod:`aeromag_env.compensation.adaptive_rules`.
* consistency (:mod:`aeromag_env.compensation.consistency`): an outlier — an innovation far
  beyond both ``S`` and the recent innovations — is rejected (predict only, the window and the
  adaptation left as they were) and counted; a whole window of outliers that shift the data,
  or an adaptive filter's runaway, is a divergence that also empties the window
* divergence (a non-finite or absurd state — beyond 1e8 typical magnitudes —, a non-finite
  covariance, a non-positive variance, or — checked once per window — a failed Cholesky of P;
  or one of the consistency checks above): counted, and the filter restarts from the last good
  state with ``P(0)``, ``Q(0)``, ``R(0)``; nothing non-finite is ever written out.
"""

from __future__ import annotations

import numpy as np

from aeromag_env.compensation.adaptive_rules import adapt, clamp_scales, sage_husa
from aeromag_env.compensation.arrays import FilterArrays, Packed, named
from aeromag_env.compensation.consistency import clear_window, outlier, reject, runaway
from aeromag_env.compensation.kernel_layout import ACC, INTS, MAX_STATE, PAR
from aeromag_env.compensation.model import FilterMode
from aeromag_env.compensation.window import window_add
from aeromag_env.numba_cache import njit
from aeromag_env.simulation.interference import EDDY_START, INDUCED_START, PERMANENT_START

#: The non-zeros of row i of ``H_s`` in the order they are stored: ``T_p,i`` at 0, ``A_i·`` from
#: 1, ``B_i·`` from 4; 7 in all.
NZ_PERMANENT, NZ_INDUCED, NZ_EDDY, H_NNZ = 0, 1, 4, 7

#: How the helpers the loop calls for every sample are compiled: they neither allocate nor copy
#: arrays, so without numba's runtime (its reference counting): ``_nrt=False``, an option numba's
#: type stubs do not list; a helper that needed the runtime would fail to compile, loudly. With
#: the runtime every call pays two atomic operations per array passed, and the loop split into
#: these helpers ran ~25% slower than the same code as one function (1.0 against 1.36 M samples/s
#: on one flight); without, within ~5%. Dropping the option changes the speed, not the results.
per_sample = njit(cache=True, _nrt=False)  # type: ignore[call-overload]


@per_sample
def _h_row(
    t: np.ndarray, td: np.ndarray, k: int, d: np.ndarray, col: np.ndarray, hv: np.ndarray
) -> None:
    """Non-zeros of the 3 rows of ``H_s(k)``: columns ``col`` (3, 7), values ``hv`` (3, 7)."""
    for i in range(3):
        col[i, NZ_PERMANENT] = PERMANENT_START + i
        hv[i, NZ_PERMANENT] = d[PERMANENT_START + i]
        for j in range(3):
            ca = INDUCED_START + 3 * i + j
            cb = EDDY_START + 3 * i + j
            col[i, NZ_INDUCED + j] = ca
            hv[i, NZ_INDUCED + j] = t[k, j] * d[ca]
            col[i, NZ_EDDY + j] = cb
            hv[i, NZ_EDDY + j] = td[k, j] * d[cb]


@per_sample
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


@per_sample
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


@per_sample
def _qoq(kt: np.ndarray, acc: np.ndarray, count: int, qd: np.ndarray) -> float:
    """``tr(K C_r Kᵀ) / tr(Q)`` in normalised coordinates (NaN when tr Q = 0); ``kt`` is Kᵀ."""
    trq = qd.sum()
    if not trq > 0.0:
        return np.nan
    c = acc[ACC.c : ACC.c + 9]
    num = 0.0
    for a in range(kt.shape[1]):  # the diagonal of K C_r Kᵀ, row by row (independent rows)
        k0, k1, k2 = kt[0, a], kt[1, a], kt[2, a]
        num += (
            k0 * (c[0] * k0 + c[1] * k1 + c[2] * k2)
            + k1 * (c[3] * k0 + c[4] * k1 + c[5] * k2)
            + k2 * (c[6] * k0 + c[7] * k1 + c[8] * k2)
        )
    return num / count / trq


@per_sample
def _predict(mode: int, lam: float, p: np.ndarray, qd: np.ndarray) -> None:
    """Eqs. 17–18 with ``Φ = I``: ``P⁻ = P + Q`` (RLS: ``P⁻ = P / λ``); ``z⁻ = z``."""
    if mode == FilterMode.RLS:
        p /= lam
    else:
        for a in range(p.shape[0]):
            p[a, a] += qd[a]


@per_sample
def _estimate(
    k: int,
    t: np.ndarray,
    td: np.ndarray,
    d: np.ndarray,
    z: np.ndarray,
    col: np.ndarray,
    hv: np.ndarray,
    est: np.ndarray,
) -> None:
    """``H_s(k)`` into ``col``, ``hv`` and the a-priori interference ``H_s z⁻`` into ``est[k]``."""
    _h_row(t, td, k, d, col, hv)
    for i in range(3):
        yhat = 0.0
        for m in range(H_NNZ):
            yhat += hv[i, m] * z[col[i, m]]
        est[k, i] = yhat


@per_sample
def _innovation(
    k: int,
    y: np.ndarray,
    est: np.ndarray,
    p: np.ndarray,
    rm: np.ndarray,
    col: np.ndarray,
    hv: np.ndarray,
    gt: np.ndarray,
    s: np.ndarray,
    r: np.ndarray,
) -> None:
    """``Gᵀ`` (``gt``), ``S = H_s G + R`` (``s``) and ``r = y − H_s z⁻`` (``r``) of sample k."""
    n_state = p.shape[0]
    # Gᵀ[i, a] = Σ_m P⁻[a, c_im] h_im, read as P⁻[c_im, a] (P is kept exactly symmetric)
    gt[:, :] = 0.0
    for i in range(3):
        for m in range(H_NNZ):
            c, h = col[i, m], hv[i, m]
            for a in range(n_state):
                gt[i, a] += p[c, a] * h
    for i in range(3):  # S = H_s G + R
        for j in range(3):
            acc_s = rm[i, j]
            for m in range(H_NNZ):
                acc_s += hv[i, m] * gt[j, col[i, m]]
            s[i, j] = acc_s
        r[i] = y[k, i] - est[k, i]


@per_sample
def _update(
    z: np.ndarray,
    p: np.ndarray,
    gt: np.ndarray,
    kt: np.ndarray,
    kst: np.ndarray,
    s: np.ndarray,
    sinv: np.ndarray,
    r: np.ndarray,
) -> None:
    """``K = G S⁻¹`` (eq. 19, into ``kt``), ``z = z⁻ + K r`` and the Joseph form, expanded:
    ``P = P⁻ − K Gᵀ − G Kᵀ + K S Kᵀ`` on the lower triangle, then mirrored (P exactly
    symmetric)."""
    n_state = z.shape[0]
    for j in range(3):
        for a in range(n_state):
            kt[j, a] = gt[0, a] * sinv[0, j] + gt[1, a] * sinv[1, j] + gt[2, a] * sinv[2, j]
    for a in range(n_state):
        z[a] += kt[0, a] * r[0] + kt[1, a] * r[1] + kt[2, a] * r[2]
    for j in range(3):
        for a in range(n_state):
            kst[j, a] = kt[0, a] * s[0, j] + kt[1, a] * s[1, j] + kt[2, a] * s[2, j]
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
    for a in range(n_state):
        for b in range(a):
            p[b, a] = p[a, b]


@per_sample
def _healthy(ok: bool, z: np.ndarray, p: np.ndarray, ints: np.ndarray, work: np.ndarray) -> bool:
    """The update went through (``ok``), the state is finite and not absurd, the variances are
    positive and finite, and — once per window — P passes a Cholesky test."""
    healthy = ok
    for a in range(z.shape[0]):
        if not (abs(z[a]) < MAX_STATE and p[a, a] > 0.0 and np.isfinite(p[a, a])):
            healthy = False
    if healthy and ints[INTS.pos] == 0 and not _psd(p, work):
        healthy = False
    return healthy


@per_sample
def _store_row(x: np.ndarray, k: int, x0: float, x1: float, x2: float) -> None:
    """Row k of the (n, 3) array ``x``: ``(x0, x1, x2)`` (element by element: a slice
    assignment would need numba's runtime)."""
    x[k, 0], x[k, 1], x[k, 2] = x0, x1, x2


@per_sample
def _copy(src: np.ndarray, dst: np.ndarray) -> None:
    """``dst[:] = src`` for vectors, element by element."""
    for a in range(src.shape[0]):
        dst[a] = src[a]


@njit(cache=True)  # on a divergence only; copies arrays: needs the runtime
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
    ints[INTS.div] += 1
    z[:] = z_good
    p[:, :] = p0
    qd[:] = q0
    rm[:, :] = r0


@per_sample
def _statistics(
    k: int,
    valid: bool,
    ints: np.ndarray,
    acc: np.ndarray,
    kt: np.ndarray,
    qd: np.ndarray,
    ror: np.ndarray,
    qoq: np.ndarray,
) -> None:
    """ROR and QOQ of the window at sample k (eqs. 22–24; NaN before data)."""
    count = ints[INTS.updates]
    ror[k] = acc[ACC.rr] / acc[ACC.s] if count > 0 and acc[ACC.s] > 0.0 else np.nan
    qoq[k] = _qoq(kt, acc, count, qd) if count > 0 and valid else np.nan


@per_sample
def _adapt(
    mode: int,
    ror: float,
    qoq: float,
    ints: np.ndarray,
    par: np.ndarray,
    acc: np.ndarray,
    qd: np.ndarray,
    q0: np.ndarray,
    rm: np.ndarray,
    r0: np.ndarray,
) -> None:
    """``fakf``, ``ding``: adapt Q and R from the window statistics ``ror``, ``qoq`` once the
    window is full, every ``adapt_interval`` samples; then (and after every Sage–Husa sample)
    clamp their scales."""
    ints[INTS.since] += 1
    if (
        (mode == FilterMode.FAKF or mode == FilterMode.DING)
        and ints[INTS.updates] == ints[INTS.window]
        and ints[INTS.since] >= ints[INTS.interval]
    ):
        adapt(mode, ror, qoq, acc, ints, qd, rm, par)
        clamp_scales(qd, q0, rm, r0, par[PAR.lo], par[PAR.hi])
        ints[INTS.since] = 0
    elif mode == FilterMode.SAGE_HUSA:
        clamp_scales(qd, q0, rm, r0, par[PAR.lo], par[PAR.hi])


@per_sample
def _record(
    k: int,
    trq0: float,
    trr0: float,
    qd: np.ndarray,
    rm: np.ndarray,
    z: np.ndarray,
    d: np.ndarray,
    q_scale: np.ndarray,
    r_scale: np.ndarray,
    states: np.ndarray,
) -> None:
    """Q and R scales and (when kept) the posterior state in physical units at row k."""
    q_scale[k] = qd.sum() / trq0 if trq0 > 0.0 else np.nan
    r_scale[k] = (rm[0, 0] + rm[1, 1] + rm[2, 2]) / trr0
    if states.shape[0] > 0:
        for a in range(z.shape[0]):
            states[k, a] = z[a] * d[a]


@njit(cache=True)
def advance(mode: int, k0: int, k1: int, arrays: FilterArrays | Packed) -> None:
    """Advance the filter over samples ``k0 ≤ k < k1`` (see the module docstring).

    ``mode`` is a :class:`~aeromag_env.compensation.model.FilterMode`; of the filter's
    ``arrays`` (:class:`~aeromag_env.compensation.arrays.FilterArrays`, or packed) the signals
    are read, the state and window updated in place and the outputs written at rows k.
    """
    f = named(arrays)
    y, t, td, valid = f.signals
    d, z, p, qd, rm, z_good, p0, q0, r0, ints, par = f.state
    rbuf, sbuf, acc = f.window
    est, innov, ror, qoq, q_scale, r_scale, states = f.outputs
    n_state = z.shape[0]
    col, hv = np.empty((3, H_NNZ), np.int64), np.empty((3, H_NNZ))
    # G = P⁻ H_sᵀ, K and K S stored transposed (3, n): the state index is contiguous, so the
    # loops over it vectorise; every sum keeps the order of the equations as written
    gt, kt, kst = np.empty((3, n_state)), np.zeros((3, n_state)), np.empty((3, n_state))
    s, sinv, r = np.empty((3, 3)), np.empty((3, 3)), np.empty(3)
    work = np.empty_like(p)
    lam = par[PAR.forget]
    trq0 = q0.sum()
    trr0 = r0[0, 0] + r0[1, 1] + r0[2, 2]
    if ints[INTS.fell_back]:  # an adaptive filter that ran away goes on as the plain KF
        mode = FilterMode.KF
    adaptive = mode == FilterMode.FAKF or mode == FilterMode.DING or mode == FilterMode.SAGE_HUSA
    for k in range(k0, k1):
        _predict(mode, lam, p, qd)
        _estimate(k, t, td, d, z, col, hv, est)
        rejected = False
        if not valid[k]:
            _store_row(innov, k, np.nan, np.nan, np.nan)
            ints[INTS.skip] += 1
        else:
            _innovation(k, y, est, p, rm, col, hv, gt, s, r)
            _store_row(innov, k, r[0], r[1], r[2])
            ok = _inv3(s, sinv)
            rejected = ok and outlier(r, sinv, acc, ints)
            inconsistent = rejected and reject(r, acc, ints)  # a window of shifted outliers
            if not rejected:
                if ok:
                    _update(z, p, gt, kt, kst, s, sinv, r)
                    window_add(r, s[0, 0] + s[1, 1] + s[2, 2], rbuf, sbuf, acc, ints)
                    if mode == FilterMode.SAGE_HUSA:
                        sage_husa(r, s, sinv, kt, rm, qd, q0, ints[INTS.base] + ints[INTS.k], par)
                if not _healthy(ok, z, p, ints, work):
                    _restart(z, z_good, p, p0, qd, q0, rm, r0, ints)
                else:
                    inconsistent = adaptive and runaway(k, y, est, valid, ints)
                    if inconsistent:  # restarted below; no more adaptation
                        mode, adaptive, ints[INTS.fell_back] = FilterMode.KF, False, 1
                    else:
                        _copy(z, z_good)
            if inconsistent:  # restart, and the window starts again at the new level
                _restart(z, z_good, p, p0, qd, q0, rm, r0, ints)
                clear_window(acc, ints)
        _statistics(k, valid[k] and not rejected, ints, acc, kt, qd, ror, qoq)
        if not rejected:  # a rejected sample leaves the window as it was: nothing to adapt to
            _adapt(mode, ror[k], qoq[k], ints, par, acc, qd, q0, rm, r0)
        _record(k, trq0, trr0, qd, rm, z, d, q_scale, r_scale, states)
        ints[INTS.k] += 1
