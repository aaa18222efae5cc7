"""Plain-numpy references of ``vbakf``, ``vbakf-pr`` and ``imm``, written from the papers.

Each filter is transcribed from its paper's algorithm with dense matrices and the papers' own
variables — Särkkä & Nummenmaa 2009 (α, β per axis, :func:`vbakf_update`), Huang et al. 2018
Algorithm 1 (t̂, T̂, û, Û, :func:`vbakf_pr_update`), Blom & Bar-Shalom 1988's IMM cycle
(:class:`BankReference`) — and not from the compiled code
(:mod:`aeromag_env.compensation.variational`, :mod:`aeromag_env.compensation.multiple_model`),
which works in the 3×3 measurement space where it can and keeps R's posterior as ``R̂`` and a
shape. :func:`run_adaptive_reference` runs them with the checks of
:mod:`aeromag_env.compensation.consistency` (:mod:`aeromag_env.compensation.reference_steps`) as
:func:`~aeromag_env.compensation.kalman_reference.run_reference` does for the other methods (and
for these, through this module), so the two are tested to agree.
"""

from __future__ import annotations

import numpy as np

from aeromag_env.compensation.kalman import FilterResult
from aeromag_env.compensation.model import STATE_SCALE, FilterConfig, measurement_rows
from aeromag_env.compensation.reference_steps import Consistency, kf_predict, kf_update, runaway
from aeromag_env.simulation.interference import N_STATES

#: The methods of this module.
ADAPTIVE_METHODS = ("vbakf", "vbakf-pr", "imm")


def vbakf_update(
    x_prior: np.ndarray,
    p_prior: np.ndarray,
    y: np.ndarray,
    h: np.ndarray,
    alpha_prior: np.ndarray,
    beta_prior: np.ndarray,
    iterations: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Särkkä & Nummenmaa 2009, the update step: ``x, P, α, β`` and the last gain ``K``.

    Shapes: x (n,), p (n, n), y (m,), h (m, n), α and β (m,) (the predicted ``α⁻``, ``β⁻``).
    """
    alpha = 0.5 + alpha_prior  # α_k,i = 1/2 + α⁻_k,i
    beta = beta_prior.copy()  # β⁽⁰⁾ = β⁻
    for _ in range(iterations):
        sigma = np.diag(beta / alpha)  # Σ⁽ⁿ⁾ = diag(β⁽ⁿ⁾ / α)
        x, p, _, _, k = kf_update(x_prior, p_prior, y, h, sigma)  # m⁽ⁿ⁺¹⁾, P⁽ⁿ⁺¹⁾
        residual = y - h @ x
        beta = beta_prior + 0.5 * residual**2 + 0.5 * np.diag(h @ p @ h.T)  # β⁽ⁿ⁺¹⁾
    return x, p, alpha, beta, k


def vbakf_pr_update(
    x_prior: np.ndarray,
    p_nominal: np.ndarray,
    y: np.ndarray,
    h: np.ndarray,
    u_prior: float,
    u_mat_prior: np.ndarray,
    tau: float,
    iterations: int,
) -> tuple[np.ndarray, np.ndarray, float, np.ndarray, np.ndarray]:
    """Huang et al. 2018, Algorithm 1, the measurement update: ``x, P, û, Û`` and the last
    gain ``K``.

    ``p_nominal`` is the nominal ``P̃_{k|k−1} = F P Fᵀ + Q``; ``u_prior``, ``u_mat_prior`` the
    predicted ``û_{k|k−1}``, ``Û_{k|k−1}``. Shapes: x (n,), p (n, n), y (m,), h (m, n).
    """
    n, m = x_prior.size, y.size
    t_prior, t_mat_prior = n + tau + 1.0, tau * p_nominal  # t̂_{k|k−1}, T̂_{k|k−1}
    t, u = t_prior + 1.0, u_prior + 1.0  # t̂_k, û_k
    x, p = x_prior, p_nominal  # x⁽⁰⁾, P⁽⁰⁾
    for _ in range(iterations):
        a = p + np.outer(x - x_prior, x - x_prior)  # A⁽ⁱ⁾
        t_mat = a + t_mat_prior  # T̂⁽ⁱ⁺¹⁾
        b = np.outer(y - h @ x, y - h @ x) + h @ p @ h.T  # B⁽ⁱ⁾
        u_mat = b + u_mat_prior  # Û⁽ⁱ⁺¹⁾
        p_pred = t_mat / (t - n - 1.0)  # P̃⁽ⁱ⁺¹⁾ = {E[P⁻¹]}⁻¹, E[P⁻¹] = (t̂ − n − 1) T̂⁻¹
        r = u_mat / (u - m - 1.0)  # R̃⁽ⁱ⁺¹⁾ = {E[R⁻¹]}⁻¹
        x, p, _, _, k = kf_update(x_prior, p_pred, y, h, r)  # x⁽ⁱ⁺¹⁾, P⁽ⁱ⁺¹⁾
    return x, p, u, u_mat, k


def gaussian_likelihood(innov: np.ndarray, s: np.ndarray) -> float:
    """``N(r; 0, S)``, the likelihood of an innovation ``r`` (m,) with covariance ``S``."""
    m = innov.size
    nis = innov @ np.linalg.solve(s, innov)
    return float(np.exp(-0.5 * nis) / np.sqrt((2.0 * np.pi) ** m * np.linalg.det(s)))


class BankReference:
    """The IMM (or MMAE) cycle over m Kalman filters, Blom & Bar-Shalom 1988.

    ``q0`` (n, n) and ``r0`` (m, m) are Q(0), R(0); model j has ``q_scales[j] Q(0)`` and
    ``r_scales[j] R(0)``. ``x``, ``p`` are the combined estimate.
    """

    def __init__(self, cfg: FilterConfig, x0: np.ndarray, p0: np.ndarray, q0, r0) -> None:
        bank = cfg.imm
        self.pi, self.mmae = bank.matrix(), bank.mixing == "mmae"
        self.q = [s * q0 for s in bank.scales()[:, 0]]
        self.r = [s * r0 for s in bank.scales()[:, 1]]
        self.restart(x0, p0)

    def restart(self, x0: np.ndarray, p0: np.ndarray) -> None:
        m = len(self.q)
        self.xs, self.ps = [x0.copy() for _ in range(m)], [p0.copy() for _ in range(m)]
        self.mu = np.full(m, 1.0 / m)
        self.x, self.p = x0.copy(), p0.copy()

    def predict(self) -> None:
        """Mixing (IMM) and each model's prediction; the combined prediction."""
        m = len(self.q)
        if not self.mmae:
            cbar = self.pi.T @ self.mu  # c̄_j = Σ_i Π_ij μ_i
            xs, ps = [], []
            for j in range(m):
                w = self.pi[:, j] * self.mu / cbar[j] if cbar[j] > 0 else np.eye(m)[j]  # μ_i|j
                x0j = sum(w[i] * self.xs[i] for i in range(m))
                p0j = sum(
                    w[i] * (self.ps[i] + np.outer(self.xs[i] - x0j, self.xs[i] - x0j))
                    for i in range(m)
                )
                xs.append(x0j)
                ps.append(p0j)
            self.xs, self.ps, self.mu = xs, ps, cbar
        for j in range(m):
            self.xs[j], self.ps[j] = kf_predict(self.xs[j], self.ps[j], self.q[j])
        self.x, self.p = self._combined()

    def noise(self) -> tuple[np.ndarray, np.ndarray]:
        """The probability-weighted Q and R of the bank."""
        weights = list(self.mu)
        return sum(w * q for w, q in zip(weights, self.q, strict=True)), sum(
            w * r for w, r in zip(weights, self.r, strict=True)
        )

    def update(self, y: np.ndarray, h: np.ndarray) -> np.ndarray:
        """Each model's update, the probabilities, the combination; returns the combined
        prediction's gain."""
        _, r_mix = self.noise()
        s = h @ self.p @ h.T + r_mix
        gain = self.p @ h.T @ np.linalg.inv(s)
        likelihood = np.empty(len(self.q))
        for j in range(len(self.q)):
            self.xs[j], self.ps[j], innov, s_j, _ = kf_update(
                self.xs[j], self.ps[j], y, h, self.r[j]
            )
            likelihood[j] = gaussian_likelihood(innov, s_j)
        self.mu = self.mu * likelihood / np.sum(self.mu * likelihood)  # μ_j = c̄_j Λ_j / c
        self.x, self.p = self._combined()
        return gain

    def _combined(self) -> tuple[np.ndarray, np.ndarray]:
        x = sum(w * xj for w, xj in zip(self.mu, self.xs, strict=True))
        p = sum(
            w * (pj + np.outer(xj - x, xj - x))
            for w, xj, pj in zip(self.mu, self.xs, self.ps, strict=True)
        )
        return x, p


class VariationalReference:
    """``vbakf`` or ``vbakf-pr`` between samples: the state, ``P``, Q and R's posterior (α, β
    per axis, or û, Û)."""

    def __init__(self, cfg: FilterConfig, x0: np.ndarray, p0: np.ndarray, q0, r0) -> None:
        self.cfg, self.q, self.r0 = cfg, q0, r0
        self.restart(x0, p0)

    def restart(self, x0: np.ndarray, p0: np.ndarray) -> None:
        self.x, self.p = x0.copy(), p0.copy()
        m = self.r0.shape[0]
        if self.cfg.method == "vbakf":  # α₀, β₀ = α₀ R(0)_ii
            self.alpha = np.full(m, self.cfg.vbakf.prior_shape)
            self.beta = self.alpha * np.diag(self.r0)
        else:  # û₀ = prior_dof + m + 1, Û₀ = prior_dof R(0)
            self.u = self.cfg.vbakf_pr.prior_dof + m + 1.0
            self.u_mat = self.cfg.vbakf_pr.prior_dof * self.r0

    @property
    def r(self) -> np.ndarray:
        """The estimate R̂: ``diag(β / α)`` or ``Û / (û − m − 1)``."""
        if self.cfg.method == "vbakf":
            return np.diag(self.beta / self.alpha)
        return self.u_mat / (self.u - self.r0.shape[0] - 1.0)

    def predict(self) -> None:
        self.x, self.p = kf_predict(self.x, self.p, self.q)  # x⁻, P⁻ (P̃⁻ of vbakf-pr)

    def _forget(self) -> None:
        """R's posterior predicted: the papers' forgetting, done here on the samples that
        update (a skipped or rejected sample leaves it as it was)."""
        m = self.r0.shape[0]
        if self.cfg.method == "vbakf":  # α⁻ = ρ α, β⁻ = ρ β
            self.alpha, self.beta = self.cfg.vbakf.rho * self.alpha, self.cfg.vbakf.rho * self.beta
        else:  # û⁻ = ρ(û − m − 1) + m + 1, Û⁻ = ρ Û
            rho = self.cfg.vbakf_pr.rho
            self.u, self.u_mat = rho * (self.u - m - 1.0) + m + 1.0, rho * self.u_mat

    def noise(self) -> tuple[np.ndarray, np.ndarray]:
        return self.q, self.r

    def update(self, y: np.ndarray, h: np.ndarray) -> np.ndarray:
        """R's posterior predicted, then the variational update; returns the last gain."""
        self._forget()
        if self.cfg.method == "vbakf":
            vb = self.cfg.vbakf
            self.x, self.p, self.alpha, self.beta, gain = vbakf_update(
                self.x, self.p, y, h, self.alpha, self.beta, vb.iterations
            )
        else:
            pr = self.cfg.vbakf_pr
            self.x, self.p, self.u, self.u_mat, gain = vbakf_pr_update(
                self.x, self.p, y, h, self.u, self.u_mat, pr.tau, pr.iterations
            )
        return gain

    def clamp(self, lo: float, hi: float) -> None:
        """Keep tr Q / tr Q(0) and tr R̂ / tr R(0) within [lo, hi] (the runaway guard)."""
        ratio = np.trace(self.r) / np.trace(self.r0)
        factor = np.clip(ratio, lo, hi) / ratio
        if self.cfg.method == "vbakf":
            self.beta = self.beta * factor
        else:
            self.u_mat = self.u_mat * factor


class PlainReference:
    """The plain KF with Q(0), R(0) that a variational filter goes on as after a runaway."""

    def __init__(self, x: np.ndarray, p: np.ndarray, q0: np.ndarray, r0: np.ndarray) -> None:
        self.x, self.p, self.q, self.r = x, p, q0, r0

    def restart(self, x0: np.ndarray, p0: np.ndarray) -> None:
        self.x, self.p = x0.copy(), p0.copy()

    def predict(self) -> None:
        self.x, self.p = kf_predict(self.x, self.p, self.q)

    def noise(self) -> tuple[np.ndarray, np.ndarray]:
        return self.q, self.r

    def update(self, y: np.ndarray, h: np.ndarray) -> np.ndarray:
        self.x, self.p, _, _, gain = kf_update(self.x, self.p, y, h, self.r)
        return gain


def run_adaptive_reference(
    cfg: FilterConfig, y: np.ndarray, t_b: np.ndarray, tdot_b: np.ndarray
) -> FilterResult:
    """Same contract as :func:`aeromag_env.compensation.kalman.run_filter` for the methods of
    :data:`ADAPTIVE_METHODS`, with the consistency checks (outlier gate, sustained shift,
    runaway of the variational filters) and not the restarts of a non-finite or indefinite
    covariance."""
    n, d = y.shape[0], STATE_SCALE
    h_all = measurement_rows(t_b, tdot_b) * d  # H_s = H diag(d)
    valid = np.all(np.isfinite(y), axis=1) & np.all(np.isfinite(h_all), axis=(1, 2))
    x0, p0 = cfg.initial_state() / d, cfg.initial_covariance() / np.outer(d, d)
    q0, r0 = np.diag(cfg.process_noise() / d**2), cfg.measurement_noise()
    kind = BankReference if cfg.method == "imm" else VariationalReference
    filt: BankReference | VariationalReference | PlainReference = kind(cfg, x0, p0, q0, r0)
    variational = cfg.method != "imm"
    out = {k: np.full(n, np.nan) for k in ("ror", "qoq", "q_scale", "r_scale")}
    est, innovations = np.full((n, 3), np.nan), np.full((n, 3), np.nan)
    states = np.zeros((n, N_STATES))
    counts = {"skipped": 0, "divergences": 0, "outliers": 0}
    window: list[tuple[np.ndarray, float]] = []
    gate, good = Consistency(cfg.window), x0.copy()
    for k in range(n):
        filt.predict()
        est[k] = h_all[k] @ filt.x
        gain, rejected, restart = None, False, False
        if not valid[k]:
            counts["skipped"] += 1
        else:
            innovations[k] = y[k] - est[k]  # r = y − H x⁻
            s = h_all[k] @ filt.p @ h_all[k].T + filt.noise()[1]  # S = H P⁻ Hᵀ + R
            rejected = gate.outlier(innovations[k], s, window)
            if rejected:  # predict only; a whole window that shifts the data: restart
                counts["outliers"] += 1
                restart = gate.reject(innovations[k])
            else:
                gain = filt.update(y[k], h_all[k])
                window = [*window, (innovations[k], float(np.trace(s)))][-cfg.window :]
                lap = gate.added(window)
                restart = variational and lap and runaway(k, cfg.window, y, est, valid)
                if not restart:
                    good = filt.x.copy()
        if restart:
            counts["divergences"] += 1
            if variational and not rejected:  # a runaway: go on as the plain KF
                filt, variational = PlainReference(good, p0, q0, r0), False
            filt.restart(good, p0)
            window = []
            gate.clear()
        if isinstance(filt, VariationalReference) and not rejected:
            filt.clamp(*cfg.scale_bounds)
        q, r = filt.noise()
        if window:
            out["ror"][k], out["qoq"][k] = _ratios(window, gain, q)
        out["q_scale"][k] = np.trace(q) / np.trace(q0) if np.trace(q0) > 0 else np.nan
        out["r_scale"][k] = np.trace(r) / np.trace(r0)
        states[k] = filt.x * d
    q, r = (q0, r0) if cfg.method == "imm" else filt.noise()  # imm: the base, as compiled
    return FilterResult(
        est,
        innovations,
        out["ror"],
        out["qoq"],
        out["q_scale"],
        out["r_scale"],
        states,
        filt.x * d,
        filt.p * np.outer(d, d),
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
