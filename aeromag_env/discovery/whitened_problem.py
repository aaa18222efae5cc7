"""The whitened (GLS) least-squares problem on the calibration rows: fits and partial tests.

Decides the numbers every verdict rests on: the noise model's Kalman innovations whiten the
residual and every regressor (generalised least squares), the base regressors are projected
out once (Frisch–Waugh–Lovell), and :meth:`WhitenedProblem.test` gives the residual sums for
adding one candidate group to the chosen ones; :meth:`WhitenedProblem.fit` gives the GLS
coefficients and their covariance, :meth:`WhitenedProblem.absorbable_share` how much of a slow
FOGM a group could absorb.
"""

from __future__ import annotations

from itertools import pairwise

import numpy as np

from aeromag_env.discovery.base_model import orthonormal
from aeromag_env.discovery.noise_model import NoiseModel, fogm_quadratic, whiten
from aeromag_env.discovery.preparation import PreparedFlight
from aeromag_env.threads import map_threads


class WhitenedProblem:
    """The whitened, axis-stacked least-squares problem on the calibration rows.

    After :meth:`set_noise`, the base regressors are projected out of the whitened data and of
    every candidate once (Frisch–Waugh–Lovell); tests then work on those small residual problems.

    Parameters
    ----------
    data : PreparedFlight
        The prepared flight; its calibration rows are the problem's rows.
    columns : list of numpy.ndarray
        Regressor groups (n, 3, p) on all samples; index 0 is the base model, the others the
        candidate groups (index ``j`` is candidate group ``j − 1``).
    """

    def __init__(self, data: PreparedFlight, columns: list[np.ndarray]) -> None:
        self.data = data
        self.idx = np.flatnonzero(data.calibration)
        self.gap = np.r_[np.inf, np.diff(data.ctx.tt[self.idx])]
        self.y = data.y[self.idx]
        self._y_axes = np.ascontiguousarray(self.y.T[:, :, None])  # (3, m, 1)
        # each axis-major (3, m, p), so an axis is contiguous and stacking is a reshape; 0 is
        # the base. The groups given here are views of one array, whitened without a copy
        self.columns = self._pack([self._rows(c) for c in columns])
        self._buffers: dict[str, np.ndarray] = {}
        self.noise: NoiseModel | None = None
        self.white: list[np.ndarray] = []
        self.yw = np.empty(0)
        self.r0 = np.empty(0)
        self.perp: list[np.ndarray] = []
        self.scale: list[float] = []  # per group, its whitened columns' largest norm
        self._spans: dict[tuple[int, ...], tuple[np.ndarray, np.ndarray]] = {}
        self._raw_spans: dict[tuple[int, ...], np.ndarray] = {}
        self._bases: dict[tuple[int, ...], np.ndarray] = {}

    def set_noise(self, noise: NoiseModel) -> None:
        """Whiten the data and every group under ``noise`` and project the base out of them."""
        self.noise = noise
        self.yw = self._whiten_columns(self._y_axes)[:, 0]
        extra = self.columns[len(self._edges) - 1 :]  # groups added since: rare
        cols = np.concatenate([self._bulk, *extra], axis=2) if extra else self._bulk
        # fresh 100-MB arrays cost more in page faults than their arithmetic: reuse them
        allc = self._whiten_columns(cols, out=self._buffer("white", cols.shape[2]))
        edges = np.cumsum([0] + [c.shape[2] for c in self.columns])
        self.white = [allc[:, edges[j] : edges[j + 1]] for j in range(len(self.columns))]
        self._q0 = orthonormal(self.white[0])
        self.r0 = self._off_base(self.yw)
        # one product for all groups, not one per group
        allp = self._off_base(allc, out=self._buffer("perp", cols.shape[2]))
        self.perp = [allp[:, edges[j] : edges[j + 1]] for j in range(len(self.columns))]
        self.scale = [_largest_norm(w) for w in self.white]
        self.k0 = self._q0.shape[1]
        self._spans = {}

    def add(self, columns: np.ndarray) -> int:
        """Append a candidate (n, 3, p) built after :meth:`set_noise`; returns its index."""
        self.columns.append(self._rows(columns))
        w = self._whiten_columns(self.columns[-1])
        self.white.append(w)
        self.perp.append(self._off_base(w))
        self.scale.append(_largest_norm(w))
        new = len(self.columns) - 1  # an index test_columns used and freed: forget its caches
        self._spans = {k: v for k, v in self._spans.items() if new not in k}
        self._raw_spans = {k: v for k, v in self._raw_spans.items() if new not in k}
        self._bases = {k: v for k, v in self._bases.items() if new not in k}
        return new

    def replace(self, index: int, columns: np.ndarray) -> None:
        """Rebuild candidate ``index`` from new columns (n, 3, p), under the current noise."""
        packed = len(self._edges) - 1
        if index < packed and columns.shape[2] == self.columns[index].shape[2]:
            self.columns[index][...] = self._rows(columns)  # stays a view of the bulk array
        elif index < packed:  # another width: pack the groups again
            self.columns[index] = self._rows(columns)
            self.columns[:packed] = self._pack(self.columns[:packed])
        else:
            self.columns[index] = self._rows(columns)
        self.white[index] = self._whiten_columns(self.columns[index])
        self.perp[index] = self._off_base(self.white[index])
        self.scale[index] = _largest_norm(self.white[index])
        self._spans, self._raw_spans, self._bases = {}, {}, {}

    def _off_base(self, x: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        out = np.matmul(self._q0, self._q0.T @ x, out=out)
        return np.subtract(x, out, out=out)

    def _pack(self, groups: list[np.ndarray]) -> list[np.ndarray]:
        """Copy axis-major groups (3, m, p) into one array (``_bulk``, bounds ``_edges``) and
        return its views, one per group."""
        self._edges = np.cumsum([0] + [g.shape[2] for g in groups])
        self._bulk = np.concatenate(groups, axis=2)
        return [self._bulk[:, :, a:b] for a, b in pairwise(self._edges)]

    def _buffer(self, name: str, p: int) -> np.ndarray:
        """A reused (3m, p) array: what :meth:`set_noise` held in it before is replaced."""
        if name not in self._buffers or self._buffers[name].shape[1] != p:
            self._buffers[name] = np.empty((3 * self.idx.size, p))
        return self._buffers[name]

    def gls(self, chosen: list[int], noise: NoiseModel) -> np.ndarray:
        """GLS coefficients of ``chosen`` (base first) under ``noise`` (not the problem's)."""
        x = self._whiten_columns(np.concatenate([self.columns[j] for j in chosen], axis=2), noise)
        yw = self._whiten_columns(self._y_axes, noise)[:, 0]
        return least_squares(x, yw)[0]

    def _whiten_columns(
        self, cols: np.ndarray, noise: NoiseModel | None = None, out: np.ndarray | None = None
    ) -> np.ndarray:
        """Whitened, axis-stacked copy (3m, p) of axis-major calibration-row columns (3, m, p),
        under ``noise`` or else the problem's noise model; into ``out`` when given."""
        noise = noise or self.noise
        assert noise is not None
        m = self.idx.size
        out = np.empty((3 * m, cols.shape[2])) if out is None else out
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

    def _rows(self, columns: np.ndarray) -> np.ndarray:
        """Axis-major calibration rows (3, m, p) of columns (n, 3, p)."""
        return np.ascontiguousarray(columns.transpose(1, 0, 2)[:, self.idx])

    def _span(self, chosen: list[int]) -> tuple[np.ndarray, np.ndarray]:
        """Orthonormal basis of the chosen effects (off the base) and the residual off it;
        cached per noise model, since every candidate of a step is tested against it."""
        key = tuple(chosen)
        if key not in self._spans:
            extra = [self.perp[j] for j in chosen if j != 0]
            q = orthonormal(np.concatenate(extra, axis=1)) if extra else np.zeros((self.yw.size, 0))
            self._spans[key] = (q, self.r0 - q @ (q.T @ self.r0))
        return self._spans[key]

    def whitened_residual(self, chosen: list[int]) -> np.ndarray:
        """Whitened, axis-stacked residual (3m,) of the GLS fit of ``chosen`` (base first)."""
        return self._span(chosen)[1]

    def fit(self, chosen: list[int]) -> tuple[np.ndarray, np.ndarray]:
        """GLS coefficients of ``chosen`` (base first) and their covariance."""
        x = np.concatenate([self.white[j] for j in chosen], axis=1)
        beta, rss, cov = least_squares(x, self.yw)
        return beta, cov * (rss / (x.shape[0] - x.shape[1]))

    def residual(self, chosen: list[int], beta: np.ndarray) -> np.ndarray:
        """Un-whitened calibration residual (m, 3) of ``chosen`` with ``beta``."""
        x = np.concatenate([self.columns[j] for j in chosen], axis=2)
        return self.y - np.einsum("ikp,p->ki", x, beta)

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
        m = self.idx.size
        u = self._absorbing_basis(chosen, candidate)
        q = [u[i * m : (i + 1) * m] for i in range(3)]
        return np.array(
            [
                [fogm_quadratic(q[i], self.gap, t).sum() / m for i, t in enumerate(row)]
                for row in np.atleast_2d(tau_s)
            ]
        )

    def _absorbing_basis(self, chosen: list[int], candidate: int) -> np.ndarray:
        """Orthonormal basis (3m, r) of ``candidate``'s un-whitened columns off the span of
        ``chosen``; the same under every noise model, so cached (a group is asked about in the
        step that tests it, after it enters and in the backward pass)."""
        key = (*chosen, -1, candidate)
        if key in self._bases:
            return self._bases[key]
        x = _stacked(self.columns[candidate])
        span = tuple(chosen)
        if span not in self._raw_spans:
            cols = np.concatenate([self.columns[j] for j in chosen], axis=2)
            self._raw_spans[span] = orthonormal(_stacked(cols))
        q0 = self._raw_spans[span]
        xp = (x - q0 @ (q0.T @ x)) / np.maximum(np.linalg.norm(x, axis=0), 1e-300)
        # an orthonormal basis of xp's columns from the p × p Gram matrix, not a tall SVD:
        # singular values s > 1e-6 are eigenvalues s² > 1e-12 (the sum in absorbable_share does
        # not depend on which basis of the span)
        lam, v = np.linalg.eigh(xp.T @ xp)
        keep = lam > 1e-12
        self._bases[key] = xp @ (v[:, keep] / np.sqrt(lam[keep]))
        return self._bases[key]

    def test_columns(self, chosen: list[int], columns: np.ndarray) -> dict[str, float] | None:
        """:meth:`test` for columns (n, 3, p) not in the problem."""
        idx = self.add(columns)
        try:
            return self.test(chosen, idx)
        finally:
            del self.columns[idx], self.white[idx], self.perp[idx], self.scale[idx]

    def test(self, chosen: list[int], candidate: int) -> dict[str, float] | None:
        """Residual sums for adding ``candidate`` to ``chosen`` (None: nothing identifiable)."""
        q, r = self._span(chosen)
        g = self.perp[candidate]
        if q.shape[1]:
            g = g - q @ (q.T @ g)
        scale = self.scale[candidate]
        # the projection of r on g's column space from the small p × p Gram matrix instead of a
        # tall SVD (6× faster on a 99-column spline group): eigenvalues are squared singular
        # values, so the rank cut 1e-6 · scale becomes (1e-6 · scale)², still 4 decades above
        # the eigenvalues' rounding (1e-16 of the largest)
        lam, v = np.linalg.eigh(g.T @ g)
        keep = lam > (1e-6 * scale) ** 2
        p = int(keep.sum())
        if p == 0:
            return None
        rss0 = float(r @ r)
        z = v[:, keep].T @ (g.T @ r)
        drss = float(np.sum(z**2 / lam[keep]))
        resid_dof = r.size - self.k0 - q.shape[1] - p
        return {"drss": drss, "rss0": rss0, "dof": p, "resid_dof": resid_dof, "rows": r.size}


#: Above this condition number of the column-scaled design, :func:`least_squares` leaves the
#: normal equations (which square it: 1e12, a relative error of 1e-4 in the weakest direction)
#: for QR with column pivoting. The whitened designs of the suite's flights reach 2e4.
NORMAL_EQUATIONS_MAX_COND = 1e6


def least_squares(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
    """Least-squares coefficients of ``y`` (rows,) on columns ``x`` (rows, p), the residual sum
    of squares and ``(xᵀx)⁺`` (p, p).

    A column that is zero on every row (a spline outside a calibration window) is not
    identified: its coefficient is 0 and its entry of ``(xᵀx)⁺`` infinite on the diagonal (0
    off it), not 0/0.

    Notes
    -----
    Solved through the p × p Gram matrix of the columns scaled to unit norm, with one step of
    iterative refinement (the corrected semi-normal equations): a tall ``xᵀx`` is one BLAS-3
    product, 15× faster than the pivoted QR of LAPACK gelsy on 72 000 × 120 (one thread), and
    the scaling is applied to the small matrix, so ``x`` is never copied. Its eigenvalues say
    whether the squared condition number is safe (:data:`NORMAL_EQUATIONS_MAX_COND`); otherwise
    gelsy solves, as it did for every fit before.
    """
    gram = x.T @ x
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
        beta[seen] = g_inv @ ((x.T @ y)[seen] / ns) / ns
        beta[seen] += g_inv @ ((x.T @ (y - x @ beta))[seen] / ns) / ns
    else:
        g_inv = np.linalg.pinv(g)
        beta[seen] = _lstsq(x[:, seen] / ns, y) / ns
    r = y - x @ beta
    cov = np.zeros((x.shape[1], x.shape[1]))
    cov[np.ix_(seen, seen)] = g_inv / np.outer(ns, ns)
    cov[~seen, ~seen] = np.inf
    return beta, float(r @ r), cov


def _stacked(x: np.ndarray) -> np.ndarray:
    """Axis-stacked rows (3m, p) of axis-major columns (3, m, p): a view."""
    return x.reshape(-1, x.shape[2])


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
        Indices of the groups in the fit, base (0) first.

    Returns
    -------
    numpy.ndarray
        The coefficients, concatenated in the order of ``chosen``.
    """
    a = _stacked(np.concatenate([prob.columns[j] for j in chosen], axis=2))
    beta, *_ = np.linalg.lstsq(a, prob.y.T.reshape(-1), rcond=None)
    return np.asarray(beta)
