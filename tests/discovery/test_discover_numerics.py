"""Discovery's fast linear algebra against the plain, slow forms it replaced.

The workflow solves its least-squares problems through Gram matrices, takes orthonormal bases
from them, whitens with a kernel that skips the settled variance recursion and flushes tiny
states to 0, and caches bases across steps. Each is checked here against LAPACK, the SVD or a
plain Kalman filter, on the cases where the fast form is taken and where it must step aside.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import lstsq

from aeromag_env.discovery import whitened_problem
from aeromag_env.discovery.base_model import BaseSpan, base_columns, orthonormal, stack
from aeromag_env.discovery.noise_model import TAIL_TOL, NoiseModel, whiten, whiten_segments
from aeromag_env.discovery.preparation import prepare
from aeromag_env.discovery.regressors import (
    AxisColumns,
    compact_group,
    is_compact,
    one_axis,
    predict,
    spline_group,
    stacked_rows,
)
from aeromag_env.discovery.segments import Segments, concat, gram
from aeromag_env.discovery.suite import base_config
from aeromag_env.discovery.whitened_problem import WhitenedProblem, least_squares
from aeromag_env.flight.data import Flight
from aeromag_env.simulation.effects import EFFECTS
from aeromag_env.simulation.effects_base import body_columns
from aeromag_env.simulation.simulate import simulate_flight


@pytest.fixture(scope="module")
def flight() -> Flight:
    return simulate_flight(base_config(1200.0), 12)


def _design(rng: np.random.Generator, rows: int, cond: float, p: int = 30) -> np.ndarray:
    """Columns (rows, p) with the given condition number, then scaled over six decades."""
    u, _ = np.linalg.qr(rng.standard_normal((rows, p)))
    v, _ = np.linalg.qr(rng.standard_normal((p, p)))
    return (u * np.logspace(0, -np.log10(cond), p)) @ v * 10 ** rng.uniform(-3, 3, p)


def _solved_by_qr(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    calls: list[int] = []
    real = whitened_problem._lstsq

    def counted(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        calls.append(a.shape[1])
        return real(a, b)

    monkeypatch.setattr(whitened_problem, "_lstsq", counted)
    return calls


@pytest.mark.parametrize("cond", [3.0, 2e4, 5e5])
def test_least_squares_through_the_gram_matrix_equals_lapack(
    cond: float, monkeypatch: pytest.MonkeyPatch
) -> None:
    rng = np.random.default_rng(int(cond))
    x = _design(rng, 4000, cond)
    y = x @ rng.standard_normal(30) + rng.standard_normal(4000)
    qr = _solved_by_qr(monkeypatch)
    beta, rss, cov = least_squares(x, y)
    assert qr == []  # below NORMAL_EQUATIONS_MAX_COND: the normal equations solved it
    want, res, *_ = lstsq(x, y, lapack_driver="gelsd")
    norm = np.linalg.norm(x, axis=0)
    r_inv = np.linalg.inv(np.linalg.qr(x / norm, mode="r"))
    want_cov = (r_inv @ r_inv.T) / np.outer(norm, norm)  # (xᵀx)⁻¹ by QR, never squared
    sd = np.sqrt(np.diag(want_cov))
    se = sd * np.sqrt(res / (x.shape[0] - x.shape[1]))
    assert np.max(np.abs(beta - want) / se) < 1e-8  # in standard errors
    assert rss == pytest.approx(float(res), rel=1e-12)
    # as correlations: the normal equations' error grows with the squared condition number
    assert np.max(np.abs(cov - want_cov) / np.outer(sd, sd)) < 1e-15 * cond**2 + 1e-12


def test_least_squares_hands_an_ill_conditioned_design_to_pivoted_qr(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    rng = np.random.default_rng(8)
    x = _design(rng, 4000, 1e9)
    y = x @ rng.standard_normal(30) + rng.standard_normal(4000)
    qr = _solved_by_qr(monkeypatch)
    beta, rss, _ = least_squares(x, y)
    assert qr == [30]
    norm = np.linalg.norm(x, axis=0)  # unscaled, its condition number is 1e15: SVD of the scaled
    want, res, *_ = lstsq(x / norm, y, lapack_driver="gelsd")
    assert rss == pytest.approx(float(res), rel=1e-10)
    np.testing.assert_allclose(x @ beta, (x / norm) @ want, atol=1e-9 * np.abs(y).max())


def test_a_column_zero_on_every_row_is_not_identified() -> None:
    rng = np.random.default_rng(3)
    x = rng.standard_normal((500, 4))
    x[:, 2] = 0.0
    y = x @ np.array([1.0, 2.0, 5.0, -1.0]) + rng.standard_normal(500)
    beta, rss, cov = least_squares(x, y)
    want = lstsq(x[:, [0, 1, 3]], y)[0]
    np.testing.assert_allclose(beta[[0, 1, 3]], want, rtol=1e-12)
    assert beta[2] == 0.0 and cov[2, 2] == np.inf
    assert not cov[2, [0, 1, 3]].any() and not cov[[0, 1, 3], 2].any()
    assert np.isfinite(rss)
    beta, rss, cov = least_squares(np.zeros((50, 2)), y[:50])
    assert not beta.any() and rss == pytest.approx(float(y[:50] @ y[:50]))
    assert (np.diag(cov) == np.inf).all()


@pytest.mark.parametrize("cond", [5.0, 2e4, 1e5])
def test_orthonormal_basis_from_the_gram_matrix_spans_what_the_svd_spans(cond: float) -> None:
    rng = np.random.default_rng(int(cond))
    x = _design(rng, 6000, cond, 40)
    q = orthonormal(x)
    u = np.linalg.svd(x / np.linalg.norm(x, axis=0), full_matrices=False)[0]
    assert q.shape == u.shape
    np.testing.assert_allclose(q.T @ q, np.eye(40), atol=1e-13)
    y = rng.standard_normal((6000, 3))
    np.testing.assert_allclose(q @ (q.T @ y), u @ (u.T @ y), atol=1e-10)


def test_orthonormal_leaves_rank_to_the_svd_when_columns_repeat_or_vanish() -> None:
    rng = np.random.default_rng(4)
    x = rng.standard_normal((3000, 6))
    assert orthonormal(np.column_stack([x, 3.0 * x[:, 0]])).shape == (3000, 6)
    assert orthonormal(np.column_stack([x, np.zeros(3000)])).shape == (3000, 6)
    assert orthonormal(x[:, :0]).shape == (3000, 0)


def _kalman(x: np.ndarray, gap: np.ndarray, noise: tuple[float, float, float]) -> np.ndarray:
    """Normalised innovations by the textbook filter, row by row (the reference)."""
    white, fogm_std, tau = noise
    f, p = np.zeros(x.shape[1]), fogm_std**2
    out = np.empty_like(x)
    for k in range(x.shape[0]):
        a = np.exp(-gap[k] / tau)
        f, p = a * f, a * a * p + fogm_std**2 * (1 - a * a)
        s = p + white**2
        v = x[k] - f
        out[k] = v / np.sqrt(s)
        f, p = f + p / s * v, (1 - p / s) * p
    return out


def test_whitening_equals_the_textbook_filter_and_leaves_no_subnormal_numbers() -> None:
    """A column that ends (a spline past its support) decays towards 0: the kernel flushes its
    state below FLUSH, the reference lets it sink into subnormal numbers; both agree."""
    rng = np.random.default_rng(6)
    n = 6000
    tt = np.r_[np.arange(3000) * 0.1, 420.0 + np.arange(3000) * 0.1]  # a held-out block
    gap = np.r_[np.inf, np.diff(tt)]
    x = np.column_stack([rng.standard_normal(n), np.r_[np.ones(200), np.zeros(n - 200)]])
    for noise in [(1.0, 2.0, 600.0), (0.5, 3.0, 20.0), (2.0, 0.1, 5000.0)]:
        got = whiten(x, gap, *noise)
        want = _kalman(x, gap, noise)
        np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-140)
        tiny = np.abs(got[got != 0])
        assert tiny.min() >= np.finfo(float).tiny  # no subnormal number left
    assert (np.abs(want[got == 0]) < 1e-140).all()
    strided = np.stack([x, x], axis=2)[:, :, 0]  # not C-contiguous: copied, the same result
    assert np.array_equal(whiten(strided, gap, 1.0, 2.0, 600.0), whiten(x, gap, 1.0, 2.0, 600.0))


def test_identifiable_fraction_on_centred_columns_equals_the_raw_projection(
    flight: Flight,
) -> None:
    """A bus voltage at 28 ± 0.5 V: the centred form gives the raw projection's share."""
    data = prepare(flight, "flux_a", None)
    span = BaseSpan(base_columns(data.ctx.t_b, data.ctx.tdot_b), data.calibration)
    rng = np.random.default_rng(9)
    n = flight.tt.size
    volts = 28.0 + 0.5 * np.cumsum(rng.standard_normal(n)) / np.sqrt(n)
    group = volts[:, None, None] * np.eye(3)[None, :, :]
    for cols in (group, EFFECTS["altitude_gradient"].groups(data.ctx)[0][0].columns):
        xs = stack(cols[data.calibration])
        perp = xs - span.q @ (span.q.T @ xs)
        centred = stack(cols[data.calibration] - cols[data.calibration].mean(axis=0))
        want = np.mean(np.sum(perp**2, axis=0) / np.sum(centred**2, axis=0))
        assert span.identifiable_fraction(cols) == pytest.approx(want, rel=1e-9)


def test_cached_bases_are_forgotten_when_a_freed_index_is_reused(flight: Flight) -> None:
    """test_columns adds a candidate and frees its index; a group added there later must not
    inherit the cached basis of the one tested before."""
    data = prepare(flight, "flux_a", None)
    ctx = data.ctx
    base = base_columns(ctx.t_b, ctx.tdot_b)
    lags = EFFECTS["sensor_lag"].groups(ctx)[0]
    splines = EFFECTS["external_field_variation"].groups(ctx)[0][0]
    prob = WhitenedProblem(data, [base, lags[0].columns])
    prob.set_noise(NoiseModel(np.ones(3), np.full(3, 2.0), np.full(3, 600.0)))
    taus = np.full((1, 3), 600.0)
    prob.add(splines.columns)
    spline_share = prob.absorbable_share([0], 2, taus)
    prob.remove_last()
    j = prob.add(lags[-1].columns)
    assert j == 2
    fresh = WhitenedProblem(data, [base, lags[0].columns, lags[-1].columns])
    fresh.set_noise(prob.noise)  # type: ignore[arg-type]
    np.testing.assert_allclose(
        prob.absorbable_share([0], 2, taus), fresh.absorbable_share([0], 2, taus), rtol=1e-9
    )
    assert not np.allclose(prob.absorbable_share([0], 2, taus), spline_share)


@pytest.mark.parametrize("wider", [False, True])
def test_a_replaced_group_is_what_the_next_noise_model_whitens(flight: Flight, wider: bool) -> None:
    """set_noise whitens the groups into one reused array: a group replaced by one of the same
    width, or of another, must be whitened as a fresh problem with it would."""
    data = prepare(flight, "flux_a", None)
    ctx = data.ctx
    base = base_columns(ctx.t_b, ctx.tdot_b)
    lags = EFFECTS["sensor_lag"].groups(ctx)[0]
    splines = EFFECTS["external_field_variation"].groups(ctx)[0][0]
    new = splines.columns if wider else lags[-1].columns
    noise = NoiseModel(np.ones(3), np.full(3, 2.0), np.full(3, 600.0))
    prob = WhitenedProblem(data, [base, lags[0].columns, lags[1].columns])
    prob.set_noise(noise)
    prob.replace(1, new)
    prob.set_noise(noise)
    fresh = WhitenedProblem(data, [base, new, lags[1].columns])
    fresh.set_noise(noise)
    for j in range(3):
        np.testing.assert_array_equal(prob.white(j), fresh.white(j))
        if j:
            np.testing.assert_array_equal(prob.perp[j], fresh.perp[j])
    assert prob.test([0], 1) == fresh.test([0], 1)


def _runs(rng: np.random.Generator, m: int, p: int) -> Segments:
    """Random columns (3m, p), each one run of rows per axis (some axes empty)."""
    start, length, chunks = np.zeros((p, 3), int), np.zeros((p, 3), int), []
    for j in range(p):
        for i in range(3):
            n = int(rng.integers(0, m // 3)) if rng.random() > 0.2 else 0
            a = int(rng.integers(0, m - n + 1))
            start[j, i], length[j, i] = i * m + a, n
            chunks.append(rng.standard_normal(n))
    offset = (np.cumsum(length.ravel()) - length.ravel()).reshape(p, 3)
    return Segments(3 * m, start, length, offset, np.concatenate(chunks))


def test_products_of_columns_held_as_runs_equal_the_dense_products() -> None:
    rng = np.random.default_rng(21)
    a, b = _runs(rng, 400, 12), _runs(rng, 400, 7)
    da, db = a.toarray(), b.toarray()
    d = rng.standard_normal((1200, 5))
    c = rng.standard_normal((12, 4))
    # the same sums in another order: rounding, 1e-12 of the products' scale
    np.testing.assert_allclose(gram(a, b), da.T @ db, rtol=0, atol=1e-12 * np.abs(da.T @ db).max())
    np.testing.assert_allclose(a.t_dot(d), da.T @ d, rtol=0, atol=1e-12 * np.abs(da.T @ d).max())
    np.testing.assert_allclose(a.dot(c), da @ c, rtol=0, atol=1e-12 * np.abs(da @ c).max())
    np.testing.assert_allclose(a.t_dot(d[:, 0]), da.T @ d[:, 0], atol=1e-11)
    np.testing.assert_allclose(a.squares().sum(axis=1), (da**2).sum(axis=0), rtol=1e-12)
    by_axis = da.reshape(3, 400, 12).sum(axis=1).T
    np.testing.assert_allclose(a.sums(), by_axis, atol=1e-11)
    np.testing.assert_array_equal(a.axis(1).toarray()[400:800], da[400:800])
    assert not a.axis(1).toarray()[:400].any()
    np.testing.assert_array_equal(concat([a, b]).toarray(), np.hstack([da, db]))


@pytest.fixture(scope="module")
def spline_flight() -> Flight:
    return simulate_flight(base_config(1500.0), 14)


def test_compact_splines_are_the_effects_columns_bit_for_bit(spline_flight: Flight) -> None:
    data = prepare(spline_flight, "flux_a", None)
    dense = EFFECTS["external_field_variation"].groups(data.ctx)[0][0]
    compact = spline_group(data.ctx)
    cols = compact.columns
    assert is_compact(cols) and cols.shape == dense.columns.shape
    np.testing.assert_array_equal(cols.dense(), dense.columns)  # type: ignore[attr-defined]
    assert compact.labels == dense.labels
    b = np.random.default_rng(1).standard_normal(cols.shape[2])
    assert compact.to_parameters(b) == dense.to_parameters(b)
    idx = np.flatnonzero(data.calibration)
    np.testing.assert_array_equal(
        stacked_rows(cols, idx).toarray(), stacked_rows(dense.columns, idx)
    )
    want = np.einsum("kip,p->ki", dense.columns, b)
    np.testing.assert_allclose(predict(cols, b), want, rtol=0, atol=1e-12 * np.abs(want).max())
    np.testing.assert_allclose(predict(cols, b, data.held_out), want[data.held_out], atol=1e-9)
    span = BaseSpan(base_columns(data.ctx.t_b, data.ctx.tdot_b), data.calibration)
    assert span.identifiable_fraction(cols) == pytest.approx(
        span.identifiable_fraction(dense.columns), rel=1e-10
    )


@pytest.mark.parametrize("noise", [(1.0, 0.8, 300.0), (0.5, 3.0, 20.0), (1.0, 0.05, 600.0)])
def test_whitening_runs_keeps_the_dense_kernels_values_and_cuts_only_a_negligible_tail(
    spline_flight: Flight, noise: tuple[float, float, float]
) -> None:
    data = prepare(spline_flight, "flux_a", None)
    idx = np.flatnonzero(data.calibration)
    m = idx.size
    gap = np.r_[np.inf, np.diff(data.ctx.tt[idx])]
    x = stacked_rows(spline_group(data.ctx).columns, idx)
    model = NoiseModel(*(np.full(3, v) for v in noise))
    got = whiten_segments(x, gap, model).toarray()
    dense = x.toarray()
    want = np.vstack([whiten(dense[i * m : (i + 1) * m], gap, *noise) for i in range(3)])
    kept = got != 0
    np.testing.assert_array_equal(got[kept], want[kept])
    for i in range(3):  # what is cut: below TAIL_TOL of its column's largest on that axis
        rows = slice(i * m, (i + 1) * m)
        biggest = np.abs(want[rows]).max(axis=0)
        cut = np.where(kept[rows], 0.0, np.abs(want[rows]))
        assert (cut <= TAIL_TOL * biggest).all()


def test_a_problem_with_compact_splines_tests_and_fits_as_with_dense_ones(
    spline_flight: Flight,
) -> None:
    """The compact splines' test, fit and absorbable share (through Gram matrices and runs) and
    the tests of other groups against them once chosen equal the dense forms' to rounding."""
    data = prepare(spline_flight, "flux_a", None)
    ctx = data.ctx
    base = base_columns(ctx.t_b, ctx.tdot_b)
    others = [g.columns for g in (*EFFECTS["eddy_time_constant"].groups(ctx)[0][:2],)]
    dense = EFFECTS["external_field_variation"].groups(ctx)[0][0].columns
    compact = spline_group(ctx).columns
    noise = NoiseModel(np.ones(3), np.full(3, 1.5), np.full(3, 200.0))
    probs = [WhitenedProblem(data, [base, s, *others]) for s in (dense, compact)]
    for prob in probs:
        prob.set_noise(noise)
    for chosen, j in [([0], 1), ([0], 2), ([0, 1], 2), ([0, 1], 3), ([0, 2], 1)]:
        want, got = probs[0].test(chosen, j), probs[1].test(chosen, j)
        assert want is not None and got is not None
        assert got["dof"] == want["dof"] and got["resid_dof"] == want["resid_dof"]
        # both take ΔRSS from the eigenvalues of the candidate's Gram matrix off the span, whose
        # rounding is eps · cond² of it (3.5e8 for these splines: the dense form itself moves by
        # 2.5e-9 when its rows are reversed); the rest is plain rounding
        g = probs[0]._span(chosen).remove(probs[0].perp[j])  # type: ignore[arg-type]
        lam = np.linalg.eigvalsh(g.T @ g)
        cond2 = lam[-1] / lam[lam > (1e-6 * probs[0].scale[j]) ** 2][0]
        assert got["drss"] == pytest.approx(want["drss"], rel=1e-15 * cond2 + 1e-12)
        assert got["rss0"] == pytest.approx(want["rss0"], rel=1e-12)
    for chosen in ([0, 1], [0, 1, 2]):
        (b0, c0), (b1, c1) = probs[0].fit(chosen), probs[1].fit(chosen)
        se = np.sqrt(np.diag(c0))
        np.testing.assert_allclose(b1, b0, rtol=0, atol=1e-8 * se.max())  # refined: rounding
        # (xᵀx)⁻¹ from the normal equations, unrefined: eps · cond² of the unit-column design
        # (about 1e9 with the splines: the dense form moves by 1e-7 on reordered rows)
        np.testing.assert_allclose(np.sqrt(np.diag(c1)), se, rtol=1e-5)
        np.testing.assert_allclose(
            probs[1].residual(chosen, b1), probs[0].residual(chosen, b0), atol=1e-9
        )
        r0, r1 = probs[0].whitened_residual(chosen), probs[1].whitened_residual(chosen)
        np.testing.assert_allclose(r1, r0, atol=1e-9 * np.abs(r0).max())
    taus = np.array([[200.0] * 3, [30.0] * 3])
    for chosen, j in [([0], 1), ([0, 1], 2)]:
        # both bases come from a Gram matrix (eigenvalues down to 1e-12 of the largest kept):
        # orthonormal to eps · cond², about 1e-7 here; the shares are compared with 0.05
        np.testing.assert_allclose(
            probs[1].absorbable_share(chosen, j, taus),
            probs[0].absorbable_share(chosen, j, taus),
            rtol=1e-6,
        )
    gls0, gls1 = (p.gls([0, 1], noise) for p in probs)
    np.testing.assert_allclose(gls1, gls0, rtol=1e-8, atol=1e-12)


def test_one_axis_groups_are_held_by_axis_and_whiten_as_the_dense_ones(flight: Flight) -> None:
    """The eddy groups (B_e rows) and the currents (``w(t) e_i``) are one-axis: held as values by
    axis, they are the dense columns bit for bit, whiten to the same bits and predict the same
    field; a group with a column on two axes (the lag) stays dense."""
    data = prepare(flight, "flux_a", None)
    ctx = data.ctx
    eddy = EFFECTS["eddy_time_constant"].groups(ctx)[0][3]
    volts = np.linspace(27.5, 28.5, ctx.n)
    current = body_columns(volts[:, None])
    lag = EFFECTS["sensor_lag"].groups(ctx)[0][0]
    assert one_axis(lag.columns) is None
    compact = compact_group(eddy)
    assert isinstance(compact.columns, AxisColumns) and compact.profile == eddy.profile
    assert isinstance(compact.rebuild(0.3).columns, AxisColumns)  # type: ignore[misc]
    base = base_columns(ctx.t_b, ctx.tdot_b)
    noise = NoiseModel(np.ones(3), np.full(3, 1.5), np.full(3, 200.0))
    for dense in (eddy.columns, current):
        cols = one_axis(dense)
        assert cols is not None
        np.testing.assert_array_equal(cols.dense(), dense)
        b = np.random.default_rng(5).standard_normal(dense.shape[2])
        want = np.einsum("kip,p->ki", dense, b)
        np.testing.assert_allclose(cols.predict(b), want, rtol=0, atol=1e-12 * np.abs(want).max())
        probs = [WhitenedProblem(data, [base, c]) for c in (dense, cols)]
        for prob in probs:
            prob.set_noise(noise)
        np.testing.assert_array_equal(probs[1].white(1), probs[0].white(1))
        np.testing.assert_array_equal(probs[1].perp[1], probs[0].perp[1])
        assert probs[1].test([0], 1) == probs[0].test([0], 1)
