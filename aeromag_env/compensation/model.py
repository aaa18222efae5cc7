"""The 21-state measurement model of the paper (§3.2) and the filter configuration.

State ``x = [T_p (3), A row-major (9), B row-major (9)]`` (layout named once in
:data:`aeromag_env.simulation.interference.STATE_SLICES`), ``Φ = I``, measurement ``y = T_m − T``
(3) with ``H(k)`` of eq. 12: row ``i`` holds 1 at ``T_p,i``, ``T(k)ᵀ`` at ``A_i·`` and ``Ṫ(k)ᵀ`` at
``B_i·``. The paper's discrete form (eq. 14) writes ``T(k+1)`` where the continuous form (eq. 12)
has ``Ṫ``; we use ``Ṫ`` (a backward difference for causal use).

The filter runs on the normalised state ``z = x / d`` with ``d`` the typical magnitudes
(:data:`STATE_SCALE`: 100 nT, 1e-3, 1e-4 s), so ``P`` is well conditioned; the Kalman filter is
invariant to such a reparametrisation, so the estimates are those of the unscaled filter.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import IntEnum

import numpy as np

from aeromag_env.compensation.adaptive_settings import ModelBank, VbakfPrSettings, VbakfSettings
from aeromag_env.configs import check, require_nonnegative, require_positive
from aeromag_env.simulation.interference import (
    BLOCK_SIZES,
    EDDY_START,
    INDUCED_START,
    N_STATES,
    PERMANENT_START,
    STATE_SLICES,
)

#: Typical magnitude of each state block: T_p [nT], A [-], B [s].
BLOCK_SCALE = (100.0, 1e-3, 1e-4)
#: Per-state normalisation ``d`` (21,).
STATE_SCALE = np.repeat(BLOCK_SCALE, BLOCK_SIZES).astype(float)

METHODS = ("kf", "fakf", "rls", "sage-husa", "ding", "vbakf", "vbakf-pr", "imm")


class FilterMode(IntEnum):
    """The methods of :data:`METHODS` as the compiled loop knows them (an ``int`` argument,
    compared with these members, which numba reads as constants)."""

    KF = 0
    FAKF = 1
    RLS = 2
    SAGE_HUSA = 3
    DING = 4
    VBAKF = 5
    VBAKF_PR = 6
    IMM = 7


#: Method name → its :class:`FilterMode`.
MODE = {name: FilterMode[name.upper().replace("-", "_")] for name in METHODS}


def measurement_rows(t_b: np.ndarray, tdot_b: np.ndarray) -> np.ndarray:
    """``H(k)`` of eq. 12 for every sample.

    Parameters
    ----------
    t_b : ndarray, shape (n, 3)       body-frame Earth field [nT]
    tdot_b : ndarray, shape (n, 3)    its time derivative [nT/s]

    Returns
    -------
    ndarray, shape (n, 3, 21)
    """
    n = t_b.shape[0]
    h = np.zeros((n, 3, N_STATES))
    for i in range(3):
        h[:, i, PERMANENT_START + i] = 1.0
        h[:, i, INDUCED_START + 3 * i : INDUCED_START + 3 * i + 3] = t_b
        h[:, i, EDDY_START + 3 * i : EDDY_START + 3 * i + 3] = tdot_b
    return h


def interference_from_states(x: np.ndarray, t_b: np.ndarray, tdot_b: np.ndarray) -> np.ndarray:
    """``H(k) x(k)`` for a state history (n, 21) or one state (21,) → (n, 3) [nT]."""
    x = np.broadcast_to(x, (t_b.shape[0], N_STATES))
    a = x[:, STATE_SLICES["induced"]].reshape(-1, 3, 3)
    b = x[:, STATE_SLICES["eddy"]].reshape(-1, 3, 3)
    return (
        x[:, STATE_SLICES["permanent"]]
        + np.einsum("kij,kj->ki", a, t_b)
        + np.einsum("kij,kj->ki", b, tdot_b)
    )


@dataclass(frozen=True, kw_only=True)
class FilterConfig:
    """Settings of the recursive compensators (one dataclass for all ``METHODS``).

    Attributes
    ----------
    method : ``kf`` (eqs. 17–20), ``fakf`` (fuzzy adaptive, eq. 21), ``rls`` (recursive least
        squares with forgetting), ``sage-husa``, ``ding`` (Ding et al. 2007 trace-ratio Q
        scaling), ``vbakf`` (variational Bayes, R estimated: Särkkä & Nummenmaa 2009),
        ``vbakf-pr`` (variational Bayes, P⁻ and R estimated: Huang et al. 2018), ``imm`` (a
        bank of filters over Q and R scales: interacting multiple models, or MMAE).
    p0_std : prior std per block (T_p [nT], A [-], B [s]); ``P(0)`` is diagonal. Defaults are
        loose priors around zero (2.5× the ``nominal`` simulator's coefficient spread).
    q_std : process-noise std per block per sample (random walk of the coefficients); the
        default lets T_p drift by ~0.02 nT per hour at 10 Hz: the coefficients are constants.
    r_std_nt : measurement-noise std per axis [nT]; ``R(0) = r_std² I``. Default 1.5 nT: the
        ``nominal`` fluxgate's 1 nT white + 1 nT FOGM noise.
    x0 : initial state (21 values) or None for zeros.
    window : M, samples in the windowed innovation covariance ``C_r`` (eq. 24).
    adapt_interval : samples between two adaptations of Q and R (``fakf``, ``ding``).
    epsilon, eta : FIS tolerances for R and Q (paper: 0.05, 0.025).
    zoom_r, zoom_q : the zoom levels b_r, b_a, applied as exponents ``s = s_FIS ** b``.
    forgetting : RLS forgetting factor λ (``P⁻ = P / λ``).
    sage_husa_b : Sage–Husa fading factor b.
    sage_husa_q : let Sage–Husa estimate Q as well as R. Off by default: estimating both from
        the same innovations is not guaranteed to converge, and on ``nominal`` flights Q runs
        away (×1e6, errors of ~100 nT); R-only Sage–Husa is the usual safe variant.
    sage_husa_form : how Sage–Husa estimates R. ``post_fit`` (default): from the post-fit
        residual, ``e eᵀ + H P⁺ Hᵀ``, always positive definite and never ran away in our tests,
        but it cannot recover from an R far too small (the residual vanishes with it: stuck at
        the paper's R(0)). ``innovation``: the classic ``r rᵀ − H P⁻ Hᵀ`` with the biased
        ``r rᵀ`` where that is not positive definite; it recovers the paper's 20 nT from
        R(0) = 2e-3 nT², but an interference step can make it run away.
    scale_bounds : limits of the adapted Q and R relative to Q(0), R(0) (runaway guard).
    rate_scheme : ``backward`` (causal) or ``central`` (offline) derivative for ``Ṫ``.
    vbakf : the settings of ``vbakf`` (:class:`~aeromag_env.compensation.adaptive_settings.
        VbakfSettings`: ρ, iterations, prior).
    vbakf_pr : the settings of ``vbakf-pr`` (:class:`~aeromag_env.compensation.
        adaptive_settings.VbakfPrSettings`: τ, ρ, iterations, prior).
    imm : the bank of ``imm`` (:class:`~aeromag_env.compensation.adaptive_settings.ModelBank`:
        the models' Q and R scales around Q(0) and R(0), the switching matrix, IMM or MMAE).
    """

    method: str = "kf"
    p0_std: tuple[float, ...] = (500.0, 5e-3, 1e-3)
    q_std: tuple[float, ...] = (1e-4, 1e-9, 1e-10)
    r_std_nt: float = 1.5
    x0: tuple[float, ...] | None = None
    window: int = 50
    adapt_interval: int = 50
    epsilon: float = 0.05
    eta: float = 0.025
    zoom_r: float = 1.0
    zoom_q: float = 1.0
    forgetting: float = 0.9999
    sage_husa_b: float = 0.99
    sage_husa_q: bool = False
    sage_husa_form: str = "post_fit"
    scale_bounds: tuple[float, ...] = (1e-8, 1e8)
    rate_scheme: str = "backward"
    vbakf: VbakfSettings = field(default_factory=VbakfSettings)
    vbakf_pr: VbakfPrSettings = field(default_factory=VbakfPrSettings)
    imm: ModelBank = field(default_factory=ModelBank)

    def __post_init__(self) -> None:
        check(
            self.method in METHODS,
            f"method must be one of {', '.join(METHODS)}; got {self.method!r}",
        )
        check(
            len(self.p0_std) == len(BLOCK_SIZES) and len(self.q_std) == len(BLOCK_SIZES),
            "p0_std and q_std need 3 values (T_p, A, B)",
        )
        check(all(v > 0 for v in self.p0_std), "FilterConfig.p0_std must be > 0")
        check(all(v >= 0 for v in self.q_std), "FilterConfig.q_std must be ≥ 0")
        require_positive(self, "r_std_nt", "epsilon", "eta")
        require_nonnegative(self, "zoom_r", "zoom_q")
        check(self.x0 is None or len(self.x0) == N_STATES, "FilterConfig.x0 needs 21 values")
        check(
            self.window >= 2 and self.adapt_interval >= 1,
            "window must be ≥ 2 and adapt_interval ≥ 1",
        )
        check(0 < self.forgetting <= 1, f"forgetting must be in (0, 1], got {self.forgetting}")
        check(0 < self.sage_husa_b < 1, f"sage_husa_b must be in (0, 1), got {self.sage_husa_b}")
        lo, hi = self.scale_bounds
        check(0 < lo < 1 < hi and math.isfinite(hi), "scale_bounds must be (lo < 1 < hi), finite")
        check(
            self.rate_scheme in ("backward", "central"), "rate_scheme must be backward or central"
        )
        check(
            self.sage_husa_form in ("post_fit", "innovation"),
            f"sage_husa_form must be post_fit or innovation, got {self.sage_husa_form!r}",
        )
        for name, kind in (
            ("vbakf", VbakfSettings),
            ("vbakf_pr", VbakfPrSettings),
            ("imm", ModelBank),
        ):
            value = getattr(self, name)
            check(
                isinstance(value, kind),
                f"FilterConfig.{name} must be a {kind.__name__}, got {type(value).__name__}",
            )

    def initial_state(self) -> np.ndarray:
        """``x(0)`` (21,)."""
        return np.zeros(N_STATES) if self.x0 is None else np.asarray(self.x0, dtype=float)

    def initial_covariance(self) -> np.ndarray:
        """``P(0)`` (21, 21), diagonal."""
        return np.diag(np.repeat(np.square(self.p0_std), BLOCK_SIZES))

    def process_noise(self) -> np.ndarray:
        """Diagonal of ``Q(0)`` (21,)."""
        return np.repeat(np.square(self.q_std), BLOCK_SIZES).astype(float)

    def measurement_noise(self) -> np.ndarray:
        """``R(0)`` (3, 3)."""
        return np.eye(3) * self.r_std_nt**2


def paper_filter_config(method: str = "fakf") -> FilterConfig:
    """The paper's §4 setting: ``Q(0) = 1e-3 I``, ``R(0) = 2e-3 I``, ε = 0.05, η = 0.025.

    ``Q(0)`` is read in the normalised state coordinates (the paper's own coordinates have no
    stated units); ``R(0)`` is in nT² (σ ≈ 0.045 nT against the 20 nT true noise). ``x(0)``:
    the paper's ``T_p(0) = 0.1`` nT is kept; its ``A(0) = 10`` and ``B(0) = 15`` are not
    physical for a dimensionless ``A`` and ``B`` in seconds and are replaced by 0.
    """
    q = math.sqrt(1e-3)
    return FilterConfig(
        method=method,
        q_std=tuple(q * s for s in BLOCK_SCALE),
        r_std_nt=math.sqrt(2e-3),
        x0=(0.1,) * BLOCK_SIZES[0] + (0.0,) * (N_STATES - BLOCK_SIZES[0]),  # T_p(0) = 0.1 nT
        epsilon=0.05,
        eta=0.025,
    )
