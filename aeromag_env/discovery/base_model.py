"""The base model of paper eq. 5: its 21 regressors, their span, and its coefficients.

Decides what the base model can already explain: the 21 regressors ``[1, T, Ṫ]`` per axis
(:func:`base_columns`), the projector off their span on the calibration rows (:class:`BaseSpan`,
whose :meth:`~BaseSpan.identifiable_fraction` says how much of a candidate group the base model
would absorb), and how the fitted coefficients read as ``T_p``, ``A`` and ``B``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from aeromag_env.discovery.regressors import is_sparse, rows_of, stacked_rows
from aeromag_env.simulation.interference import STATE_SLICES


def base_columns(t_b: np.ndarray, tdot_b: np.ndarray) -> np.ndarray:
    """The 21 base regressors as vector columns (n, 3, 21), axis-major ``[1, T, Ṫ]`` per axis.

    Parameters
    ----------
    t_b : numpy.ndarray
        Model Earth field in body axes (n, 3) [nT].
    tdot_b : numpy.ndarray
        Its time derivative (n, 3) [nT/s].

    Returns
    -------
    numpy.ndarray
        Columns (n, 3, 21): axis i has ``[1, T, Ṫ]`` in columns ``7 i … 7 i + 6``, zeros elsewhere.
    """
    n = t_b.shape[0]
    cols = np.zeros((n, 3, 3, 7))
    rows = np.column_stack([np.ones(n), t_b, tdot_b])
    for i in range(3):
        cols[:, i, i, :] = rows
    return cols.reshape(n, 3, 21)


def base_state(beta: np.ndarray) -> np.ndarray:
    """Axis-major base coefficients (21) → state ``[T_p, A row-major, B row-major]``.

    Parameters
    ----------
    beta : numpy.ndarray
        Coefficients whose first 21 are the base model's, axis-major as in :func:`base_columns`.

    Returns
    -------
    numpy.ndarray
        The state (21,): ``T_p`` (3), ``A`` (9, row-major), ``B`` (9, row-major).
    """
    b = np.asarray(beta[:21]).reshape(3, 7)
    return np.r_[b[:, 0], b[:, 1:4].ravel(), b[:, 4:7].ravel()]


def stack(x: np.ndarray) -> np.ndarray:
    """Vector columns (m, 3, p) → axis-stacked rows (3m, p).

    Parameters
    ----------
    x : numpy.ndarray
        Vector columns (m, 3, p).

    Returns
    -------
    numpy.ndarray
        Rows (3m, p): all of axis 0, then axis 1, then axis 2.
    """
    return x.transpose(1, 0, 2).reshape(-1, x.shape[2])


def orthonormal(x: np.ndarray, tol: float = 1e-7) -> np.ndarray:
    """Orthonormal basis of the column space of ``x`` (rank by singular values > tol·max).

    Parameters
    ----------
    x : numpy.ndarray
        Columns (rows, p); each is scaled to unit norm first.
    tol : float
        Relative singular-value threshold of the rank.

    Returns
    -------
    numpy.ndarray
        Orthonormal columns (rows, rank).

    Notes
    -----
    Callers project with the basis, so any basis of the span serves. A well-conditioned ``x``
    (condition number of the unit columns below :data:`GRAM_BASIS_MAX_COND`, so of full rank at
    any ``tol`` ≤ its inverse) gets its basis from the p × p Gram matrix, ``x V Λ^{-1/2}``, then
    one Cholesky re-orthogonalisation (the first pass is orthogonal to ``eps · cond²``, the
    second to rounding): two tall BLAS-3 products instead of a tall SVD, 5× faster on
    72 000 × 120. Otherwise the SVD decides the rank.
    """
    if x.shape[1] == 0:
        return x
    from scipy.linalg import cholesky, solve_triangular

    gram = x.T @ x
    norm = np.sqrt(np.diag(gram))
    if norm.min() > 0 and tol <= 1 / GRAM_BASIS_MAX_COND:
        lam, v = np.linalg.eigh(gram / np.outer(norm, norm))
        if lam[0] > lam[-1] / GRAM_BASIS_MAX_COND**2:
            u = x @ (v / norm[:, None] / np.sqrt(lam))
            r = cholesky(u.T @ u, lower=False, check_finite=False)
            return np.asarray(solve_triangular(r, u.T, trans="T", check_finite=False).T)
    u, s, _ = np.linalg.svd(x / np.maximum(norm, 1e-300), full_matrices=False)
    return u[:, s > tol * s[0]] if s.size and s[0] > 0 else u[:, :0]


#: :func:`orthonormal` takes its basis from the Gram matrix below this condition number of the
#: unit-norm columns (the Gram matrix's is its square, 1e12: its eigenvectors stay accurate).
GRAM_BASIS_MAX_COND = 1e6


class BaseSpan:
    """Projector off the un-whitened base regressors on the calibration rows.

    Parameters
    ----------
    base : numpy.ndarray
        The base regressors (n, 3, 21) of :func:`base_columns`.
    rows : numpy.ndarray
        Boolean mask (n,) of the rows the span is taken over.
    """

    def __init__(self, base: np.ndarray, rows: np.ndarray) -> None:
        self.rows = rows
        self.q = orthonormal(stack(base[rows]), tol=1e-10)

    def perp(self, x: np.ndarray) -> np.ndarray:
        """Axis-stacked part (3m, p) of columns ``x`` (n, 3, p) outside the span, on the rows."""
        xs = stack(x[self.rows])
        return xs - self.q @ (self.q.T @ xs)

    def identifiable_fraction(self, group: Any) -> float:
        """Share of the group's centred variance outside the base span, mean over its columns
        (0 when the group does not vary).

        The base span holds a constant per axis (the permanent field), so the centred columns
        have the same part outside it as the raw ones; working on them keeps the subtraction
        ``‖x‖² − ‖Qᵀx‖²`` free of a large mean (a bus voltage at 28 ± 0.5 V) and needs no
        axis-stacked copy: ``Qᵀx`` is one product per axis on the strided view.
        """
        if is_sparse(group):
            return self._compact_fraction(group)
        g = rows_of(group, self.rows)
        scale = math.sqrt(float(np.einsum("kip,kip->p", g, g).max(initial=0.0)))
        g -= g.mean(axis=0, keepdims=True)
        centred = np.einsum("kip,kip->p", g, g)
        ok = np.sqrt(centred) > 1e-9 * max(scale, 1e-300)
        if not ok.any():
            return 0.0
        m = g.shape[0]
        q = self.q.reshape(3, m, -1)
        inside = sum(np.einsum("rp,rp->p", *(2 * [q[i].T @ g[:, i, ok]])) for i in range(3))
        outside = np.maximum(centred[ok] - inside, 0.0)
        return float(np.mean(outside / centred[ok]))

    def _compact_fraction(self, group: Any) -> float:
        """:meth:`identifiable_fraction` of compact columns, from their sparse axis-stacked rows:
        the centred sums as ``Σ x² − m μ²`` and ``qᵢᵀ(xᵢ − μᵢ) = qᵢᵀ xᵢ − (qᵢᵀ 1) μᵢ``, the
        columns never made dense."""
        rows = np.flatnonzero(self.rows)
        x = stacked_rows(group, rows)
        m = rows.size
        total = np.zeros(x.shape[1])
        centred = np.zeros(x.shape[1])
        inside = np.zeros(x.shape[1])
        squares, sums = x.squares(), x.sums()  # (p, 3)
        q_full = self.q.reshape(3, m, -1)
        for i in range(3):
            mean = sums[:, i] / m
            total += squares[:, i]
            centred += squares[:, i] - m * mean**2
            # qᵢᵀ xᵢ: axis i's runs against the basis's rows of axis i
            proj = x.axis(i).t_dot(self.q).T - np.outer(q_full[i].sum(axis=0), mean)
            inside += np.einsum("rp,rp->p", proj, proj)
        scale = math.sqrt(float(total.max(initial=0.0)))
        ok = np.sqrt(np.maximum(centred, 0.0)) > 1e-9 * max(scale, 1e-300)
        if not ok.any():
            return 0.0
        return float(np.mean(np.maximum(centred[ok] - inside[ok], 0.0) / centred[ok]))


def base_dict(state: np.ndarray) -> dict[str, list[float]]:
    """The base state of :func:`base_state` as JSON-ready lists, by term.

    Parameters
    ----------
    state : numpy.ndarray
        ``[T_p, A row-major, B row-major]`` (21,).

    Returns
    -------
    dict
        ``permanent_nt`` (3), ``induced`` (9) and ``eddy_s`` (9).
    """
    return {
        "permanent_nt": state[STATE_SLICES["permanent"]].tolist(),
        "induced": state[STATE_SLICES["induced"]].tolist(),
        "eddy_s": state[STATE_SLICES["eddy"]].tolist(),
    }
