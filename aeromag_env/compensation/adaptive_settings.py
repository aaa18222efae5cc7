"""Settings of the variational-Bayes and multiple-model filters (``vbakf``, ``vbakf-pr``, ``imm``).

Each method's settings are one frozen group of :class:`~aeromag_env.compensation.model.
FilterConfig` (its fields ``vbakf``, ``vbakf_pr`` and ``imm``), validated on construction with
one-line errors naming the field. The defaults were chosen on simulated training flights of the
scenario suite (seeds 1000–1003 of every scenario) by ``experiments/choose_adaptive_defaults.py``,
whose results are committed in ``docs/results/adaptive_defaults.json``: the lowest geometric
mean over those flights of the RMSE (second half of the flight, against the simulator's truth)
over ``kf``'s, one setting at a time; each class says which candidate won and by how much. The
equations are in :mod:`aeromag_env.compensation.variational` and
:mod:`aeromag_env.compensation.multiple_model`, and on the documentation page
``background/adaptive-filters``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from aeromag_env.configs import check, require_positive

#: Most fixed-point iterations a variational filter may run per sample (each costs a 3×3 solve in
#: ``vbakf`` and a whole Kalman update in ``vbakf-pr``).
MAX_ITERATIONS = 100
#: Most models in a bank (the mixing costs m² covariance sums per sample).
MAX_MODELS = 16
#: How far a row of the switching matrix may sum from 1 [-] (rounding of a matrix typed in
#: decimals, e.g. three times 1/3 written as 0.333333333333).
ROW_SUM_TOLERANCE = 1e-9
#: The two ways a bank combines its models.
MIXING = ("imm", "mmae")


def _check_forgetting(owner: str, rho: float) -> None:
    check(
        math.isfinite(rho) and 0.0 < rho <= 1.0,
        f"{owner}.rho (forgetting factor) must be in (0, 1], got {rho}",
    )


def _check_iterations(owner: str, iterations: int) -> None:
    check(
        isinstance(iterations, int | np.integer)
        and not isinstance(iterations, bool)
        and 1 <= iterations <= MAX_ITERATIONS,
        f"{owner}.iterations must be an integer in [1, {MAX_ITERATIONS}], got {iterations!r}",
    )


@dataclass(frozen=True, kw_only=True)
class VbakfSettings:
    """``vbakf``: Särkkä & Nummenmaa 2009, R diagonal with an inverse-Gamma posterior per axis.

    The figures below are geometric-mean RMSE ratios to ``kf`` over the 32 search flights (8
    scenarios × seeds 1000–1003; ``docs/results/adaptive_defaults.json``).

    Attributes
    ----------
    rho : forgetting factor ρ ∈ (0, 1] of the posterior's parameters per sample
        (``α⁻ = ρ α``, ``β⁻ = ρ β``): R is estimated from about ``1 / (1 − ρ)`` samples.
        Default 0.95 (20 samples, 2 s at 10 Hz): ×0.678 against ×0.758–0.777 for 0.8, 0.9,
        0.99, 0.995 and 0.999. The ``paper`` scenario decides it: only at 0.95 did the filter
        climb from the paper's R(0), 2e5 times too small (6.8 against 20.1 nT); on the noise
        scenarios alone a longer memory is a little better (``noise_bursts`` 1.9 nT at 0.999,
        2.2 at 0.95).
    iterations : fixed-point iterations N per sample (``R̂ → KF update → β``), ≥ 1. Default 2:
        ×0.672, as 3 and 5 (within 0.05 %) and better than 1 (×0.840: one pass leaves R at
        its prior's level for the update).
    prior_shape : ``α₀`` of the prior inverse-Gamma, > 0, with ``β₀ = α₀ R(0)_ii`` (the prior's
        R is the filter's R(0)); it counts as ``2 α₀`` samples, and a restart returns to it.
        Default 10, the steady state ``½ / (1 − ρ)`` of ρ = 0.95 (×0.672, against ×0.678 for 1).
    """

    rho: float = 0.95
    iterations: int = 2
    prior_shape: float = 10.0

    def __post_init__(self) -> None:
        _check_forgetting("VbakfSettings", self.rho)
        _check_iterations("VbakfSettings", self.iterations)
        require_positive(self, "prior_shape")


@dataclass(frozen=True, kw_only=True)
class VbakfPrSettings:
    """``vbakf-pr``: Huang, Zhang, Wu, Li & Chambers 2018, the predicted covariance ``P⁻`` and
    the full 3×3 R both with inverse-Wishart posteriors.

    Searched from the authors' demonstration values (τ = 3, ρ = 1 − e⁻⁴, N = 10) on the same
    flights as :class:`VbakfSettings` (figures: geometric-mean RMSE ratios to ``kf``).

    Attributes
    ----------
    tau : τ > 0, the weight of the nominal ``P⁻ = P + Q`` in the prior of ``P⁻``
        (``IW(n + τ + 1, τ P⁻)``). Default 30: ×0.676, against ×0.982 for the authors' 3 and
        ×1.145 for 1 (100: ×0.675). A weak prior lets the first iterations' ``P⁻`` swell with
        the innovation, and R with it; here ``P⁻`` is best left close to its nominal value.
    rho : forgetting factor ρ ∈ (0, 1] of R's posterior per sample
        (``û⁻ = ρ (û − m − 1) + m + 1``, ``Û⁻ = ρ Û``). Default 0.95 (about 20 samples):
        ×0.672, the authors' ``1 − e⁻⁴`` ≈ 0.982 ×0.676, 0.999 ×0.765.
    iterations : fixed-point iterations N per sample, ≥ 1; each is a whole Kalman update of the
        21 states. With N = 1 the update uses the nominal ``P⁻`` (``P⁻⁽¹⁾ = P̃⁻``): the filter
        estimates R alone. Default 2: ×0.671, the authors' 10 ×0.672 at five times the cost;
        N = 1 scored ×0.663 but was not eligible, being no longer the method.
    prior_dof : ``û₀ − m − 1`` > 0 of R's prior, with ``Û₀ = prior_dof · R(0)``, so that the
        prior's R is the filter's R(0); a restart returns to it. Default 21, the
        ``n + τ − m`` of the authors' ``û₀ = n + τ + 1`` at their τ = 3 (whose ``Û₀ = τ R(0)``
        puts the prior's R at R(0)/7 here); 2 and the steady state ``1 / (1 − ρ)`` scored
        within 0.1 %.
    """

    tau: float = 30.0
    rho: float = 0.95
    iterations: int = 2
    prior_dof: float = 21.0

    def __post_init__(self) -> None:
        require_positive(self, "tau", "prior_dof")
        _check_forgetting("VbakfPrSettings", self.rho)
        _check_iterations("VbakfPrSettings", self.iterations)


@dataclass(frozen=True, kw_only=True)
class BankModel:
    """One model of an ``imm`` bank: its Q and R relative to a base.

    Attributes
    ----------
    q_scale, r_scale : the model's Q and R over the base Q and R [-], > 0.
    follows : True: the base is the filter's current Q and R, which an external controller (the
        tuning environment's action, :meth:`~aeromag_env.compensation.kalman.FilterState.
        scale_noise`) rescales, so the model follows it; False: the base is Q(0) and R(0),
        whatever the controller does (a fixed fallback model). Without a controller the two are
        the same.
    """

    q_scale: float = 1.0
    r_scale: float = 1.0
    follows: bool = True

    def __post_init__(self) -> None:
        require_positive(self, "q_scale", "r_scale")
        check(
            isinstance(self.follows, bool | np.bool_),
            f"BankModel.follows must be true or false, got {self.follows!r}",
        )


#: The default bank: the filter's own Q(0), R(0), and R(0) × 0.01 and × 1000 (the R scales of
#: the tuned constants of ``nonstationary`` and ``noise_bursts``, ``agents/tuned_constants.json``)
#: with Q(0) (see :class:`ModelBank`).
DEFAULT_BANK = (
    BankModel(q_scale=1.0, r_scale=1.0),
    BankModel(q_scale=1.0, r_scale=1e-2),
    BankModel(q_scale=1.0, r_scale=1e3),
)


@dataclass(frozen=True, kw_only=True)
class ModelBank:
    """``imm``: a bank of m Kalman filters over (Q, R) scales, switching as a Markov chain.

    Attributes
    ----------
    models : the m models (1 ≤ m ≤ :data:`MAX_MODELS`), each a :class:`BankModel`. Default
        :data:`DEFAULT_BANK`, R(0) × (1, 0.01, 1000): ×0.779 (geometric-mean RMSE ratio to
        ``kf`` over the 32 search flights, ``docs/results/adaptive_defaults.json``), the best of
        the seven banks tried. The whole table of the tuned constants (8 models) scored ×1.50
        and a 3 × 3 grid of Q × (1e-4, 1, 1e4) and R × (0.01, 1, 100) ×1.30: mixing models of
        very different Q makes the combined estimate follow the loosest one. A bank of Q scales
        alone (Q × 1e4 and 1e-4) follows the interference steps of ``nonstationary`` (3.1 nT,
        against 26 nT for the default bank) but not the noise of ``noise_bursts`` (53 nT,
        against 2.2).
    stay : probability that the model in force stays in force from one sample to the next,
        in (0, 1]; the rest is spread evenly over the other models. Used when ``transition``
        is empty. Default 0.999 (a model is expected to hold ~100 s at 10 Hz): ×0.773, with
        0.9999 and 0.99999 within 0.2 % and 0.99 ×0.779, 0.9 ×0.807.
    transition : the whole switching matrix instead, row-major m × m: entry (i, j) the
        probability of model j at sample k given model i at k − 1; each entry in [0, 1], each
        row summing to 1. Empty (default): built from ``stay``.
    mixing : ``imm`` (default: interacting multiple models, Blom & Bar-Shalom 1988, the models'
        estimates mixed before every prediction; ×0.773) or ``mmae`` (multiple-model adaptive
        estimation, Magill 1965: no mixing, each model runs on its own and only the weights
        move; the switching matrix is then not used, and a model whose weight underflows to 0
        stays at 0: ×0.921, locked on one model early in most flights).
    """

    models: tuple[BankModel, ...] = DEFAULT_BANK
    stay: float = 0.999
    transition: tuple[float, ...] = ()
    mixing: str = "imm"

    def __post_init__(self) -> None:
        m = len(self.models)
        check(
            1 <= m <= MAX_MODELS and all(isinstance(b, BankModel) for b in self.models),
            f"ModelBank.models must hold 1 to {MAX_MODELS} BankModel entries, got {m}",
        )
        check(
            math.isfinite(self.stay) and 0.0 < self.stay <= 1.0,
            f"ModelBank.stay must be in (0, 1], got {self.stay}",
        )
        check(
            self.mixing in MIXING,
            f"ModelBank.mixing must be one of {', '.join(MIXING)}, got {self.mixing!r}",
        )
        if self.transition:
            self._check_transition(m)

    def _check_transition(self, m: int) -> None:
        check(
            len(self.transition) == m * m,
            f"ModelBank.transition needs {m}×{m} = {m * m} values (row-major) for {m} models, "
            f"got {len(self.transition)}",
        )
        pi = np.asarray(self.transition, dtype=float).reshape(m, m)
        check(
            bool(np.all(np.isfinite(pi) & (pi >= 0.0) & (pi <= 1.0))),
            "ModelBank.transition entries must be probabilities in [0, 1]",
        )
        sums = pi.sum(axis=1)
        for i in np.flatnonzero(np.abs(sums - 1.0) > ROW_SUM_TOLERANCE)[:1]:
            check(False, f"ModelBank.transition row {i} sums to {sums[i]:.12g}, must sum to 1")

    @property
    def size(self) -> int:
        """m, the number of models."""
        return len(self.models)

    def matrix(self) -> np.ndarray:
        """The switching matrix (m, m): ``transition``, or ``stay`` on the diagonal and the rest
        spread evenly."""
        m = self.size
        if self.transition:
            return np.asarray(self.transition, dtype=float).reshape(m, m)
        if m == 1:
            return np.ones((1, 1))
        pi = np.full((m, m), (1.0 - self.stay) / (m - 1))
        np.fill_diagonal(pi, self.stay)
        return pi

    def scales(self) -> np.ndarray:
        """(m, 2) the models' Q and R scales."""
        return np.array([(b.q_scale, b.r_scale) for b in self.models], dtype=float)

    def follows(self) -> np.ndarray:
        """(m,) bool: which models follow an external controller's rescaling."""
        return np.array([bool(b.follows) for b in self.models], dtype=bool)
