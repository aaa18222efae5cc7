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

from typing import NamedTuple

import numpy as np

from aeromag_env.compensation.adaptive_rules import adapt, clamp_scales, sage_husa
from aeromag_env.compensation.arrays import FilterArrays, Packed, named
from aeromag_env.compensation.consistency import clear_window, outlier, reject, runaway
from aeromag_env.compensation.kalman_steps import (
    H_NNZ,
    GainWork,
    SparseH,
    gain,
    gain_terms,
    h_row,
    h_times,
    inv3,
    kalman_update,
    per_sample,
)
from aeromag_env.compensation.kernel_layout import ACC, INTS, MAX_STATE, PAR
from aeromag_env.compensation.model import FilterMode
from aeromag_env.compensation.multiple_model import (
    bank_noise,
    imm_predict,
    imm_restart,
    imm_update,
)
from aeromag_env.compensation.variational import (
    VbWork,
    vb_prior,
    vbakf_pr_update,
    vbakf_update,
)
from aeromag_env.compensation.window import window_add
from aeromag_env.numba_cache import njit


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
    h_row(t, td, k, d, col, hv)
    for i in range(3):
        est[k, i] = h_times(col, hv, z, i)


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
    gain_terms(p, rm, col, hv, gt, s)
    for i in range(3):
        r[i] = y[k, i] - est[k, i]


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
def _restart(mode: int, f: FilterArrays) -> None:
    """Divergence: count it and restart from the last good state with P(0), Q(0), R(0) (the
    variational filters with R's prior shape, the bank with every model there)."""
    z, p, qd, rm, ints = f.state.z, f.state.p, f.state.qd, f.state.rm, f.state.ints
    ints[INTS.div] += 1
    z[:] = f.state.z_good
    p[:, :] = f.state.p0
    qd[:] = f.state.q0
    rm[:, :] = f.state.r0
    if mode == FilterMode.VBAKF or mode == FilterMode.VBAKF_PR:
        vb_prior(mode, f.state.vb_shape, f.state.par)
    elif mode == FilterMode.IMM:
        imm_restart(f.bank, ints[INTS.models], f.state.z_good, f.state.p0)


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
    window is full, every ``adapt_interval`` samples; then (and after every Sage–Husa or
    variational sample) clamp their scales."""
    ints[INTS.since] += 1
    if (
        (mode == FilterMode.FAKF or mode == FilterMode.DING)
        and ints[INTS.updates] == ints[INTS.window]
        and ints[INTS.since] >= ints[INTS.interval]
    ):
        adapt(mode, ror, qoq, acc, ints, qd, rm, par)
        clamp_scales(qd, q0, rm, r0, par[PAR.lo], par[PAR.hi])
        ints[INTS.since] = 0
    elif mode == FilterMode.SAGE_HUSA or mode == FilterMode.VBAKF or mode == FilterMode.VBAKF_PR:
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


class Scratch(NamedTuple):
    """Work arrays of one :func:`advance` call (allocated once per call, sized 0 where a method
    does not use them)."""

    col: np.ndarray  #: (3, 7) int64 columns of the non-zeros of ``H_s(k)``
    hv: np.ndarray  #: (3, 7) their values
    gt: np.ndarray  #: (3, n) ``Gᵀ = (P⁻ H_sᵀ)ᵀ``
    kt: np.ndarray  #: (3, n) ``Kᵀ`` (kept: QOQ reads the last gain)
    kst: np.ndarray  #: (3, n) ``(K S)ᵀ``
    s: np.ndarray  #: (3, 3) ``S``
    sinv: np.ndarray  #: (3, 3) ``S⁻¹``
    r: np.ndarray  #: (3,) the innovation
    work: np.ndarray  #: (n, n) the Cholesky test's
    m33: np.ndarray  #: (5, 3, 3) the variational and bank updates' 3×3 matrices
    v3: np.ndarray  #: (3, 3) their 3-vectors
    p_nominal: np.ndarray  #: (n, n) vbakf-pr's nominal ``P⁻`` ((0, 0) otherwise)
    z_prior: np.ndarray  #: (n,) vbakf-pr's ``x⁻`` ((0,) otherwise)
    t3n: np.ndarray  #: (3, 3, n) a bank model's ``Gᵀ``, ``Kᵀ``, ``(K S)ᵀ`` (imm; else (3, 3, 0))
    mix_w: np.ndarray  #: the mixing weights ``μ_i|j`` (the shape of ``Bank.bank_pi``)
    mix_z: np.ndarray  #: the bank's mixed states (the shape of ``Bank.bank_z``)
    mix_p: np.ndarray  #: the bank's mixed covariances (the shape of ``Bank.bank_p``)
    cbar: np.ndarray  #: (m,) the models' predicted probabilities ``c̄``
    q_mix: np.ndarray  #: (n,) the bank's probability-weighted Q (imm)
    r_mix: np.ndarray  #: (3, 3) its probability-weighted R [nT²] (imm)


@njit(cache=True)
def _scratch(mode: int, f: FilterArrays) -> Scratch:
    """The work arrays of :func:`advance` for ``mode`` and the filter ``f`` (those of the
    variational and bank updates empty for the other methods)."""
    n = f.state.z.shape[0]
    pr = n if mode == FilterMode.VBAKF_PR else 0
    bk = n if mode == FilterMode.IMM else 0
    small = 3 if mode == FilterMode.VBAKF or pr > 0 or bk > 0 else 0
    mixed = 3 if bk > 0 else 0
    m = f.bank.bank_mu.shape[0]
    return Scratch(
        np.empty((3, H_NNZ), np.int64),
        np.empty((3, H_NNZ)),
        np.empty((3, n)),
        np.zeros((3, n)),  # QOQ may read the gain before a first update
        np.empty((3, n)),
        np.empty((3, 3)),
        np.empty((3, 3)),
        np.empty(3),
        np.empty((n, n)),
        np.empty((5, small, small)),
        np.empty((3, small)),
        np.empty((pr, pr)),
        np.empty(pr),
        np.empty((3, 3, bk)),
        np.empty((m, m)),
        np.empty((m, n)),
        np.empty((m, n, n)),
        np.empty(m),
        np.empty(bk),
        np.empty((mixed, mixed)),
    )


@njit(cache=True)
def advance(mode: int, k0: int, k1: int, arrays: FilterArrays | Packed) -> None:
    """Advance the filter over samples ``k0 ≤ k < k1`` (see the module docstring).

    ``mode`` is a :class:`~aeromag_env.compensation.model.FilterMode`; of the filter's
    ``arrays`` (:class:`~aeromag_env.compensation.arrays.FilterArrays`, or packed) the signals
    are read, the state, window and bank updated in place and the outputs written at rows k.
    """
    f = named(arrays)
    y, t, td, valid = f.signals
    d, z, p, qd, rm, z_good, _, q0, r0, ints, par, vb_shape = f.state
    rbuf, sbuf, acc = f.window
    est, innov, ror, qoq, q_scale, r_scale, states = f.outputs
    w = _scratch(mode, f)
    col, hv, gt, kt, kst, s, sinv, r = w.col, w.hv, w.gt, w.kt, w.kst, w.s, w.sinv, w.r
    m33, v3 = w.m33, w.v3
    # the groups the variational and bank updates take (built once per call)
    h, g = SparseH(col, hv), GainWork(gt, kt, kst)
    g_model = GainWork(w.t3n[0], w.t3n[1], w.t3n[2])
    vb_work = VbWork(m33, v3, w.p_nominal, w.z_prior)
    lam, rho, tau = par[PAR.forget], par[PAR.vb_rho], par[PAR.vb_tau]
    iterations, models = ints[INTS.iterations], ints[INTS.models]
    trq0 = q0.sum()
    trr0 = r0[0, 0] + r0[1, 1] + r0[2, 2]
    if ints[INTS.fell_back]:  # an adaptive filter that ran away goes on as the plain KF
        mode = FilterMode.KF
    variational = mode == FilterMode.VBAKF or mode == FilterMode.VBAKF_PR
    adaptive = (
        mode == FilterMode.FAKF
        or mode == FilterMode.DING
        or mode == FilterMode.SAGE_HUSA
        or variational
    )
    imm, bank = mode == FilterMode.IMM, f.bank
    # the noise the prediction carries: the filter's own, or the bank's probability-weighted
    qn, rn = (w.q_mix, w.r_mix) if imm else (qd, rm)
    for k in range(k0, k1):
        if imm:
            imm_predict(bank, ints, par, z, p, qd, q0, w.mix_w, w.mix_z, w.mix_p, w.cbar)
            bank_noise(bank, models, qd, rm, q0, r0, qn, rn, m33[0])
        else:
            _predict(mode, lam, p, qd)
        _estimate(k, t, td, d, z, col, hv, est)
        rejected = False
        if not valid[k]:
            _store_row(innov, k, np.nan, np.nan, np.nan)
            ints[INTS.skip] += 1
        else:
            _innovation(k, y, est, p, rn, col, hv, gt, s, r)
            _store_row(innov, k, r[0], r[1], r[2])
            ok = inv3(s, sinv)
            rejected = ok and outlier(r, sinv, acc, ints)
            inconsistent = rejected and reject(r, acc, ints)  # a window of shifted outliers
            if not rejected:
                if ok:  # the update (eqs. 19–20), or the one that replaces it
                    if mode == FilterMode.VBAKF:
                        ok = vbakf_update(z, p, r, rm, vb_shape, iterations, rho, h, g, vb_work)
                    elif mode == FilterMode.VBAKF_PR:
                        ok = vbakf_pr_update(
                            z, p, r, rm, vb_shape, iterations, rho, tau, h, g, vb_work
                        )
                    elif imm:
                        gain(gt, sinv, kt)  # the combined prediction's gain, which QOQ reads
                        ok = imm_update(k, y, bank, models, h, rm, r0, z, p, g_model, m33, v3)
                    else:
                        kalman_update(z, p, gt, kt, kst, s, sinv, r)
                    window_add(r, s[0, 0] + s[1, 1] + s[2, 2], rbuf, sbuf, acc, ints)
                    if mode == FilterMode.SAGE_HUSA:
                        sage_husa(r, s, sinv, kt, rm, qd, q0, ints[INTS.base] + ints[INTS.k], par)
                if not _healthy(ok, z, p, ints, w.work):
                    _restart(mode, f)
                else:
                    inconsistent = adaptive and runaway(k, y, est, valid, ints)
                    if inconsistent:  # restarted below; no more adaptation
                        mode, adaptive, ints[INTS.fell_back] = FilterMode.KF, False, 1
                    else:
                        _copy(z, z_good)
            if inconsistent:  # restart, and the window starts again at the new level
                _restart(mode, f)
                clear_window(acc, ints)
        if imm:  # Q and R of the bank after the update (its posterior probabilities)
            bank_noise(bank, models, qd, rm, q0, r0, qn, rn, m33[0])
        _statistics(k, valid[k] and not rejected, ints, acc, kt, qn, ror, qoq)
        if not rejected:  # a rejected sample leaves the window as it was: nothing to adapt to
            _adapt(mode, ror[k], qoq[k], ints, par, acc, qd, q0, rm, r0)
        _record(k, trq0, trr0, qn, rn, z, d, q_scale, r_scale, states)
        ints[INTS.k] += 1
