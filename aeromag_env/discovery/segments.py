"""Axis-stacked columns that are non-zero on one run of rows per axis, and their products.

A B-spline regressor is non-zero on four knot intervals; on the axis-stacked calibration rows
(all of body axis x, then y, then z) it is one contiguous run of rows per axis, and so is its
whitened form (the Kalman innovations start with the run and fade out after it).
:class:`Segments` holds such columns (rows, p) as those runs: the values of column j on axis i
are ``values[offset[j, i] : offset[j, i] + length[j, i]]``, on rows ``start[j, i] …``. Storage
and every product grow with the runs, not with rows × p: :func:`gram` (``aᵀ b`` of two such
matrices, from the overlaps of their runs), :meth:`Segments.t_dot` (``aᵀ D`` of a dense D),
:meth:`Segments.dot` (``a C``). The kernels are checked against the dense products in
``tests/discovery/test_discover_numerics.py``.
"""

from __future__ import annotations

import numpy as np

from aeromag_env.numba_cache import njit


class Segments:
    """Columns (rows, p) stored as one run of values per column and axis (see the module).

    Parameters
    ----------
    rows : int
        Rows of the matrix (3m: three axes of m rows).
    start, length, offset : numpy.ndarray
        (p, 3) int64: first row (absolute, in axis i's block ``[i m, (i + 1) m)``), number of
        rows and position in ``values`` of each column's run on each axis (length 0: none).
    values : numpy.ndarray
        The runs' values, float64.
    """

    def __init__(
        self,
        rows: int,
        start: np.ndarray,
        length: np.ndarray,
        offset: np.ndarray,
        values: np.ndarray,
    ) -> None:
        self.rows = int(rows)
        self.start = np.ascontiguousarray(start, np.int64)
        self.length = np.ascontiguousarray(length, np.int64)
        self.offset = np.ascontiguousarray(offset, np.int64)
        self.values = np.ascontiguousarray(values, np.float64)

    @property
    def shape(self) -> tuple[int, int]:
        return (self.rows, self.start.shape[0])

    @property
    def nnz(self) -> int:
        """Values stored."""
        return int(self.length.sum())

    def axis(self, i: int) -> Segments:
        """The same columns with only axis ``i``'s runs (the others empty), sharing the values."""
        length = np.zeros_like(self.length)
        length[:, i] = self.length[:, i]
        return Segments(self.rows, self.start, length, self.offset, self.values)

    def columns(self, cols: np.ndarray | slice) -> Segments:
        """The columns ``cols``, sharing the values."""
        return Segments(
            self.rows, self.start[cols], self.length[cols], self.offset[cols], self.values
        )

    def t_dot(self, d: np.ndarray) -> np.ndarray:
        """``selfᵀ d`` (p, k) of a dense ``d`` (rows, k) or (rows,) → (p,)."""
        d_t = np.ascontiguousarray(d.reshape(self.rows, -1).T, np.float64)  # (k, rows)
        out = np.zeros((self.shape[1], d_t.shape[0]))
        _t_dot(self.start, self.length, self.offset, self.values, d_t, out)
        return out if d.ndim == 2 else out[:, 0]

    def dot(self, c: np.ndarray) -> np.ndarray:
        """``self c`` (rows, k) of coefficients ``c`` (p, k) or (p,) → (rows,)."""
        c2 = np.ascontiguousarray(c.reshape(self.shape[1], -1), np.float64)
        out_t = np.zeros((c2.shape[1], self.rows))  # (k, rows): each run added as one stride
        _dot(self.start, self.length, self.offset, self.values, c2, out_t)
        return out_t.T.copy() if c.ndim == 2 else out_t[0]

    def __matmul__(self, c: np.ndarray) -> np.ndarray:
        return self.dot(c)

    def sums(self) -> np.ndarray:
        """Per column and axis, the sum of its values (p, 3)."""
        return _run_sums(self.length, self.offset, self.values, 1)

    def squares(self) -> np.ndarray:
        """Per column and axis, the sum of its squared values (p, 3)."""
        return _run_sums(self.length, self.offset, self.values, 2)

    def toarray(self) -> np.ndarray:
        """The dense matrix (rows, p)."""
        out = np.zeros(self.shape)
        for j in range(self.shape[1]):
            for i in range(3):
                a, n, o = self.start[j, i], self.length[j, i], self.offset[j, i]
                out[a : a + n, j] = self.values[o : o + n]
        return out


def gram(a: Segments, b: Segments) -> np.ndarray:
    """``aᵀ b`` (p_a, p_b) of two :class:`Segments` of the same rows, from their runs' overlaps."""
    out = np.zeros((a.shape[1], b.shape[1]))
    _gram(a.start, a.length, a.offset, a.values, b.start, b.length, b.offset, b.values, out)
    return out


def concat(parts: list[Segments]) -> Segments:
    """Columns side by side (one :class:`Segments`)."""
    if len(parts) == 1:
        return parts[0]
    shift = np.cumsum([0] + [p.values.size for p in parts])[:-1]
    return Segments(
        parts[0].rows,
        np.concatenate([p.start for p in parts]),
        np.concatenate([p.length for p in parts]),
        np.concatenate([p.offset + s for p, s in zip(parts, shift, strict=True)]),
        np.concatenate([p.values for p in parts]),
    )


@njit(cache=True, nogil=True, fastmath={"reassoc"})
def _t_dot(
    start: np.ndarray,
    length: np.ndarray,
    offset: np.ndarray,
    values: np.ndarray,
    d_t: np.ndarray,
    out: np.ndarray,
) -> None:
    """``out[j, c] = Σ_rows a[row, j] d_t[c, row]``: per run, a dot product of contiguous values
    (summed in vector lanes: ``reassoc``, a rounding-level reordering of the sum)."""
    p, k = out.shape
    for j in range(p):
        for i in range(3):
            a, o, n = start[j, i], offset[j, i], length[j, i]
            for c in range(k):
                acc = 0.0
                for r in range(n):
                    acc += values[o + r] * d_t[c, a + r]
                out[j, c] += acc


@njit(cache=True, nogil=True)
def _dot(
    start: np.ndarray,
    length: np.ndarray,
    offset: np.ndarray,
    values: np.ndarray,
    c: np.ndarray,
    out_t: np.ndarray,
) -> None:
    """``out_t[q, row] += a[row, j] c[j, q]``: per run and coefficient, one contiguous ``axpy``."""
    p, k = c.shape
    for j in range(p):
        for i in range(3):
            a, o, n = start[j, i], offset[j, i], length[j, i]
            for q in range(k):
                w = c[j, q]
                if w == 0.0:
                    continue
                for r in range(n):
                    out_t[q, a + r] += w * values[o + r]


@njit(cache=True, nogil=True, fastmath={"reassoc"})
def _gram(
    sa: np.ndarray,
    la: np.ndarray,
    oa: np.ndarray,
    va: np.ndarray,
    sb: np.ndarray,
    lb: np.ndarray,
    ob: np.ndarray,
    vb: np.ndarray,
    out: np.ndarray,
) -> None:
    """``out[j, k] = Σ_rows a[row, j] b[row, k]``: per axis, the dot product over the overlap of
    the two runs (summed in vector lanes, as :func:`_t_dot`)."""
    pa, pb = out.shape
    for j in range(pa):
        for k in range(pb):
            acc = 0.0
            for i in range(3):
                lo = max(sa[j, i], sb[k, i])
                hi = min(sa[j, i] + la[j, i], sb[k, i] + lb[k, i])
                da = oa[j, i] - sa[j, i]
                db = ob[k, i] - sb[k, i]
                for row in range(lo, hi):
                    acc += va[da + row] * vb[db + row]
            out[j, k] = acc


@njit(cache=True, nogil=True)
def _run_sums(length: np.ndarray, offset: np.ndarray, values: np.ndarray, power: int) -> np.ndarray:
    """Per column and axis, the sum of the run's values (``power`` 1) or of their squares (2)."""
    p = length.shape[0]
    out = np.zeros((p, 3))
    for j in range(p):
        for i in range(3):
            acc = 0.0
            o = offset[j, i]
            for r in range(length[j, i]):
                v = values[o + r]
                acc += v if power == 1 else v * v
            out[j, i] = acc
    return out
