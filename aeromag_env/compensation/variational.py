"""Compiled variational-Bayes updates: ``vbakf`` (Särkkä & Nummenmaa 2009) and ``vbakf-pr``
(Huang, Zhang, Wu, Li & Chambers 2018).

Called by the per-sample loop (:func:`aeromag_env.compensation.kernels.advance`) in place of its
plain Kalman update; the prediction ``P⁻ = P + Q``, the innovation ``r = y − H z⁻`` and its
``S = H P⁻ Hᵀ + R̂`` (which the outlier gate and the window use) are the loop's. R's posterior is
kept as the estimate ``R̂`` in ``State.rm`` (the matrix an external controller rescales) and its
shape in ``State.vb_shape``; the posterior's scale follows from the two (``β = α R̂``,
``Û = (û − m − 1) R̂``), so a rescaled ``R̂`` rescales the posterior.

R's posterior is predicted (its forgetting) on the samples that update the filter, just before
the update; a skipped sample or one the outlier gate rejected leaves it as it was, as it leaves
the innovation window. (The papers predict it every time step. Under ρ = 0.95 a 60-s burst of
rejected samples then left α at 0.95⁶⁰⁰ ≈ 4e-14 of its value: the first update after it started
its fixed point at Σ ≈ 0, R̂ collapsed to the floor of ``scale_bounds`` and 18 more samples were
rejected.)

``vbakf`` (the paper's Algorithm, R diagonal): per axis i, predict ``α⁻ = ρ α``, ``β⁻ = ρ β``;
update ``α = α⁻ + ½`` and, from ``β⁽⁰⁾ = β⁻``, N times: ``Σ = diag(β/α)``, the Kalman update
with ``Σ``, ``β = β⁻ + ½ (y − H x)ᵢ² + ½ (H P Hᵀ)ᵢᵢ``; then ``R̂ = diag(β/α)``. The iterations run
in the 3×3 measurement space: with the optimal gain the post-fit residual is
``y − H x = Σ S⁻¹ r`` and ``H P Hᵀ = M − M S⁻¹ M`` (``M = H P⁻ Hᵀ``), so only the last Σ's update
touches the 21 states. R stays diagonal, as published.

``vbakf-pr`` (the paper's Algorithm 1, R full 3×3): prior ``IW(n + τ + 1, τ P̃⁻)`` on ``P⁻``
around the nominal ``P̃⁻ = P + Q``, R's predicted by ``û⁻ = ρ(û − m − 1) + m + 1``,
``Û⁻ = ρ Û``; ``û = û⁻ + 1`` and, from ``x⁽⁰⁾ = x⁻``, ``P⁽⁰⁾ = P̃⁻``, N times:
``A = P⁽ⁱ⁾ + (x⁽ⁱ⁾ − x⁻)(·)ᵀ``, ``B = (y − H x⁽ⁱ⁾)(·)ᵀ + H P⁽ⁱ⁾ Hᵀ``,
``P⁻⁽ⁱ⁺¹⁾ = (τ P̃⁻ + A) / (τ + 1)``, ``R⁽ⁱ⁺¹⁾ = (Û⁻ + B) / (û − m − 1)`` and the Kalman update of
``x⁻`` with them; then ``R̂ = R⁽ᴺ⁾`` (``Û = Û⁻ + B``). ``vb_shape[0]`` holds ``û − m − 1``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from aeromag_env.compensation.kalman_steps import (
    GainWork,
    SparseH,
    gain_terms,
    h_g,
    inv3,
    kalman_update,
    per_sample,
)
from aeromag_env.compensation.kernel_layout import PAR
from aeromag_env.compensation.model import FilterMode

#: The dimension m of the measurement (3 fluxgate axes).
M_MEAS = 3


class VbWork(NamedTuple):
    """Work arrays of the variational updates (and of the bank's, which uses the first two)."""

    m33: np.ndarray  #: (5, 3, 3) 3×3 matrices
    v3: np.ndarray  #: (3, 3) 3-vectors
    p_nominal: np.ndarray  #: (n, n) vbakf-pr's nominal ``P⁻`` ((0, 0) otherwise)
    z_prior: np.ndarray  #: (n,) vbakf-pr's ``x⁻`` ((0,) otherwise)


@per_sample
def vb_prior(mode: int, shape: np.ndarray, par: np.ndarray) -> None:
    """R's prior shape (at the start and after a restart): ``α₀`` per axis (``vbakf``) or
    ``û₀ − m − 1`` (``vbakf-pr``)."""
    for i in range(M_MEAS):
        shape[i] = par[PAR.vb_prior] if mode == FilterMode.VBAKF or i == 0 else 0.0


@per_sample
def vb_predict(mode: int, shape: np.ndarray, rho: float) -> None:
    """The forgetting of R's posterior: ``α⁻ = ρ α`` (``vbakf``), ``û⁻ − m − 1 = ρ (û − m − 1)``
    (``vbakf-pr``); with ``R̂`` unchanged, ``β⁻ = ρ β`` and ``Û⁻ = ρ Û``."""
    n = M_MEAS if mode == FilterMode.VBAKF else 1
    for i in range(n):
        shape[i] *= rho


@per_sample
def _posterior_terms(
    mm: np.ndarray, sinv: np.ndarray, r: np.ndarray, e: np.ndarray, hph: np.ndarray
) -> None:
    """After a Kalman update with ``S`` (``sinv`` = S⁻¹) and ``M = H P⁻ Hᵀ`` (``mm``): the
    post-fit residual ``e = y − H x = r − M S⁻¹ r`` and ``H P Hᵀ = M − M S⁻¹ M`` (symmetrised)."""
    for i in range(3):
        acc = r[i]
        for j in range(3):
            msr = 0.0
            for m in range(3):
                msr += sinv[j, m] * r[m]
            acc -= mm[i, j] * msr
        e[i] = acc
    for i in range(3):
        for j in range(i + 1):
            acc = 0.0
            for a in range(3):
                for b in range(3):
                    acc += mm[i, a] * sinv[a, b] * mm[b, j]
            v = mm[i, j] - acc if i == j else 0.5 * (mm[i, j] + mm[j, i]) - acc
            hph[i, j] = v
            hph[j, i] = v


@per_sample
def vbakf_update(
    z: np.ndarray,
    p: np.ndarray,
    r: np.ndarray,
    rm: np.ndarray,
    shape: np.ndarray,
    iterations: int,
    rho: float,
    h: SparseH,
    g: GainWork,
    work: VbWork,
) -> bool:
    """Särkkä & Nummenmaa's update of ``z``, ``p`` (the prediction, with ``g.gt`` its ``Gᵀ``)
    by the innovation ``r`` [nT], R's posterior predicted with the forgetting factor ``rho``
    first; ``R̂`` (``rm``) and ``α`` (``shape``) updated; ``g.kt`` the last gain. False if an
    ``S`` is not positive definite."""
    col, hv, gt = h.col, h.hv, g.gt
    mm, s_it, sinv_it, hph = work.m33[0], work.m33[1], work.m33[2], work.m33[3]
    beta, sigma, e = work.v3[0], work.v3[1], work.v3[2]
    vb_predict(FilterMode.VBAKF, shape, rho)
    h_g(gt, col, hv, mm)  # M = H P⁻ Hᵀ
    for i in range(3):
        beta[i] = shape[i] * rm[i, i]  # β⁻ = α⁻ R̂
    for _ in range(iterations):
        for i in range(3):
            sigma[i] = beta[i] / (shape[i] + 0.5)  # Σ = diag(β / α), α = α⁻ + ½
        for i in range(3):
            for j in range(3):
                s_it[i, j] = mm[i, j] + (sigma[i] if i == j else 0.0)
        if not inv3(s_it, sinv_it):
            return False
        _posterior_terms(mm, sinv_it, r, e, hph)
        for i in range(3):  # β = β⁻ + ½ (y − H x)ᵢ² + ½ (H P Hᵀ)ᵢᵢ
            beta[i] = shape[i] * rm[i, i] + 0.5 * e[i] * e[i] + 0.5 * hph[i, i]
    kalman_update(z, p, gt, g.kt, g.kst, s_it, sinv_it, r)  # with the last Σ
    for i in range(3):
        shape[i] += 0.5
        for j in range(3):
            rm[i, j] = beta[i] / shape[i] if i == j else 0.0
    return True


@per_sample
def vbakf_pr_update(
    z: np.ndarray,
    p: np.ndarray,
    r: np.ndarray,
    rm: np.ndarray,
    shape: np.ndarray,
    iterations: int,
    rho: float,
    tau: float,
    h: SparseH,
    g: GainWork,
    work: VbWork,
) -> bool:
    """Huang et al.'s update of ``z``, ``p`` (the nominal prediction ``P̃⁻``, with ``g.gt`` its
    ``Gᵀ``) by the innovation ``r`` [nT], R's posterior predicted with the forgetting factor
    ``rho`` first; ``R̂`` (``rm``) and ``û − m − 1`` (``shape[0]``) updated; ``g.kt`` the last
    gain. False if an ``S`` is not positive definite."""
    n_state = z.shape[0]
    col, hv, gt = h.col, h.hv, g.gt
    p_nominal, z_prior = work.p_nominal, work.z_prior
    m33 = work.m33
    mm, s_it, sinv_it, hph, r_it = m33[0], m33[1], m33[2], m33[3], m33[4]
    e = work.v3[2]
    vb_predict(FilterMode.VBAKF_PR, shape, rho)
    dof_prior = shape[0]  # û⁻ − m − 1
    dof = dof_prior + 1.0  # û − m − 1, û = û⁻ + 1
    for a in range(n_state):
        z_prior[a] = z[a]
        for b in range(n_state):
            p_nominal[a, b] = p[a, b]
    h_g(gt, col, hv, hph)  # H P⁽⁰⁾ Hᵀ = H P̃⁻ Hᵀ
    for i in range(3):
        e[i] = r[i]  # y − H x⁽⁰⁾
    for _ in range(iterations):
        for i in range(3):  # R⁽ⁱ⁺¹⁾ = (Û⁻ + B⁽ⁱ⁾) / (û − m − 1), Û⁻ = (û⁻ − m − 1) R̂
            for j in range(3):
                r_it[i, j] = (dof_prior * rm[i, j] + e[i] * e[j] + hph[i, j]) / dof
        for a in range(n_state):  # P⁻⁽ⁱ⁺¹⁾ = (τ P̃⁻ + P⁽ⁱ⁾ + δ δᵀ) / (τ + 1), δ = x⁽ⁱ⁾ − x⁻
            da = z[a] - z_prior[a]
            for b in range(a + 1):
                v = (tau * p_nominal[a, b] + p[a, b] + da * (z[b] - z_prior[b])) / (tau + 1.0)
                p[a, b] = v
                p[b, a] = v
        for a in range(n_state):
            z[a] = z_prior[a]
        gain_terms(p, r_it, col, hv, gt, s_it)
        if not inv3(s_it, sinv_it):
            return False
        h_g(gt, col, hv, mm)  # M = H P⁻⁽ⁱ⁺¹⁾ Hᵀ
        kalman_update(z, p, gt, g.kt, g.kst, s_it, sinv_it, r)
        _posterior_terms(mm, sinv_it, r, e, hph)  # B's terms for the next iteration
    for i in range(3):
        for j in range(3):
            rm[i, j] = r_it[i, j]
    shape[0] = dof
    return True
