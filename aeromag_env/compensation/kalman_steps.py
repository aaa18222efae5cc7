"""Compiled pieces of one Kalman update with the sparse ``H(k)`` of eq. 12 (numba).

Shared by the per-sample loop (:mod:`aeromag_env.compensation.kernels`) and the updates that
replace its plain one: the variational filters (:mod:`aeromag_env.compensation.variational`) and
the bank of models (:mod:`aeromag_env.compensation.multiple_model`). In normalised coordinates
(``H_s = H diag(d)``); ``Gᵀ = (P⁻ H_sᵀ)ᵀ``, ``K`` and ``K S`` are stored transposed (3, n) so that
the loops over the state index are contiguous and vectorise; every sum keeps the order of the
equations as written.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

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


class SparseH(NamedTuple):
    """The non-zeros of ``H_s(k)`` (:func:`h_row`)."""

    col: np.ndarray  #: (3, 7) int64 their columns
    hv: np.ndarray  #: (3, 7) their values


class GainWork(NamedTuple):
    """The work arrays of one Kalman update, each (3, n), stored transposed."""

    gt: np.ndarray  #: ``Gᵀ = (P⁻ H_sᵀ)ᵀ``
    kt: np.ndarray  #: ``Kᵀ``
    kst: np.ndarray  #: ``(K S)ᵀ``


@per_sample
def h_row(
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
def h_times(col: np.ndarray, hv: np.ndarray, z: np.ndarray, i: int) -> float:
    """Row i of ``H_s z`` (the ``H_s`` of :func:`h_row`)."""
    value = 0.0
    for m in range(H_NNZ):
        value += hv[i, m] * z[col[i, m]]
    return value


@per_sample
def gain_terms(
    p: np.ndarray, rm: np.ndarray, col: np.ndarray, hv: np.ndarray, gt: np.ndarray, s: np.ndarray
) -> None:
    """``Gᵀ = (P H_sᵀ)ᵀ`` into ``gt`` (3, n) and ``S = H_s G + R`` into ``s`` (3, 3), for the
    covariance ``p`` and the measurement noise ``rm`` [nT²]."""
    n_state = p.shape[0]
    # Gᵀ[i, a] = Σ_m P[a, c_im] h_im, read as P[c_im, a] (P is kept exactly symmetric)
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


@per_sample
def h_g(gt: np.ndarray, col: np.ndarray, hv: np.ndarray, out: np.ndarray) -> None:
    """``H_s G = H_s P H_sᵀ`` (3, 3) into ``out``, from the ``Gᵀ`` of :func:`gain_terms`."""
    for i in range(3):
        for j in range(3):
            acc = 0.0
            for m in range(H_NNZ):
                acc += hv[i, m] * gt[j, col[i, m]]
            out[i, j] = acc


@per_sample
def det3(s: np.ndarray) -> float:
    """Determinant of a symmetric 3×3 matrix."""
    a, b, c = s[0, 0], s[0, 1], s[0, 2]
    e, f, i = s[1, 1], s[1, 2], s[2, 2]
    return a * (e * i - f * f) + b * (c * f - b * i) + c * (b * f - c * e)


@per_sample
def inv3(s: np.ndarray, out: np.ndarray) -> bool:
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
def gain(gt: np.ndarray, sinv: np.ndarray, kt: np.ndarray) -> None:
    """``K = G S⁻¹`` (eq. 19), into ``kt`` (Kᵀ, (3, n))."""
    for j in range(3):
        for a in range(gt.shape[1]):
            kt[j, a] = gt[0, a] * sinv[0, j] + gt[1, a] * sinv[1, j] + gt[2, a] * sinv[2, j]


@per_sample
def kalman_update(
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
    symmetric); ``kst`` is scratch (3, n)."""
    n_state = z.shape[0]
    gain(gt, sinv, kt)
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
