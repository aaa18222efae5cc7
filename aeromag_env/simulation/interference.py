"""Aircraft magnetic interference at a magnetometer (paper eq. 5 / 9).

``ΔT = T_p + A T + B Ṫ`` in the body frame, with ``T_p`` the permanent field [nT], ``A`` the
induced-field matrix [-], ``B`` the eddy-current matrix [s], ``T`` the body-frame ambient field
[nT] and ``Ṫ`` its time derivative [nT/s]. The 21-parameter state layout of the compensator is
``[T_p (3), A row-major (9), B row-major (9)]`` (:data:`STATE_SLICES`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aeromag_env.simulation.config import InterferenceConfig

#: The 21-state layout, named once: the first index of each block and the state count (plain
#: ints, which compiled code reads as constants). ``A`` and ``B`` are row-major 3×3 blocks, so
#: ``A[i, j]`` is state ``INDUCED_START + 3 i + j``.
PERMANENT_START, INDUCED_START, EDDY_START, N_STATES = 0, 3, 12, 21
#: The blocks by name, as slices of the state vector.
STATE_SLICES = {
    "permanent": slice(PERMANENT_START, INDUCED_START),
    "induced": slice(INDUCED_START, EDDY_START),
    "eddy": slice(EDDY_START, N_STATES),
}
#: States per block (3, 9, 9), in the order of :data:`STATE_SLICES`.
BLOCK_SIZES = tuple(s.stop - s.start for s in STATE_SLICES.values())


@dataclass(frozen=True)
class VectorCoefficients:
    """Interference coefficients of one magnetometer installation.

    Attributes
    ----------
    permanent_nt : ndarray, shape (3,)   ``T_p`` [nT]
    induced : ndarray, shape (3, 3)      ``A`` [-]
    eddy_s : ndarray, shape (3, 3)       ``B`` [s]
    """

    permanent_nt: np.ndarray
    induced: np.ndarray
    eddy_s: np.ndarray

    def as_state(self) -> np.ndarray:
        """The 21-vector ``[T_p, A row-major, B row-major]``."""
        return np.concatenate([self.permanent_nt, self.induced.ravel(), self.eddy_s.ravel()])

    @classmethod
    def from_state(cls, x: np.ndarray) -> VectorCoefficients:
        """Inverse of :meth:`as_state`."""
        x = np.asarray(x, dtype=float)
        return cls(
            permanent_nt=x[STATE_SLICES["permanent"]].copy(),
            induced=x[STATE_SLICES["induced"]].reshape(3, 3).copy(),
            eddy_s=x[STATE_SLICES["eddy"]].reshape(3, 3).copy(),
        )

    def to_dict(self) -> dict[str, list]:
        """JSON-friendly form (nested lists)."""
        return {
            "permanent_nt": self.permanent_nt.tolist(),
            "induced": self.induced.tolist(),
            "eddy_s": self.eddy_s.tolist(),
        }


def draw_coefficients(cfg: InterferenceConfig, rng: np.random.Generator) -> VectorCoefficients:
    """Coefficients from the configuration: explicit values where given, else ``N(0, std²)``."""
    perm = rng.normal(0.0, cfg.permanent_std_nt, 3)
    induced = rng.normal(0.0, cfg.induced_std, 9)
    eddy = rng.normal(0.0, cfg.eddy_std_s, 9)
    return VectorCoefficients(
        permanent_nt=np.asarray(cfg.permanent_nt if cfg.permanent_nt is not None else perm, float),
        induced=np.asarray(cfg.induced if cfg.induced is not None else induced, float).reshape(
            3, 3
        ),
        eddy_s=np.asarray(cfg.eddy_s if cfg.eddy_s is not None else eddy, float).reshape(3, 3),
    )


def vector_interference(
    coef: VectorCoefficients, t_b: np.ndarray, tdot_b: np.ndarray
) -> np.ndarray:
    """``ΔT = T_p + A T + B Ṫ`` (paper eq. 9).

    Parameters
    ----------
    coef : VectorCoefficients
    t_b : ndarray, shape (n, 3)      body-frame ambient field [nT]
    tdot_b : ndarray, shape (n, 3)   its time derivative [nT/s]

    Returns
    -------
    ndarray, shape (n, 3) [nT]
    """
    return coef.permanent_nt + t_b @ coef.induced.T + tdot_b @ coef.eddy_s.T


def scalar_interference(
    coef: VectorCoefficients, t_b: np.ndarray, tdot_b: np.ndarray
) -> np.ndarray:
    """Interference seen by a total-field sensor: ``|T + ΔT| - |T|`` [nT], shape (n,).

    Exact, not linearised: the Tolles–Lawson model is the first-order term ``T̂ · ΔT``; the
    remainder is ≈ ``|ΔT_⊥|² / (2 |T|)`` (≈ 0.05 nT for a 70 nT stinger field at 50 000 nT).
    """
    total = t_b + vector_interference(coef, t_b, tdot_b)
    return np.linalg.norm(total, axis=1) - np.linalg.norm(t_b, axis=1)
