"""The whitened (GLS) least-squares problem on the calibration rows: fits and partial tests.

Decides the numbers every verdict rests on: the noise model's Kalman innovations whiten the
residual and every regressor (generalised least squares), the base regressors are projected
out once (Frisch–Waugh–Lovell), and :meth:`WhitenedProblem.test` gives the residual sums for
adding one candidate group to the chosen ones; :meth:`WhitenedProblem.fit` gives the GLS
coefficients and their covariance, :meth:`WhitenedProblem.absorbable_share` how much of a slow
FOGM a group could absorb.

Memory: the problem reads the groups' own columns (every sample) through the calibration row
indices and holds one whitened, base-projected copy of the dense ones; whitened columns are kept
only for the groups a fit asks for. Compact groups (:class:`~aeromag_env.discovery.regressors.
SplineColumns`, whose number of columns grows with the flight) stay sparse whitened, and their
projections are taken through their small Gram matrices (:class:`SparseSpan`), so memory and
time grow linearly with the flight.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from aeromag_env.discovery.base_model import orthonormal
from aeromag_env.discovery.noise_model import (
    NoiseModel,
    fogm_quadratic,
    whiten,
    whiten_rows,
    whiten_segments,
)
from aeromag_env.discovery.preparation import PreparedFlight
from aeromag_env.discovery.regressors import (
    AxisColumns,
    Design,
    cross,
    design,
    is_compact,
    is_sparse,
    predict_all,
    stacked_rows,
    width,
)
from aeromag_env.discovery.segments import concat
from aeromag_env.threads import map_threads

#: Columns projected off the base at a time in :meth:`WhitenedProblem.set_noise` (in place: a
#: temporary of this width, not of the whole array).
PROJECTION_CHUNK = 32
#: Columns of an implicit basis formed at a time (:meth:`ChunkedBasis.chunks`).
BASIS_CHUNK = 32
#: :class:`SparseSpan` keeps the directions whose eigenvalue of the unit-column Gram matrix is
#: above this share of the largest (singular values above 1e-6 of the largest: the rank cut of
#: :func:`~aeromag_env.discovery.base_model.orthonormal`'s Gram path, whose condition limit is
#: 1e6).
SPARSE_RANK_TOL = 1e-12


class SparseSpan:
    """The span of sparse columns ``x`` (rows, p) off an orthonormal dense basis ``q``
    (rows, k), ``(I − q qᵀ) x``, held through its Gram matrix.

    ``t`` (p, r) maps it to an orthonormal basis, ``u = (I − q qᵀ) x t``, never formed.

    Parameters
    ----------
    x : Segments
        The columns (rows, p).
    q : numpy.ndarray
        Orthonormal columns (rows, k), possibly none.
    """

    def __init__(self, x: Any, q: np.ndarray) -> None:
        self.x, self.q = x, q
        self.c = cross(q, x)  # (k, p): qᵀ x
        gram = cross(x, x) - self.c.T @ self.c  # ((I − q qᵀ) x)ᵀ ((I − q qᵀ) x)
        d = np.sqrt(np.maximum(np.diag(gram), 0.0))
        d = np.where(d > 0, d, 1.0)
        lam, v = np.linalg.eigh(gram / np.outer(d, d))
        keep = lam > SPARSE_RANK_TOL * max(float(lam[-1]) if lam.size else 0.0, 1e-300)
        self.t = (v[:, keep] / np.sqrt(lam[keep])) / d[:, None]
        self.rank = int(keep.sum())

    def t_dot(self, z: np.ndarray) -> np.ndarray:
        """``uᵀ z`` (r, c) of dense ``z`` (rows, c)."""
        return self.t.T @ (self.x.t_dot(z) - self.c.T @ (self.q.T @ z))

    def dot(self, coef: np.ndarray) -> np.ndarray:
        """``u coef`` (rows, c) of coefficients (r, c)."""
        a = self.t @ coef
        return self.x.dot(a) - self.q @ (self.c @ a)

    def remove(self, z: np.ndarray, passes: int = 2) -> np.ndarray:
        """``z`` (rows, ...) with its part in the span removed (a new array). ``u`` from the Gram
        matrix is orthonormal only to ``eps · cond²``; a second pass takes what the first left
        (as :func:`~aeromag_env.discovery.base_model.orthonormal` re-orthogonalises its basis)."""
        for _ in range(passes):
            z = z - self.dot(self.t_dot(z))
        return z


@dataclass
class Span:
    """The model ``chosen`` (base first) under one noise model: the orthonormal basis ``q`` of its
    dense groups' columns off the base, its sparse groups' span off both (``sparse``, or None),
    the whitened residual ``r`` off all of it and the rank besides the base."""

    q: np.ndarray
    sparse: SparseSpan | None
    r: np.ndarray
    rank: int

    def remove(self, z: np.ndarray, passes: int = 2) -> np.ndarray:
        """``z`` (rows, c), already off the base, off the span too (``passes``: of the sparse
        part, :meth:`SparseSpan.remove`)."""
        if self.q.shape[1]:
            z = z - self.q @ (self.q.T @ z)
        return z if self.sparse is None else self.sparse.remove(z, passes)


class ChunkedBasis:
    """An orthonormal basis ``(x − q c) t`` (rows, r) of sparse ``x`` off dense ``q``, formed a
    few columns at a time (:meth:`chunks`): for the compact groups, whose basis held whole
    would grow with the square of the flight."""

    def __init__(self, x: Any, q: np.ndarray, c: np.ndarray, t: np.ndarray) -> None:
        self.x, self.q, self.c, self.t = x, q, c, t

    def chunks(self, size: int = BASIS_CHUNK) -> Iterator[np.ndarray]:
        for a in range(0, self.t.shape[1], size):
            t = self.t[:, a : a + size]
            yield self.x.dot(t) - self.q @ (self.c @ t)


class WhitenedProblem:
    """The whitened, axis-stacked least-squares problem on the calibration rows.

    After :meth:`set_noise`, the base regressors are projected out of the whitened data and of
    every candidate once (Frisch–Waugh–Lovell); tests then work on those small residual problems.

    Parameters
    ----------
    data : PreparedFlight
        The prepared flight; its calibration rows are the problem's rows.
    columns : list
        Regressor groups (n, 3, p) on all samples, dense or compact
        (:mod:`~aeromag_env.discovery.regressors`); index 0 is the base model, the others the
        candidate groups (index ``j`` is candidate group ``j − 1``). They are read, not copied.
    """

    def __init__(self, data: PreparedFlight, columns: list[Any]) -> None:
        self.data = data
        self.idx = np.flatnonzero(data.calibration)
        self.gap = np.r_[np.inf, np.diff(data.ctx.tt[self.idx])]
        self.y = data.y[self.idx]
        self._y_axes = np.ascontiguousarray(self.y.T[:, :, None])  # (3, m, 1)
        self.groups = [_stored(c) for c in columns]
        self.noise: NoiseModel | None = None
        self.yw = np.empty(0)
        self.r0 = np.empty(0)
        self.k0 = 0
        self.perp: list[np.ndarray | None] = []  # dense groups: whitened, off the base
        self.scale: list[float] = []  # per group, its whitened columns' largest norm
        self._q0 = np.empty((0, 0))
        self._white: dict[int, Any] = {}  # whitened columns under self.noise, asked for
        self._raw: dict[int, Any] = {}  # axis-stacked calibration rows of compact groups
        self._buffer = np.empty((0, 0))
        self._spans: dict[tuple[int, ...], Span] = {}
        self._raw_spans: dict[tuple[int, ...], tuple[np.ndarray, SparseSpan | None]] = {}
        self._bases: dict[tuple[int, ...], ChunkedBasis] = {}

    @property
    def m(self) -> int:
        """Calibration rows per axis."""
        return int(self.idx.size)

    def __len__(self) -> int:
        """Groups in the problem, the base included."""
        return len(self.groups)

    def width(self, j: int) -> int:
        """Columns of group ``j``."""
        return width(self.groups[j])

    def set_noise(self, noise: NoiseModel) -> None:
        """Whiten the data and every group under ``noise`` and project the base out of them."""
        self.noise = noise
        self._white, self._spans = {}, {}
        self.yw = self._whiten_dense(self._y_axes, noise)[:, 0]
        self._white[0] = self._whitened(0, noise)
        self._q0 = orthonormal(self._white[0])
        self.k0 = self._q0.shape[1]
        self.r0 = self._off_base(self.yw)
        self.perp = [None] * len(self.groups)
        self.scale = [0.0] * len(self.groups)
        self.scale[0] = _largest_norm(self._white[0])
        dense = [j for j in range(1, len(self.groups)) if not is_sparse(self.groups[j])]
        edges = np.cumsum([0] + [self.width(j) for j in dense])
        if self._buffer.shape != (3 * self.m, edges[-1]):
            # reused: a fresh 100-MB array costs more in page faults than its arithmetic
            self._buffer = np.empty((3 * self.m, edges[-1]))
        buf = self._buffer
        blocks = {j: buf[:, edges[k] : edges[k + 1]] for k, j in enumerate(dense)}
        self._whiten_into([(self.groups[j], blocks[j]) for j in dense], noise)
        for j in dense:
            self.scale[j] = _largest_norm(blocks[j])
        for a in range(0, edges[-1], PROJECTION_CHUNK):  # off the base, in place
            part = buf[:, a : min(a + PROJECTION_CHUNK, edges[-1])]
            part -= self._q0 @ (self._q0.T @ part)
        for j in dense:
            self.perp[j] = blocks[j]
        for j in range(len(self.groups)):
            if is_sparse(self.groups[j]):
                self._install_compact(j)

    def _install_compact(self, j: int) -> None:
        """Whiten compact group ``j`` under the current noise (its perp is implicit)."""
        assert self.noise is not None
        w = whiten_segments(self._raw_rows(j), self.gap, self.noise)
        self._white[j] = w
        self.scale[j] = float(np.sqrt(np.max(w.squares().sum(axis=1), initial=0.0)))

    def _install(self, j: int) -> None:
        """Whiten group ``j`` under the current noise and project the base out of it."""
        self.perp[j] = None
        if is_sparse(self.groups[j]):
            self._install_compact(j)
            return
        w = self.white(j)
        self.perp[j] = self._off_base(w)
        self.scale[j] = _largest_norm(w)

    def add(self, columns: Any) -> int:
        """Append a candidate (n, 3, p) built after :meth:`set_noise`; returns its index."""
        self.groups.append(_stored(columns))
        self.perp.append(None)
        self.scale.append(0.0)
        new = len(self.groups) - 1
        self._install(new)
        # an index a test_columns used and freed: forget its caches
        self._spans = {k: v for k, v in self._spans.items() if new not in k}
        self._raw_spans = {k: v for k, v in self._raw_spans.items() if new not in k}
        self._bases = {k: v for k, v in self._bases.items() if new not in k}
        return new

    def remove_last(self) -> None:
        """Drop the group :meth:`add` appended last."""
        last = len(self.groups) - 1
        del self.groups[last], self.perp[last], self.scale[last]
        self._white.pop(last, None)
        self._raw.pop(last, None)

    def replace(self, index: int, columns: Any) -> None:
        """Rebuild candidate ``index`` from new columns (n, 3, p), under the current noise."""
        self.groups[index] = _stored(columns)
        self._white.pop(index, None)
        self._raw.pop(index, None)
        self._install(index)
        self._spans, self._raw_spans, self._bases = {}, {}, {}

    def _off_base(self, x: np.ndarray) -> np.ndarray:
        out = np.matmul(self._q0, self._q0.T @ x)
        return np.subtract(x, out, out=out)

    def white(self, j: int) -> Any:
        """Whitened, axis-stacked columns of group ``j`` (3m, p) under the current noise model
        (dense, or sparse for a compact group); kept while the noise model stands."""
        if j not in self._white:
            assert self.noise is not None
            self._white[j] = self._whitened(j, self.noise)
        return self._white[j]

    def _whitened(self, j: int, noise: NoiseModel) -> Any:
        """Group ``j`` whitened under ``noise`` (a new array)."""
        if is_sparse(self.groups[j]):
            return whiten_segments(self._raw_rows(j), self.gap, noise)
        out = np.empty((3 * self.m, self.width(j)))
        self._whiten_into([(self.groups[j], out)], noise)
        return out

    def _whiten_into(self, pairs: list[tuple[Any, np.ndarray]], noise: NoiseModel) -> None:
        """Whiten each dense group's calibration rows (read from its (n, 3, p) columns, or from
        :class:`~aeromag_env.discovery.regressors.AxisColumns`' values on their axes, zeros
        elsewhere) into its axis-stacked block (3m, p); the three axes on their own threads."""
        m = self.m

        def axis(i: int) -> None:
            args = (noise.white_std_nt[i], noise.fogm_std_nt[i], noise.fogm_tau_s[i])
            for cols, out in pairs:
                rows = out[i * m : (i + 1) * m]
                if not isinstance(cols, AxisColumns):
                    whiten_rows(cols, self.idx, i, self.gap, *args, out=rows)
                    continue
                on = cols.axis == i
                rows[:, ~on] = 0.0  # a zero column whitens to zeros
                if on.any():
                    values = np.ascontiguousarray(cols.values[:, on])[:, None, :]
                    part = np.empty((m, values.shape[2]))
                    rows[:, on] = whiten_rows(values, self.idx, 0, self.gap, *args, out=part)

        map_threads(axis, range(3))

    def _whiten_dense(self, cols: np.ndarray, noise: NoiseModel) -> np.ndarray:
        """Whitened, axis-stacked copy (3m, p) of axis-major calibration-row columns (3, m, p)."""
        m = self.m
        out = np.empty((3 * m, cols.shape[2]))
        map_threads(
            lambda i: whiten(
                cols[i],
                self.gap,
                noise.white_std_nt[i],
                noise.fogm_std_nt[i],
                noise.fogm_tau_s[i],
                out=out[i * m : (i + 1) * m],
            ),
            range(3),
        )
        return out

    def _raw_rows(self, j: int) -> Any:
        """Axis-stacked calibration rows (3m, p) of group ``j``: kept for compact groups (sparse,
        small), a new dense array otherwise."""
        if not is_sparse(self.groups[j]):
            return stacked_rows(self.groups[j], self.idx)
        if j not in self._raw:
            self._raw[j] = stacked_rows(self.groups[j], self.idx)
        return self._raw[j]

    def gls(self, chosen: list[int], noise: NoiseModel) -> np.ndarray:
        """GLS coefficients of ``chosen`` (base first) under ``noise`` (not the problem's)."""
        x = design([self._whitened(j, noise) for j in chosen])
        yw = self._whiten_dense(self._y_axes, noise)[:, 0]
        return least_squares(x, yw)[0]

    def _span(self, chosen: list[int]) -> Span:
        """The chosen effects' span (off the base) and the whitened residual off it; cached per
        noise model, since every candidate of a step is tested against it."""
        key = tuple(chosen)
        if key not in self._spans:
            extra = [j for j in chosen if j != 0]
            dense = [self._perp(j) for j in extra if not is_sparse(self.groups[j])]
            compact = [self.white(j) for j in extra if is_sparse(self.groups[j])]
            q = orthonormal(np.concatenate(dense, axis=1)) if dense else np.zeros((self.yw.size, 0))
            r = self.r0 - q @ (q.T @ self.r0)
            sparse = None
            if compact:
                sparse = SparseSpan(concat(compact), np.concatenate([self._q0, q], axis=1))
                r = sparse.remove(r)
            rank = q.shape[1] + (0 if sparse is None else sparse.rank)
            self._spans[key] = Span(q, sparse, r, rank)
        return self._spans[key]

    def _perp(self, j: int) -> np.ndarray:
        """Dense group ``j``'s whitened columns off the base (3m, p)."""
        perp = self.perp[j]
        assert perp is not None, "a compact group's part off the base is implicit"
        return perp

    def whitened_residual(self, chosen: list[int]) -> np.ndarray:
        """Whitened, axis-stacked residual (3m,) of the GLS fit of ``chosen`` (base first)."""
        return self._span(chosen).r

    def fit(self, chosen: list[int]) -> tuple[np.ndarray, np.ndarray]:
        """GLS coefficients of ``chosen`` (base first) and their covariance."""
        x = design([self.white(j) for j in chosen])
        beta, rss, cov = least_squares(x, self.yw)
        return beta, cov * (rss / (x.shape[0] - x.shape[1]))

    def residual(self, chosen: list[int], beta: np.ndarray) -> np.ndarray:
        """Un-whitened calibration residual (m, 3) of ``chosen`` with ``beta``."""
        return self.y - predict_all([self.groups[j] for j in chosen], beta, self.idx)

    def absorbable_share(self, chosen: list[int], candidate: int, tau_s: np.ndarray) -> np.ndarray:
        """Per axis, the share of a FOGM's variance that ``candidate``'s columns outside the span
        of ``chosen`` could absorb, for each row of correlation times ``tau_s`` (k, 3) → (k, 3).

        Notes
        -----
        With ``q_j`` an orthonormal basis of the candidate's columns off the chosen ones
        (un-whitened, axis-stacked) and ``e`` a unit FOGM on axis i, least squares removes
        ``E‖P e‖² = Σ_j q_jiᵀ K_i q_ji`` of ``E‖e‖² = m``. Columns on the time scale of the
        eddy or lag effects (T̈-like) absorb next to nothing of a slow FOGM; slow, flexible
        groups (the external-field splines) absorb much of it.
        """
        m = self.m
        taus = np.atleast_2d(tau_s)
        basis = self._absorbing_basis(chosen, candidate)
        pieces = basis.chunks() if isinstance(basis, ChunkedBasis) else [basis]
        total = np.zeros(taus.shape)
        for u in pieces:
            for i in range(3):
                q = np.ascontiguousarray(u[i * m : (i + 1) * m])
                for k, t in enumerate(taus[:, i]):
                    total[k, i] += fogm_quadratic(q, self.gap, t).sum()
        return total / m

    def _raw_span(self, chosen: list[int]) -> tuple[np.ndarray, SparseSpan | None]:
        """The span of ``chosen``'s un-whitened columns: an orthonormal basis of the dense ones
        and the compact ones' span off it; the same under every noise model, so cached."""
        key = tuple(chosen)
        if key not in self._raw_spans:
            dense = [j for j in chosen if not is_sparse(self.groups[j])]
            compact = [j for j in chosen if is_sparse(self.groups[j])]
            cols = np.concatenate([self._raw_rows(j) for j in dense], axis=1)
            q0 = orthonormal(cols)
            sparse = None
            if compact:
                sparse = SparseSpan(concat([self._raw_rows(j) for j in compact]), q0)
            self._raw_spans[key] = (q0, sparse)
        return self._raw_spans[key]

    def _absorbing_basis(self, chosen: list[int], candidate: int) -> np.ndarray | ChunkedBasis:
        """Orthonormal basis (3m, r) of ``candidate``'s un-whitened columns off the span of
        ``chosen``; the same under every noise model. A compact candidate's basis is formed in
        pieces (:class:`ChunkedBasis`, whose small factors are kept: a group is asked about in
        the step that tests it, after it enters and in the backward pass)."""
        key = (*chosen, -1, candidate)
        if key in self._bases:
            return self._bases[key]
        q0, sparse = self._raw_span(chosen)
        x = self._raw_rows(candidate)
        if is_sparse(self.groups[candidate]):
            assert sparse is None, "one compact group at a time"
            # the same basis, xp V Λ^{-1/2} with xp = (x − q0 c) / ‖x‖, from xp's Gram matrix
            norm = np.sqrt(x.squares().sum(axis=1))
            inv = np.divide(1.0, norm, out=np.zeros_like(norm), where=norm > 0)  # 0: no column
            c = cross(q0, x)  # q0ᵀ x
            gram = (cross(x, x) - c.T @ c) * np.outer(inv, inv)
            lam, v = np.linalg.eigh(gram)
            keep = lam > 1e-12
            self._bases[key] = ChunkedBasis(
                x, q0, c, inv[:, None] * (v[:, keep] / np.sqrt(lam[keep]))
            )
            return self._bases[key]
        xp = x - q0 @ (q0.T @ x)
        if sparse is not None:
            xp = sparse.remove(xp)
        xp /= np.maximum(np.linalg.norm(x, axis=0), 1e-300)
        # an orthonormal basis of xp's columns from the p × p Gram matrix, not a tall SVD:
        # singular values s > 1e-6 are eigenvalues s² > 1e-12 (the sum in absorbable_share does
        # not depend on which basis of the span); formed again when asked again, not kept
        lam, v = np.linalg.eigh(xp.T @ xp)
        keep = lam > 1e-12
        return xp @ (v[:, keep] / np.sqrt(lam[keep]))

    def test_columns(self, chosen: list[int], columns: Any) -> dict[str, float] | None:
        """:meth:`test` for columns (n, 3, p) not in the problem."""
        idx = self.add(columns)
        try:
            return self.test(chosen, idx)
        finally:
            self.remove_last()

    def test(self, chosen: list[int], candidate: int) -> dict[str, float] | None:
        """Residual sums for adding ``candidate`` to ``chosen`` (None: nothing identifiable)."""
        span = self._span(chosen)
        r = span.r
        perp = self.perp[candidate]
        if perp is not None:
            # one pass: what it leaves in the span (eps · cond² of it) is orthogonal to r and
            # adds its square to gᵀg, far below rounding
            g = span.remove(perp, passes=1)
            gram, gr = g.T @ g, g.T @ r
        else:  # compact: its Gram matrix off the base and the chosen span, g never formed
            assert span.sparse is None, "one compact group at a time"
            w, q = self.white(candidate), np.concatenate([self._q0, span.q], axis=1)
            c = cross(q, w)
            gram = cross(w, w) - c.T @ c
            gr = w.t_dot(r) - c.T @ (q.T @ r)
        scale = self.scale[candidate]
        # the projection of r on g's column space from the small p × p Gram matrix instead of a
        # tall SVD (6× faster on a 99-column spline group): eigenvalues are squared singular
        # values, so the rank cut 1e-6 · scale becomes (1e-6 · scale)², still 4 decades above
        # the eigenvalues' rounding (1e-16 of the largest)
        lam, v = np.linalg.eigh(gram)
        keep = lam > (1e-6 * scale) ** 2
        p = int(keep.sum())
        if p == 0:
            return None
        rss0 = float(r @ r)
        z = v[:, keep].T @ gr
        drss = float(np.sum(z**2 / lam[keep]))
        resid_dof = r.size - self.k0 - span.rank - p
        return {"drss": drss, "rss0": rss0, "dof": p, "resid_dof": resid_dof, "rows": r.size}


#: Above this condition number of the column-scaled design, :func:`least_squares` leaves the
#: normal equations (which square it: 1e12, a relative error of 1e-4 in the weakest direction)
#: for QR with column pivoting. The whitened designs of the suite's flights reach 2e4.
NORMAL_EQUATIONS_MAX_COND = 1e6


def least_squares(x: np.ndarray | Design, y: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
    """Least-squares coefficients of ``y`` (rows,) on columns ``x`` (rows, p), the residual sum
    of squares and ``(xᵀx)⁺`` (p, p).

    ``x`` is a dense array or a :class:`~aeromag_env.discovery.regressors.Design` (blocks, some
    sparse): the same products either way. A column that is zero on every row (a spline
    outside a calibration window) is not identified: its coefficient is 0 and its entry of
    ``(xᵀx)⁺`` infinite on the diagonal (0 off it), not 0/0.

    Notes
    -----
    Solved through the p × p Gram matrix of the columns scaled to unit norm, with one step of
    iterative refinement (the corrected semi-normal equations): a tall ``xᵀx`` is one BLAS-3
    product, 15× faster than the pivoted QR of LAPACK gelsy on 72 000 × 120 (one thread), and
    the scaling is applied to the small matrix, so ``x`` is never copied. Its eigenvalues say
    whether the squared condition number is safe (:data:`NORMAL_EQUATIONS_MAX_COND`); otherwise
    gelsy solves, as it did for every fit before.
    """
    blocks = x if isinstance(x, Design) else None
    t_dot = (lambda z: x.T @ z) if blocks is None else blocks.t_dot  # type: ignore[union-attr]
    dot = (lambda b: x @ b) if blocks is None else blocks.dot
    gram = x.T @ x if blocks is None else blocks.gram()  # type: ignore[union-attr]
    norm = np.sqrt(np.diag(gram))
    seen = norm > 0
    ns = norm[seen]
    g = gram[np.ix_(seen, seen)] / np.outer(ns, ns)  # the Gram matrix of the unit columns
    lam, v = np.linalg.eigh(g)
    beta = np.zeros(x.shape[1])
    if not seen.any():
        g_inv = np.zeros((0, 0))
    elif lam[0] > lam[-1] / NORMAL_EQUATIONS_MAX_COND**2:
        g_inv = (v / lam) @ v.T
        beta[seen] = g_inv @ (t_dot(y)[seen] / ns) / ns
        beta[seen] += g_inv @ (t_dot(y - dot(beta))[seen] / ns) / ns
    else:
        g_inv = np.linalg.pinv(g)
        dense = x if blocks is None else blocks.dense()
        beta[seen] = _lstsq(dense[:, seen] / ns, y) / ns  # type: ignore[index]
    r = y - dot(beta)
    cov = np.zeros((x.shape[1], x.shape[1]))
    cov[np.ix_(seen, seen)] = g_inv / np.outer(ns, ns)
    cov[~seen, ~seen] = np.inf
    return beta, float(r @ r), cov


def _stored(columns: Any) -> Any:
    """A group's columns as the problem keeps them: compact forms as they are, dense arrays
    C-contiguous (the whitening kernel reads a row's columns in one run)."""
    return columns if is_compact(columns) else np.ascontiguousarray(columns)


def _largest_norm(x: np.ndarray) -> float:
    """The largest column norm of ``x`` (rows, p), 0 for no columns."""
    return float(np.sqrt(np.einsum("ij,ij->j", x, x).max(initial=0.0)))


def _lstsq(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Least squares by QR with column pivoting (LAPACK gelsy): rank-revealing like the SVD
    solver, 3x faster on these tall problems."""
    from scipy.linalg import lstsq

    return np.asarray(lstsq(a, b, lapack_driver="gelsy", check_finite=False)[0])


def ols(prob: WhitenedProblem, chosen: list[int]) -> np.ndarray:
    """Ordinary (un-whitened) least-squares coefficients of ``chosen`` on the calibration rows.

    Parameters
    ----------
    prob : WhitenedProblem
        The problem (its noise model is not used).
    chosen : list of int
        Indices of the groups in the fit, base (0) first (dense groups).

    Returns
    -------
    numpy.ndarray
        The coefficients, concatenated in the order of ``chosen``.
    """
    a = np.concatenate([stacked_rows(prob.groups[j], prob.idx) for j in chosen], axis=1)
    beta, *_ = np.linalg.lstsq(a, prob.y.T.reshape(-1), rcond=None)
    return np.asarray(beta)
