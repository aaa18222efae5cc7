"""Batch least squares of the 21-parameter vector model (the offline optimum the filters chase).

``y_i(k) = T_p,i + A_i· T(k) + B_i· Ṫ(k) + v_i(k)`` decouples by axis: three independent least
squares problems with the 7 regressors ``[1, T_x, T_y, T_z, Ṫ_x, Ṫ_y, Ṫ_z]``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aeromag_env.compensation.model import interference_from_states
from aeromag_env.errors import AeromagError
from aeromag_env.simulation.interference import VectorCoefficients


@dataclass(frozen=True)
class BatchFit:
    """Result of :func:`fit_vector_lsq`.

    Attributes
    ----------
    state : (21,) ``[T_p, A row-major, B row-major]``
    residual_std_nt : (3,) std of the fit residual per axis [nT]
    condition_number : (3,) condition number of each axis's (column-scaled) design
    n_samples : samples used
    """

    state: np.ndarray
    residual_std_nt: np.ndarray
    condition_number: np.ndarray
    n_samples: int

    @property
    def coefficients(self) -> VectorCoefficients:
        """The state as ``T_p``, ``A``, ``B``."""
        return VectorCoefficients.from_state(self.state)

    def predict(self, t_b: np.ndarray, tdot_b: np.ndarray) -> np.ndarray:
        """Interference ``T_p + A T + B Ṫ`` (n, 3) [nT]."""
        return interference_from_states(self.state, t_b, tdot_b)


def fit_vector_lsq(
    y: np.ndarray,
    t_b: np.ndarray,
    tdot_b: np.ndarray,
    mask: np.ndarray | None = None,
    ridge: float = 0.0,
) -> BatchFit:
    """Least-squares fit of ``T_p``, ``A``, ``B`` to ``y = T_m − T``.

    Parameters
    ----------
    y : ndarray, shape (n, 3)     measured minus model Earth field [nT]
    t_b, tdot_b : ndarray, shape (n, 3)   model field [nT] and its rate [nT/s]
    mask : ndarray of bool, shape (n,), optional
        Samples to fit (e.g. a calibration window); non-finite samples are always dropped.
    ridge : float
        Tikhonov weight on the column-normalised coefficients (0: plain least squares).

    Returns
    -------
    BatchFit
    """
    design = np.column_stack([np.ones(len(y)), t_b, tdot_b])  # (n, 7), shared by the three axes
    use = np.all(np.isfinite(design), axis=1) & np.all(np.isfinite(y), axis=1)
    if mask is not None:
        use &= mask
    if use.sum() < 4 * design.shape[1]:
        raise AeromagError(
            f"batch least squares needs at least 28 usable samples, got {int(use.sum())}"
        )
    a, yy = design[use], y[use]
    norm = np.sqrt(np.mean(a**2, axis=0))  # column scaling: a well-conditioned solve
    norm[norm == 0] = 1.0
    a_s = a / norm
    if ridge > 0:
        a_s = np.vstack([a_s, np.sqrt(ridge * len(a_s)) * np.eye(a_s.shape[1])])
    coef = np.empty((3, 7))
    resid = np.empty(3)
    for i in range(3):
        target = yy[:, i] if ridge == 0 else np.r_[yy[:, i], np.zeros(7)]
        sol, *_ = np.linalg.lstsq(a_s, target, rcond=None)
        coef[i] = sol / norm
        resid[i] = np.std(yy[:, i] - a @ coef[i])
    cond = np.full(3, np.linalg.cond(a / norm))
    state = np.concatenate([coef[:, 0], coef[:, 1:4].ravel(), coef[:, 4:7].ravel()])
    return BatchFit(
        state=state, residual_std_nt=resid, condition_number=cond, n_samples=int(use.sum())
    )
