"""Compiled adaptation rules of the recursive compensators: how Q and R change online.

Called by the per-sample loop (:func:`aeromag_env.compensation.kernels.advance`): the fuzzy rule
of the paper (eq. 21) and Ding et al. 2007 once per window (:func:`adapt`), Sage–Husa every
sample (:func:`sage_husa`), and the runaway guard on both (:func:`clamp_scales`).
"""

from __future__ import annotations

import numpy as np

from aeromag_env.compensation.fuzzy import zoomed_scale
from aeromag_env.compensation.kernel_layout import ACC, INTS, PAR
from aeromag_env.compensation.model import FilterMode
from aeromag_env.numba_cache import njit


@njit(cache=True)
def clamp_scales(
    qd: np.ndarray, q0: np.ndarray, rm: np.ndarray, r0: np.ndarray, lo: float, hi: float
) -> None:
    """Keep tr Q / tr Q(0) and tr R / tr R(0) within [lo, hi] (runaway guard)."""
    q0s = q0.sum()
    if q0s > 0.0:
        ratio = qd.sum() / q0s
        if ratio < lo or ratio > hi:
            qd *= min(max(ratio, lo), hi) / ratio
    ratio = (rm[0, 0] + rm[1, 1] + rm[2, 2]) / (r0[0, 0] + r0[1, 1] + r0[2, 2])
    if ratio < lo or ratio > hi:
        rm *= min(max(ratio, lo), hi) / ratio


@njit(cache=True)
def adapt(
    mode: int,
    ror: float,
    qoq: float,
    acc: np.ndarray,
    ints: np.ndarray,
    qd: np.ndarray,
    rm: np.ndarray,
    par: np.ndarray,
) -> None:
    """Windowed adaptation of Q and R: fuzzy (eq. 21) or Ding et al. 2007."""
    if mode == FilterMode.FAKF:
        s_r = zoomed_scale(ror, par[PAR.eps], par[PAR.zoom_r])
        s_a = zoomed_scale(qoq, par[PAR.eta], par[PAR.zoom_q])
        rm *= s_r
        qd *= s_a
    elif mode == FilterMode.DING:
        m = ints[INTS.updates]
        trr = rm[0, 0] + rm[1, 1] + rm[2, 2]
        denom = abs(acc[ACC.s] / m - trr)
        if denom > 0.0:
            alpha = abs(acc[ACC.rr] / m - trr) / denom
            if alpha > 0.0 and np.isfinite(alpha):
                qd *= np.sqrt(alpha)


@njit(cache=True)
def sage_husa_innovation_r(r: np.ndarray, s: np.ndarray, rm: np.ndarray, dk: float) -> None:
    """Classic form ``R ← (1−d)R + d(r rᵀ − H P⁻ Hᵀ)``; where that is not positive definite,
    the biased ``R ← (1−d)R + d r rᵀ``."""
    cand = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            cand[i, j] = (1.0 - dk) * rm[i, j] + dk * (r[i] * r[j] - (s[i, j] - rm[i, j]))
    ok = cand[0, 0] > 0.0 and cand[0, 0] * cand[1, 1] - cand[0, 1] ** 2 > 0.0
    if ok and np.linalg.det(cand) > 0.0:
        rm[:, :] = cand
    else:
        for i in range(3):
            for j in range(3):
                rm[i, j] = (1.0 - dk) * rm[i, j] + dk * r[i] * r[j]


@njit(cache=True)
def sage_husa(
    r: np.ndarray,
    s: np.ndarray,
    sinv: np.ndarray,
    kt: np.ndarray,
    rm: np.ndarray,
    qd: np.ndarray,
    q0: np.ndarray,
    k: int,
    par: np.ndarray,
) -> None:
    """Sage–Husa with fading factor b: ``d = (1−b)/(1−b^{k+1})`` (``kt`` is the gain Kᵀ).

    Default: ``R ← (1−d) R + d (e eᵀ + H P⁺ Hᵀ)`` from the post-fit residual ``e`` (Akhlaghi,
    Zhou & Huang 2017), positive definite by construction; with the optimal gain
    ``e = R S⁻¹ r`` and ``H P⁺ Hᵀ = M − M S⁻¹ M``, ``M = H P⁻ Hᵀ = S − R``. With
    ``par[PAR.sh_innov]``: the classic innovation form (:func:`sage_husa_innovation_r`).
    Optionally (``par[PAR.sh_q]``) ``Q ← Q + d diag(K (r rᵀ − S) Kᵀ)``, since
    ``P⁺_k − P⁺_{k−1} = Q − K S Kᵀ`` for ``Φ = I``; its diagonal is floored at ``lo``·Q(0).
    """
    b = par[PAR.sh_b]
    dk = (1.0 - b) / (1.0 - b ** (k + 1))
    if par[PAR.sh_innov] != 0.0:
        sage_husa_innovation_r(r, s, rm, dk)
    else:
        m = s - rm
        e = rm @ (sinv @ r)
        hph = m - m @ sinv @ m
        for i in range(3):
            for j in range(3):
                post = e[i] * e[j] + 0.5 * (hph[i, j] + hph[j, i])
                rm[i, j] = (1.0 - dk) * rm[i, j] + dk * post
    if par[PAR.sh_q] == 0.0:
        return
    lo = par[PAR.lo]
    for a in range(qd.shape[0]):
        v = 0.0
        for i in range(3):
            for j in range(3):
                v += kt[i, a] * (r[i] * r[j] - s[i, j]) * kt[j, a]
        qd[a] = max(qd[a] + dk * v, lo * q0[a])
