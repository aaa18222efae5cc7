"""Compiled bank of models of ``imm``: interacting multiple models (Blom & Bar-Shalom 1988) or,
without mixing, multiple-model adaptive estimation (MMAE, Magill 1965).

Called by the per-sample loop (:func:`aeromag_env.compensation.kernels.advance`) for ``imm``: it
replaces the loop's prediction (:func:`imm_predict`) and update (:func:`imm_update`); the loop's
own ``State.z`` and ``State.p`` hold the combined estimate, from which it takes the a-priori
interference, the innovation and the ``S`` that its outlier gate and window use. The models' Q
and R are their scales times a base (:func:`model_q`, :func:`model_r`): the filter's current Q,
R (``follows``: an external controller rescales them) or Q(0), R(0).

Per sample k, with model probabilities ``μ`` and the switching matrix ``Π`` (``Φ = I``):

1. mixing (IMM only; MMAE keeps each model's own estimate and ``c̄ = μ``):
   ``c̄_j = Σ_i Π_ij μ_i``, ``μ_i|j = Π_ij μ_i / c̄_j``, ``x_0j = Σ_i μ_i|j x_i``,
   ``P_0j = Σ_i μ_i|j [P_i + (x_i − x_0j)(x_i − x_0j)ᵀ]``; then ``μ = c̄``
2. prediction of each model: ``x_j⁻ = x_0j``, ``P_j⁻ = P_0j + Q_j``; the combined prediction
   ``x⁻ = Σ c̄_j x_j⁻``, ``P⁻ = Σ c̄_j [P_j⁻ + (x_j⁻ − x⁻)(·)ᵀ]``, with ``R̄ = Σ c̄_j R_j`` its
   ``S = H P⁻ Hᵀ + R̄`` (the predictive covariance of the mixture)
3. update of each model with its own innovation ``r_j = y − H x_j⁻``, ``S_j = H P_j⁻ Hᵀ + R_j``
   (the loop's Joseph update), and its likelihood ``Λ_j = N(r_j; 0, S_j)``
4. ``μ_j = c̄_j Λ_j / Σ_i c̄_i Λ_i`` (in logarithms, relative to the largest, so that nothing
   underflows while one model still explains the data)
5. combination: ``x = Σ μ_j x_j``, ``P = Σ μ_j [P_j + (x_j − x)(x_j − x)ᵀ]``
"""

from __future__ import annotations

import math

import numpy as np

from aeromag_env.compensation.arrays import Bank
from aeromag_env.compensation.kalman_steps import (
    GainWork,
    SparseH,
    det3,
    gain_terms,
    h_times,
    inv3,
    kalman_update,
    per_sample,
)
from aeromag_env.compensation.kernel_layout import INTS, PAR

#: Indices into a model's row of ``Bank.bank_scale``.
Q_SCALE, R_SCALE = 0, 1


@per_sample
def model_q(bank: Bank, j: int, qd: np.ndarray, q0: np.ndarray, a: int) -> float:
    """Diagonal element a of model j's Q: its scale times the current Q (``qd``) when it follows,
    else times Q(0)."""
    base = qd[a] if bank.bank_follow[j] else q0[a]
    return bank.bank_scale[j, Q_SCALE] * base


@per_sample
def model_r(bank: Bank, j: int, rm: np.ndarray, r0: np.ndarray, out: np.ndarray) -> None:
    """Model j's R (3, 3) [nT²] into ``out``: its scale times the current R or R(0)."""
    scale = bank.bank_scale[j, R_SCALE]
    for a in range(3):
        for b in range(3):
            out[a, b] = scale * (rm[a, b] if bank.bank_follow[j] else r0[a, b])


@per_sample
def bank_noise(
    bank: Bank,
    m: int,
    qd: np.ndarray,
    rm: np.ndarray,
    q0: np.ndarray,
    r0: np.ndarray,
    q_mix: np.ndarray,
    r_mix: np.ndarray,
    rj: np.ndarray,
) -> None:
    """The probability-weighted noise of the bank: ``Σ μ_j Q_j`` (diagonal, into ``q_mix``) and
    ``Σ μ_j R_j`` (into ``r_mix``); ``rj`` (3, 3) scratch."""
    mu = bank.bank_mu
    for a in range(q_mix.shape[0]):
        acc = 0.0
        for j in range(m):
            acc += mu[j] * model_q(bank, j, qd, q0, a)
        q_mix[a] = acc
    r_mix[:, :] = 0.0
    for j in range(m):
        model_r(bank, j, rm, r0, rj)
        for a in range(3):
            for b in range(3):
                r_mix[a, b] += mu[j] * rj[a, b]


@per_sample
def combine(bank: Bank, m: int, z: np.ndarray, p: np.ndarray) -> None:
    """Step 5 (and the combined prediction of step 2): ``z = Σ μ_j z_j``,
    ``P = Σ μ_j [P_j + (z_j − z)(z_j − z)ᵀ]``, with the bank's current ``μ`` (summed model by
    model, the innermost loop along a row of P)."""
    bz, bp, mu = bank.bank_z, bank.bank_p, bank.bank_mu
    n_state = z.shape[0]
    for a in range(n_state):
        acc = 0.0
        for j in range(m):
            acc += mu[j] * bz[j, a]
        z[a] = acc
        for b in range(a + 1):
            p[a, b] = 0.0
    for j in range(m):
        w = mu[j]
        for a in range(n_state):
            da = bz[j, a] - z[a]
            for b in range(a + 1):
                p[a, b] += w * (bp[j, a, b] + da * (bz[j, b] - z[b]))
    for a in range(n_state):
        for b in range(a):
            p[b, a] = p[a, b]


@per_sample
def _mix(
    bank: Bank,
    m: int,
    mix_w: np.ndarray,
    mix_z: np.ndarray,
    mix_p: np.ndarray,
    cbar: np.ndarray,
) -> None:
    """Step 1: the weights ``μ_i|j`` into ``mix_w``, the mixed estimates of every model into
    ``mix_z``, ``mix_p`` (lower triangles), then into the bank; ``μ = c̄``. A model no other can
    switch to (``c̄_j = 0``) keeps its own estimate. Summed model by model, the innermost loop
    along a row of P."""
    bz, bp, mu, pi = bank.bank_z, bank.bank_p, bank.bank_mu, bank.bank_pi
    n_state = bz.shape[1]
    for j in range(m):
        acc = 0.0
        for i in range(m):
            acc += pi[i, j] * mu[i]
        cbar[j] = acc
        for i in range(m):
            if acc > 0.0:
                mix_w[i, j] = pi[i, j] * mu[i] / acc
            else:
                mix_w[i, j] = 1.0 if i == j else 0.0
    for j in range(m):
        for a in range(n_state):
            acc = 0.0
            for i in range(m):
                acc += mix_w[i, j] * bz[i, a]
            mix_z[j, a] = acc
            for b in range(a + 1):
                mix_p[j, a, b] = 0.0
        for i in range(m):
            w = mix_w[i, j]
            for a in range(n_state):
                da = bz[i, a] - mix_z[j, a]
                for b in range(a + 1):
                    mix_p[j, a, b] += w * (bp[i, a, b] + da * (bz[i, b] - mix_z[j, b]))
    for j in range(m):
        mu[j] = cbar[j]
        for a in range(n_state):
            bz[j, a] = mix_z[j, a]
            for b in range(a + 1):
                bp[j, a, b] = mix_p[j, a, b]
                bp[j, b, a] = mix_p[j, a, b]


@per_sample
def imm_predict(
    bank: Bank,
    ints: np.ndarray,
    par: np.ndarray,
    z: np.ndarray,
    p: np.ndarray,
    qd: np.ndarray,
    q0: np.ndarray,
    mix_w: np.ndarray,
    mix_z: np.ndarray,
    mix_p: np.ndarray,
    cbar: np.ndarray,
) -> None:
    """Steps 1–2: mixing (unless MMAE), each model's ``P_j⁻ = P_0j + Q_j``, and the combined
    prediction into ``z``, ``p``; ``mix_w``, ``mix_z``, ``mix_p``, ``cbar`` are scratch of the
    bank's shapes."""
    m = ints[INTS.models]
    if par[PAR.mmae] == 0.0:
        _mix(bank, m, mix_w, mix_z, mix_p, cbar)
    for j in range(m):
        for a in range(z.shape[0]):
            bank.bank_p[j, a, a] += model_q(bank, j, qd, q0, a)
    combine(bank, m, z, p)


@per_sample
def imm_update(
    k: int,
    y: np.ndarray,
    bank: Bank,
    m: int,
    h: SparseH,
    rm: np.ndarray,
    r0: np.ndarray,
    z: np.ndarray,
    p: np.ndarray,
    g: GainWork,
    m33: np.ndarray,
    v3: np.ndarray,
) -> bool:
    """Steps 3–5 for sample k (``y`` (n, 3) [nT], ``h`` the sparse ``H_s(k)``): the models
    updated, ``μ`` and the combined ``z``, ``p``; ``g`` a model's gain work, ``m33``
    (≥ 3, 3, 3) and ``v3`` (≥ 1, 3) scratch. Step 4 in logarithms: ``μ_j`` holds
    ``ln c̄_j + ln Λ_j`` until all are known, then ``exp`` of it relative to the largest. False
    if a model's ``S_j`` is not positive definite or no model explains the data (all weights
    zero or not finite)."""
    col, hv, gt, kt, kst = h.col, h.hv, g.gt, g.kt, g.kst
    s, sinv, rj, r = m33[0], m33[1], m33[2], v3[0]
    mu = bank.bank_mu
    top = -np.inf
    for j in range(m):
        zj, pj = bank.bank_z[j], bank.bank_p[j]
        for i in range(3):
            r[i] = y[k, i] - h_times(col, hv, zj, i)  # r_j = y − H x_j⁻
        model_r(bank, j, rm, r0, rj)
        gain_terms(pj, rj, col, hv, gt, s)  # S_j = H P_j⁻ Hᵀ + R_j
        if not inv3(s, sinv):
            return False
        nis = 0.0
        for a in range(3):
            nis += r[a] * (sinv[a, 0] * r[0] + sinv[a, 1] * r[1] + sinv[a, 2] * r[2])
        loglik = -0.5 * (nis + math.log(det3(s)))  # ln Λ_j + (3/2) ln 2π
        mu[j] = math.log(mu[j]) + loglik if mu[j] > 0.0 else -np.inf  # ln c̄_j Λ_j
        top = max(top, mu[j])
        kalman_update(zj, pj, gt, kt, kst, s, sinv, r)
    total = 0.0
    for j in range(m):
        mu[j] = math.exp(mu[j] - top) if mu[j] > -np.inf else 0.0
        total += mu[j]
    if not (0.0 < total < np.inf):
        return False
    for j in range(m):
        mu[j] /= total
    combine(bank, m, z, p)
    return True


@per_sample
def imm_restart(bank: Bank, m: int, z_good: np.ndarray, p0: np.ndarray) -> None:
    """Every model from the last good combined state with P(0), equally probable."""
    for j in range(m):
        bank.bank_mu[j] = 1.0 / m
        for a in range(z_good.shape[0]):
            bank.bank_z[j, a] = z_good[a]
            for b in range(z_good.shape[0]):
                bank.bank_p[j, a, b] = p0[a, b]
