"""Recursive compensators (KF, fuzzy adaptive KF, RLS, Sage–Husa, Ding, the variational KFs, the
bank of models) as a stateful filter.

:class:`FilterState` holds everything the compiled loop
(:func:`aeromag_env.compensation.kernels.advance`) updates — the arrays of
:class:`aeromag_env.compensation.arrays.FilterArrays`, each an attribute of the same name — so a
caller can advance a flight window by window and rescale Q and R in between (the environment
does); :func:`run_filter` runs a whole flight.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from aeromag_env.compensation.arrays import FilterArrays, filter_arrays, packed
from aeromag_env.compensation.kernel_layout import INTS, N_ACC, N_INT, N_PAR, PAR
from aeromag_env.compensation.kernels import advance
from aeromag_env.compensation.model import MODE, STATE_SCALE, FilterConfig, FilterMode
from aeromag_env.compensation.variational import M_MEAS
from aeromag_env.errors import ConfigError
from aeromag_env.simulation.interference import N_STATES


@dataclass
class FilterResult:
    """Outputs of a filter run over n samples.

    Attributes
    ----------
    interference : (n, 3) a-priori interference estimate ``H(k) x(k|k−1)`` [nT] (causal)
    innovations : (n, 3) ``r_k`` [nT] (NaN where the sample was skipped)
    ror, qoq : (n,) windowed consistency ratios (eq. 22; NaN until the window has data)
    q_scale, r_scale : (n,) tr Q / tr Q(0), tr R / tr R(0) (imm: of the bank's
        probability-weighted Q and R)
    states : (n, 21) posterior states [physical units] (empty when not stored)
    final_state : (21,) ``x`` after the last sample
    final_covariance : (21, 21) ``P`` after the last sample [physical units]
    final_r : (3, 3) ``R`` after the last sample [nT²] (adapted by fakf, sage-husa and the
        variational filters; for imm the base the models' scales multiply)
    final_q : (21,) diagonal of ``Q`` after the last sample [physical units²] (imm: the base)
    divergences : restarts: a non-finite or absurd state, a non-finite or non-positive-definite
        covariance, an adaptive filter's runaway, or a whole window of outliers that shift the data
        (:mod:`aeromag_env.compensation.consistency`)
    skipped : samples with non-finite input (predict only)
    outliers_rejected : samples whose innovation failed the outlier gate (predict only)
    """

    interference: np.ndarray
    innovations: np.ndarray
    ror: np.ndarray
    qoq: np.ndarray
    q_scale: np.ndarray
    r_scale: np.ndarray
    states: np.ndarray
    final_state: np.ndarray
    final_covariance: np.ndarray
    final_r: np.ndarray
    final_q: np.ndarray
    divergences: int
    skipped: int
    outliers_rejected: int = 0


class FilterState:
    """State of one recursive compensator over one flight, in normalised coordinates.

    Parameters
    ----------
    cfg : FilterConfig
    y : (n, 3) measurement ``T_m − T`` [nT]
    t_b, tdot_b : (n, 3) model Earth field in body axes [nT] and its rate [nT/s]
    store_states : keep the (n, 21) posterior state history

    Attributes
    ----------
    mode : the method's :class:`~aeromag_env.compensation.model.FilterMode`, as an int
    every name of :data:`aeromag_env.compensation.arrays.CORE_ARRAYS` : that array (updated in
        place, never replaced)
    """

    def __init__(
        self,
        cfg: FilterConfig,
        y: np.ndarray,
        t_b: np.ndarray,
        tdot_b: np.ndarray,
        store_states: bool = True,
    ) -> None:
        n = y.shape[0]
        self.cfg = cfg
        self.mode = int(MODE[cfg.method])
        self.d = STATE_SCALE.copy()
        finite = np.isfinite(y), np.isfinite(t_b), np.isfinite(tdot_b)
        both = finite[0] & finite[1] & finite[2]
        # every axis finite: all(axis=1) by its three columns (reducing over the 3-wide axis is
        # ten times slower, a quarter of a training environment's reset)
        self.valid = both[:, 0] & both[:, 1] & both[:, 2]
        # non-finite inputs become 0 in the arrays the loop reads; those samples only predict
        self.y = np.where(finite[0], y, 0.0)
        self.t = np.ascontiguousarray(np.where(finite[1], t_b, 0.0))
        self.td = np.ascontiguousarray(np.where(finite[2], tdot_b, 0.0))
        self.z = cfg.initial_state() / self.d
        self.p0 = cfg.initial_covariance() / np.outer(self.d, self.d)
        self.p = self.p0.copy()
        self.q0 = cfg.process_noise() / self.d**2
        self.qd = self.q0.copy()
        self.r0 = cfg.measurement_noise()
        self.rm = self.r0.copy()
        self.z_good = self.z.copy()
        self.rbuf = np.zeros((cfg.window, 3))
        self.sbuf = np.zeros(cfg.window)
        self.acc = np.zeros(N_ACC)
        self.ints = np.zeros(N_INT, dtype=np.int64)
        self.ints[INTS.window], self.ints[INTS.interval] = cfg.window, cfg.adapt_interval
        self.par = _parameters(cfg)
        self.vb_shape = np.zeros(M_MEAS)
        self._variational(cfg)
        self._bank(cfg)
        self.est = np.full((n, 3), np.nan)
        self.innov = np.full((n, 3), np.nan)
        self.ror, self.qoq = np.full(n, np.nan), np.full(n, np.nan)
        self.q_scale, self.r_scale = np.full(n, np.nan), np.full(n, np.nan)
        self.states = np.full((n if store_states else 0, N_STATES), np.nan)
        self._arrays = filter_arrays(self)
        self._packed = packed(self._arrays)

    def _variational(self, cfg: FilterConfig) -> None:
        """R's prior shape and the iterations of ``vbakf`` and ``vbakf-pr``."""
        if self.mode == FilterMode.VBAKF:
            self.ints[INTS.iterations] = cfg.vbakf.iterations
            self.vb_shape[:] = cfg.vbakf.prior_shape  # α₀ per axis
        elif self.mode == FilterMode.VBAKF_PR:
            self.ints[INTS.iterations] = cfg.vbakf_pr.iterations
            self.vb_shape[0] = cfg.vbakf_pr.prior_dof  # û₀ − m − 1

    def _bank(self, cfg: FilterConfig) -> None:
        """The bank of ``imm`` (zero models for the other methods): every model at x(0), P(0),
        equally probable."""
        bank = cfg.imm
        m = bank.size if self.mode == FilterMode.IMM else 0
        self.ints[INTS.models] = m
        self.bank_z = np.repeat(self.z[None, :], m, axis=0)
        self.bank_p = np.repeat(self.p0[None, :, :], m, axis=0)
        self.bank_scale = bank.scales()[:m]
        self.bank_follow = bank.follows()[:m]
        self.bank_mu = np.full(m, 1.0 / max(m, 1))
        self.bank_pi = bank.matrix()[:m, :m].copy()

    @property
    def n(self) -> int:
        """Number of samples of the flight."""
        return int(self.y.shape[0])

    @property
    def k(self) -> int:
        """Samples processed so far (the next sample to process)."""
        return int(self.ints[INTS.k])

    @property
    def divergences(self) -> int:
        """Restarts after a divergence so far."""
        return int(self.ints[INTS.div])

    @property
    def outliers_rejected(self) -> int:
        """Samples rejected by the outlier gate so far."""
        return int(self.ints[INTS.out])

    def advance(self, k1: int) -> None:
        """Run the filter from the current sample up to (not including) ``k1``."""
        k1 = min(int(k1), self.n)
        if k1 <= self.k:
            return
        advance(int(self.mode), self.k, k1, self._packed)

    def arrays(self) -> FilterArrays:
        """The filter's arrays, grouped as the compiled loop takes them (the same arrays as the
        attributes, not copies)."""
        return self._arrays

    def packed(self) -> tuple:
        """:meth:`arrays` as plain tuples (:func:`aeromag_env.compensation.arrays.packed`), for
        calls from Python into compiled code."""
        return self._packed

    def scale_noise(self, s_q: float, s_r: float) -> None:
        """Multiply Q and R by ``s_q`` and ``s_r`` (paper eq. 21 with an external tuner).

        Each factor must be a finite real number > 0 (a zero, negative or non-finite one would
        make Q or R singular, indefinite or NaN): a one-line ConfigError otherwise, raised
        before either matrix changes.
        """
        for name, s in (("s_q", s_q), ("s_r", s_r)):
            if not _positive_finite(s):
                raise ConfigError(f"scale_noise: {name} must be a finite number > 0, got {s!r}")
        self.qd *= s_q
        self.rm *= s_r

    def result(self) -> FilterResult:
        """Outputs so far, in physical units."""
        return FilterResult(
            interference=self.est,
            innovations=self.innov,
            ror=self.ror,
            qoq=self.qoq,
            q_scale=self.q_scale,
            r_scale=self.r_scale,
            states=self.states,
            final_state=self.z * self.d,
            final_covariance=self.p * np.outer(self.d, self.d),
            final_r=self.rm.copy(),
            final_q=self.qd * self.d**2,
            divergences=int(self.ints[INTS.div]),
            skipped=int(self.ints[INTS.skip]),
            outliers_rejected=int(self.ints[INTS.out]),
        )


def _positive_finite(value: object) -> bool:
    """A real number (not a bool) that is finite and > 0 as a float."""
    if not isinstance(value, int | float | np.integer | np.floating) or isinstance(
        value, bool | np.bool_
    ):
        return False
    try:
        return 0.0 < float(value) < math.inf  # NaN fails both comparisons
    except OverflowError:  # an int beyond the largest float
        return False


def _parameters(cfg: FilterConfig) -> np.ndarray:
    par = np.zeros(N_PAR)
    par[PAR.eps], par[PAR.eta] = cfg.epsilon, cfg.eta
    par[PAR.zoom_r], par[PAR.zoom_q] = cfg.zoom_r, cfg.zoom_q
    par[PAR.forget], par[PAR.sh_b] = cfg.forgetting, cfg.sage_husa_b
    par[PAR.lo], par[PAR.hi] = cfg.scale_bounds
    par[PAR.sh_q] = float(cfg.sage_husa_q)
    par[PAR.sh_innov] = float(cfg.sage_husa_form == "innovation")
    if cfg.method == "vbakf-pr":
        par[PAR.vb_rho], par[PAR.vb_prior] = cfg.vbakf_pr.rho, cfg.vbakf_pr.prior_dof
    else:
        par[PAR.vb_rho], par[PAR.vb_prior] = cfg.vbakf.rho, cfg.vbakf.prior_shape
    par[PAR.vb_tau] = cfg.vbakf_pr.tau
    par[PAR.mmae] = float(cfg.imm.mixing == "mmae")
    return par


def run_filter(
    cfg: FilterConfig, y: np.ndarray, t_b: np.ndarray, tdot_b: np.ndarray, store_states: bool = True
) -> FilterResult:
    """Run a recursive compensator over a whole flight.

    Parameters
    ----------
    cfg : FilterConfig
    y : ndarray, shape (n, 3)
        ``T_m − T``: vector magnetometer minus the model Earth field in body axes [nT].
    t_b, tdot_b : ndarray, shape (n, 3)
        Model Earth field in body axes [nT] and its time derivative [nT/s].
    store_states : bool
        Keep the posterior state history (n, 21).

    Returns
    -------
    FilterResult
    """
    state = FilterState(cfg, y, t_b, tdot_b, store_states)
    state.advance(state.n)
    return state.result()
