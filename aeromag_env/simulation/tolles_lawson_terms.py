"""The Tolles–Lawson (TL) model of a scalar magnetometer's interference, MagNav.jl conventions.

Design matrix columns, from the vector field ``B`` (n, 3) [nT] measured by a fluxgate and its
direction cosines ``B̂ = B / |B|``:

* permanent (3): ``B̂_i``
* induced (6): ``B̂_i B_j / Bt`` for ij = xx, xy, xz, yy, yz, zz
* eddy (9): ``B̂_i ΔB_j / Bt`` for all (i, j), row-major, with ``ΔB_j`` the per-sample central
  difference (``(B[k+1] - B[k-1]) / 2``; **not** divided by the sample interval, so eddy
  coefficients depend on the sample rate, as in MagNav.jl)

with ``Bt = 50 000 nT``. The scalar interference is ``design @ coefficients`` [nT].
Shared by the simulator (the scalar channel's true coefficients) and the compensator
(:class:`aeromag_env.compensation.tolles_lawson.TollesLawson` fits them).
"""

from __future__ import annotations

import numpy as np

from aeromag_env.simulation.interference import VectorCoefficients
from aeromag_env.units import BT_SCALE_NT

INDUCED_PAIRS = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))
TERMS = {"permanent": 3, "induced": 6, "eddy": 9}
N_TERMS = sum(TERMS.values())


def design_matrix(b: np.ndarray, bt_scale_nt: float = BT_SCALE_NT) -> np.ndarray:
    """The 18-column TL design matrix (permanent, induced, eddy).

    Parameters
    ----------
    b : ndarray, shape (n, 3)
        Vector field in body axes [nT] (a fluxgate, or the true field).
    bt_scale_nt : float
        Scale of the induced and eddy terms [nT].

    Returns
    -------
    ndarray, shape (n, 18)
    """
    b = np.asarray(b, dtype=float)
    mag = np.linalg.norm(b, axis=1, keepdims=True)
    cos = b / mag
    induced = np.column_stack([cos[:, i] * b[:, j] for i, j in INDUCED_PAIRS]) / bt_scale_nt
    db = np.gradient(b, axis=0)  # per-sample central difference
    eddy = (cos[:, :, None] * db[:, None, :]).reshape(-1, 9) / bt_scale_nt
    return np.hstack([cos, induced, eddy])


def coefficients_from_vector(
    coef: VectorCoefficients, dt_s: float, bt_scale_nt: float = BT_SCALE_NT
) -> np.ndarray:
    """TL coefficients (18) equivalent to a vector installation ``T_p + A T + B Ṫ``.

    The TL model is the projection ``T̂ · ΔT``; matching it term by term gives
    permanent ``T_p``; induced ``Bt A_ii`` on the diagonal and ``Bt (A_ij + A_ji)`` off it (only
    the symmetric part of ``A`` is visible to a total-field sensor); eddy ``Bt B_ij / dt``
    (the design uses per-sample differences ``ΔB = Ḃ dt``).
    """
    a = coef.induced
    induced = [a[i, i] if i == j else a[i, j] + a[j, i] for i, j in INDUCED_PAIRS]
    return np.concatenate(
        [
            coef.permanent_nt,
            bt_scale_nt * np.asarray(induced),
            bt_scale_nt * coef.eddy_s.ravel() / dt_s,
        ]
    )
