"""A candidate group's columns on every sample, dense or compact, and the products discovery takes
of them.

Decides how regressors are held. A group's columns (n, 3, p) [nT per unit coefficient] are a dense
array, except those of ``external_field_variation``: one navigation-frame cubic B-spline per
:data:`~aeromag_env.simulation.effects_base.EXTERNAL_KNOT_SPACING_S` and NED axis, so their count
grows with the flight, while each is non-zero on four knot intervals only. Held dense, they made
the workflow's memory grow with the square of the flight's length and its time with the cube
(a 4-hour flight needed 9 GB). :class:`SplineColumns` keeps them as the sparse B-spline basis
and the attitude: their values are the dense columns' bit for bit (:meth:`SplineColumns.dense`),
their axis-stacked rows a sparse array (:meth:`SplineColumns.stacked`).

:func:`width`, :func:`predict` and :func:`stacked_rows` read either form; :class:`Design` is a
row of column blocks (dense or sparse) for least squares; :func:`spline_group` builds the
external field's candidate group in the compact form.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any, cast

import numpy as np

from aeromag_env.discovery.segments import Segments, gram
from aeromag_env.simulation.effects import EFFECTS, EffectContext, Group
from aeromag_env.simulation.effects_base import NED, spline_knots


class SplineColumns:
    """The columns ``N_m(t) C_bnᵀ e_j`` (n, 3, 3M) of M B-splines ``N_m`` and the NED axes
    ``e_j`` (column ``3 m + j``), held as the sparse basis and the attitude.

    Parameters
    ----------
    basis : scipy.sparse array
        The B-spline basis on every sample (n, M), at most four non-zeros a row.
    c_nb : numpy.ndarray
        The attitude DCMs (n, 3, 3), body → NED.
    """

    ndim = 3

    def __init__(self, basis: Any, c_nb: np.ndarray) -> None:
        from scipy.sparse import csr_array

        self.basis = csr_array(basis)
        self.c_nb = c_nb

    @property
    def shape(self) -> tuple[int, int, int]:
        """(n, 3, 3M), as the dense columns."""
        return (self.c_nb.shape[0], 3, 3 * self.basis.shape[1])

    def dense(self) -> np.ndarray:
        """The dense columns (n, 3, 3M): each value the one product ``N_m(t) · C_nb[j, i]``, as
        :func:`~aeromag_env.simulation.effects_base.nav_columns` forms it."""
        n, _, p = self.shape
        weights = self.basis.toarray()
        c_bn = np.transpose(self.c_nb, (0, 2, 1))
        return (weights[:, None, :, None] * c_bn[:, :, None, :]).reshape(n, 3, p)

    def __array__(self, dtype: Any = None, copy: Any = None) -> np.ndarray:
        """The dense columns, for code that reads a group as an array (correct, not compact)."""
        return self.dense() if dtype is None else self.dense().astype(dtype)

    def predict(self, beta: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """``Σ_p columns[:, :, p] beta[p]`` (k, 3) on ``rows`` (all samples when None): the
        NED field ``N β`` (β as M × 3) rotated into body axes."""
        basis = self.basis if rows is None else self.basis[rows]
        c_nb = self.c_nb if rows is None else self.c_nb[rows]
        field_ned = basis @ np.asarray(beta, float).reshape(-1, 3)
        return np.einsum("kji,kj->ki", c_nb, field_ned)

    def stacked(self, rows: np.ndarray) -> Segments:
        """The columns on ``rows`` (m,), sorted in time, axis-stacked (all of body axis x, then
        y, then z): each column one run of rows per axis (:class:`Segments`, from its B-spline's
        first to last non-zero row), holding the dense columns' values."""
        from scipy.sparse import csc_array

        m = rows.size
        part = csc_array(self.basis[rows])
        part.sort_indices()
        n_basis = part.shape[1]
        start = np.zeros((3 * n_basis, 3), np.int64)
        length = np.zeros((3 * n_basis, 3), np.int64)
        chunks = []
        for b in range(n_basis):
            nz = part.indices[part.indptr[b] : part.indptr[b + 1]]
            if nz.size == 0:
                continue
            run = slice(int(nz[0]), int(nz[-1]) + 1)
            w = np.zeros(run.stop - run.start)
            w[nz - run.start] = part.data[part.indptr[b] : part.indptr[b + 1]]
            c_nb = self.c_nb[rows[run]]
            for j in range(3):
                start[3 * b + j] = np.arange(3) * m + run.start
                length[3 * b + j] = run.stop - run.start
                chunks += [w * c_nb[:, j, i] for i in range(3)]
        offset = (np.cumsum(length.ravel()) - length.ravel()).reshape(length.shape)
        values = np.concatenate(chunks) if chunks else np.zeros(0)
        return Segments(3 * m, start, length, offset, values)


class AxisColumns:
    """Columns (n, 3, p) each non-zero on one body axis only, held as their values (n, p) and
    axes (p,): the eddy, second-order, drift and current groups (``B_e`` rows, quadratic terms,
    ``w(t) e_i``), a third of the dense array's size.

    Parameters
    ----------
    values : numpy.ndarray
        Each column's values on its axis (n, p).
    axis : numpy.ndarray
        Each column's body axis (p,), 0, 1 or 2.
    """

    ndim = 3

    def __init__(self, values: np.ndarray, axis: np.ndarray) -> None:
        self.values = np.ascontiguousarray(values, dtype=float)
        self.axis = np.asarray(axis, dtype=np.int64)

    @property
    def shape(self) -> tuple[int, int, int]:
        """(n, 3, p), as the dense columns."""
        return (self.values.shape[0], 3, self.values.shape[1])

    def rows(self, rows: np.ndarray | slice = slice(None)) -> np.ndarray:
        """The dense columns (k, 3, p) on ``rows``: the values on their axes, zeros elsewhere."""
        values = self.values[rows]
        out = np.zeros((values.shape[0], 3, values.shape[1]))
        out[:, self.axis, np.arange(values.shape[1])] = values
        return out

    def dense(self) -> np.ndarray:
        """The dense columns (n, 3, p)."""
        return self.rows()

    def __array__(self, dtype: Any = None, copy: Any = None) -> np.ndarray:
        """The dense columns, for code that reads a group as an array (correct, not compact)."""
        return self.dense() if dtype is None else self.dense().astype(dtype)

    def predict(self, beta: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """``Σ_p columns[:, :, p] beta[p]`` (k, 3) on ``rows`` (all samples when None)."""
        values = self.values if rows is None else self.values[rows]
        out = np.zeros((values.shape[0], 3))
        for i in range(3):
            on = self.axis == i
            if on.any():
                out[:, i] = values[:, on] @ beta[on]
        return out


def one_axis(columns: np.ndarray) -> AxisColumns | None:
    """``columns`` (n, 3, p) as :class:`AxisColumns` when each column is non-zero on at most one
    body axis, else None."""
    nonzero = np.any(columns != 0, axis=0)  # (3, p)
    if columns.shape[2] == 0 or (nonzero.sum(axis=0) > 1).any():
        return None
    axis = np.argmax(nonzero, axis=0)
    return AxisColumns(columns[:, axis, np.arange(columns.shape[2])], axis)


def compact_group(group: Group) -> Group:
    """``group`` with its columns held as :class:`AxisColumns` where they are one-axis (and so
    every group it rebuilds), else ``group`` as it is."""
    if not isinstance(group.columns, np.ndarray):
        return group
    cols = one_axis(group.columns)
    if cols is None:
        return group
    rebuild = group.rebuild
    wrapped = None if rebuild is None else (lambda v: compact_group(rebuild(v)))
    return dataclasses.replace(group, columns=cast(np.ndarray, cols), rebuild=wrapped)


def is_sparse(columns: Any) -> bool:
    """Whether a group's columns take the sparse path (:class:`SplineColumns`: whitened as runs,
    projected through Gram matrices)."""
    return isinstance(columns, SplineColumns)


def is_compact(columns: Any) -> bool:
    """Whether a group's columns are held compact (:class:`SplineColumns`, :class:`AxisColumns`),
    not as a dense array."""
    return isinstance(columns, SplineColumns | AxisColumns)


def width(columns: Any) -> int:
    """The number of columns p of a group's columns (n, 3, p), dense or compact."""
    return int(columns.shape[2])


def predict(columns: Any, beta: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
    """The field ``Σ_p columns[:, :, p] beta[p]`` (k, 3) [nT] of a group (dense or compact) on
    ``rows`` (a mask or indices; all samples when None)."""
    if is_compact(columns):
        idx = None if rows is None else np.flatnonzero(rows) if rows.dtype == bool else rows
        return cast(SplineColumns, columns).predict(beta, idx)
    x = columns if rows is None else columns[rows]
    return np.einsum("kip,p->ki", x, beta)


def rows_of(columns: Any, rows: np.ndarray) -> np.ndarray:
    """A group's columns on ``rows`` (k, 3, p), dense, whatever their form."""
    if isinstance(columns, AxisColumns):
        return columns.rows(rows)
    if isinstance(columns, SplineColumns):
        return columns.dense()[rows]
    return np.asarray(columns[rows])


def predict_all(
    columns: Sequence[Any], beta: np.ndarray, rows: np.ndarray | None = None
) -> np.ndarray:
    """The summed field (k, 3) [nT] of groups whose coefficients ``beta`` are concatenated in
    their order (:func:`predict` of each)."""
    parts = np.split(beta, np.cumsum([width(c) for c in columns])[:-1])
    n = (
        columns[0].shape[0]
        if rows is None
        else np.count_nonzero(rows)
        if rows.dtype == bool
        else rows.size
    )
    out = np.zeros((n, 3))
    for cols, b in zip(columns, parts, strict=True):
        out += predict(cols, b, rows)
    return out


def stacked_rows(columns: Any, rows: np.ndarray) -> Any:
    """A group's columns on ``rows`` (m,), axis-stacked (3m, p): dense, or :class:`Segments` for
    compact columns."""
    if is_sparse(columns):
        return cast(SplineColumns, columns).stacked(rows)
    x = rows_of(columns, rows)
    return np.ascontiguousarray(x.transpose(1, 0, 2)).reshape(-1, x.shape[2])


def spline_group(ctx: EffectContext) -> Group:
    """``external_field_variation``'s candidate group (the flight's navigation-frame B-splines,
    :meth:`~aeromag_env.simulation.effects_field.ExternalFieldVariation.groups`) with
    :class:`SplineColumns`: the same columns, labels and parameters, held compact."""
    from scipy.interpolate import BSpline

    effect = EFFECTS["external_field_variation"]
    knots = spline_knots(ctx.span())
    basis = BSpline.design_matrix(np.clip(ctx.tt, knots[0], knots[-1]), knots, 3)
    cols = SplineColumns(basis, ctx.c_nb)
    labels = [f"N{m}(t)·C_bn e_{a}" for m in range(basis.shape[1]) for a in NED]
    to_params = lambda b: {"spline_ned_nt": b.tolist(), "spline_knots_s": knots.tolist()}  # noqa: E731
    return Group(effect.name, None, cast(np.ndarray, cols), labels, to_params)


def cross(a: Any, b: Any) -> np.ndarray:
    """``aᵀ b`` (p, q), dense, for ``a`` (rows, p) and ``b`` (rows, q) each dense or
    :class:`Segments`."""
    if isinstance(a, Segments) and isinstance(b, Segments):
        return gram(a, b)
    if isinstance(a, Segments):
        return a.t_dot(b)
    if isinstance(b, Segments):
        return b.t_dot(a).T
    return np.asarray(a.T @ b)


class Design:
    """Columns (rows, p) held as a row of blocks, dense arrays or :class:`Segments`, for least
    squares: the products it takes without forming the whole matrix.

    Parameters
    ----------
    blocks : sequence
        Column blocks (rows, p_k), each a dense array or :class:`Segments`.
    """

    def __init__(self, blocks: Sequence[Any]) -> None:
        self.blocks = list(blocks)
        self.edges = np.cumsum([0] + [b.shape[1] for b in self.blocks])

    @property
    def shape(self) -> tuple[int, int]:
        return (self.blocks[0].shape[0], int(self.edges[-1]))

    def gram(self) -> np.ndarray:
        """``xᵀ x`` (p, p)."""
        p = self.shape[1]
        out = np.empty((p, p))
        e = self.edges
        for i, a in enumerate(self.blocks):
            for j in range(i, len(self.blocks)):
                block = cross(a, self.blocks[j])
                out[e[i] : e[i + 1], e[j] : e[j + 1]] = block
                out[e[j] : e[j + 1], e[i] : e[i + 1]] = block.T
        return out

    def t_dot(self, y: np.ndarray) -> np.ndarray:
        """``xᵀ y`` (p,) of a vector y (rows,)."""
        return np.concatenate([cross(b, y) for b in self.blocks])

    def dot(self, beta: np.ndarray) -> np.ndarray:
        """``x β`` (rows,)."""
        out = np.zeros(self.shape[0])
        for b, part in zip(self.blocks, np.split(beta, self.edges[1:-1]), strict=True):
            out += b @ part
        return out

    def dense(self) -> np.ndarray:
        """The whole matrix (rows, p), dense."""
        return np.concatenate(
            [b.toarray() if isinstance(b, Segments) else b for b in self.blocks], axis=1
        )


def design(blocks: Sequence[Any]) -> np.ndarray | Design:
    """Blocks as one dense array when all are dense (concatenated), else a :class:`Design`."""
    if any(isinstance(b, Segments) for b in blocks):
        return Design(blocks)
    return blocks[0] if len(blocks) == 1 else np.concatenate(blocks, axis=1)
