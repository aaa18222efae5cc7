import json
from dataclasses import replace

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter

from aeromag_env.compensation.compensate import earth_model
from aeromag_env.compensation.kalman import FilterState, run_filter
from aeromag_env.compensation.kalman_reference import run_reference
from aeromag_env.compensation.least_squares import fit_vector_lsq
from aeromag_env.compensation.model import (
    METHODS,
    FilterConfig,
    interference_from_states,
    measurement_rows,
    paper_filter_config,
)
from aeromag_env.errors import ConfigError
from aeromag_env.simulation.config import preset
from aeromag_env.simulation.simulate import simulate_flight
from tests._flights import simulated


def _true_state(f):
    c = json.loads(f.attrs["truth_coefficients"])["flux_a"]
    return np.concatenate([c["permanent_nt"], np.ravel(c["induced"]), np.ravel(c["eddy_s"])])


def _assert_columns_close(actual, desired, rel):
    """max |actual − desired| per column, relative to that column's magnitude, below ``rel``."""
    scale = np.abs(desired).max(axis=0)
    worst = np.max(np.abs(actual - desired), axis=0) / np.where(scale > 0, scale, 1.0)
    assert worst.max() < rel, (
        f"worst relative column error {worst.max():.2e} (column {worst.argmax()})"
    )


def _inputs(f, scheme="backward"):
    t_b, td = earth_model(f, scheme)
    return f.vector("flux_a") - t_b, t_b, td


@pytest.fixture(scope="module")
def short_paper():
    """A 150 s slice of the paper flight: long enough for windows to fill and adapt."""
    y, t_b, td = _inputs(simulated("paper", 1))
    return y[:1500], t_b[:1500], td[:1500]


def test_measurement_rows_follow_eq_12():
    t = np.array([[1.0, 2.0, 3.0]])
    td = np.array([[4.0, 5.0, 6.0]])
    h = measurement_rows(t, td)[0]
    np.testing.assert_array_equal(h[1, :3], [0, 1, 0])
    np.testing.assert_array_equal(h[1, 6:9], [1, 2, 3])
    np.testing.assert_array_equal(h[1, 15:18], [4, 5, 6])
    assert np.count_nonzero(h) == 21  # each state appears in exactly one row
    x = np.arange(21.0)
    np.testing.assert_allclose(interference_from_states(x, t, td)[0], h @ x)


@pytest.mark.parametrize("method", METHODS)
def test_compiled_equals_numpy_reference(short_paper, method):
    cfg = (
        paper_filter_config(method)
        if method == "fakf"
        else FilterConfig(method=method, r_std_nt=20.0)
    )
    fast = run_filter(cfg, *short_paper)
    ref = run_reference(cfg, *short_paper)
    # same equations, different summation order and Joseph layout: agreement to round-off,
    # amplified by the conditioning of P (relative 1e-8 on the states)
    _assert_columns_close(fast.states, ref.states, 1e-8)
    np.testing.assert_allclose(fast.ror, ref.ror, rtol=1e-8)
    np.testing.assert_allclose(fast.q_scale, ref.q_scale, rtol=1e-8)
    np.testing.assert_allclose(fast.r_scale, ref.r_scale, rtol=1e-8)
    np.testing.assert_allclose(fast.interference, ref.interference, rtol=1e-8, atol=1e-6)


def test_plain_kf_equals_filterpy(short_paper):
    """filterpy 2.0.0 runs the unscaled 21-state problem with its own Joseph update."""
    y, t_b, td = short_paper
    cfg = FilterConfig(r_std_nt=20.0)
    ours = run_filter(cfg, y, t_b, td)
    kf = KalmanFilter(dim_x=21, dim_z=3)
    kf.x = cfg.initial_state().reshape(21, 1)
    kf.P = cfg.initial_covariance()
    kf.Q = np.diag(cfg.process_noise())
    kf.R = cfg.measurement_noise()
    kf.F = np.eye(21)
    h_all = measurement_rows(t_b, td)
    states = np.empty((len(y), 21))
    for k in range(len(y)):
        kf.predict()
        kf.update(y[k].reshape(3, 1), H=h_all[k])
        states[k] = kf.x.ravel()
    _assert_columns_close(ours.states, states, 1e-9)


def test_noise_free_lsq_recovers_and_kf_converges():
    f = simulated("noise_free", 0)
    truth = _true_state(f)
    y, t_b, td = _inputs(f, "central")
    fit = fit_vector_lsq(y, t_b, td)
    np.testing.assert_allclose(fit.state, truth, rtol=1e-6)  # exact data, exact model
    kf = run_filter(FilterConfig(rate_scheme="central"), y, t_b, td)
    # the random-walk Q keeps the KF a little loose: 1e-3 relative on every coefficient
    np.testing.assert_allclose(kf.final_state, truth, rtol=1e-3)
    causal = run_filter(FilterConfig(), *_inputs(f, "backward"))
    # a backward-difference Ṫ lags half a sample: the eddy block is biased by a few percent,
    # which is why ``lsq`` (offline) uses central differences
    np.testing.assert_allclose(causal.final_state[:12], truth[:12], rtol=2e-2)


def test_kf_matches_batch_lsq_on_nominal_flights_on_average():
    """Issue 3: after convergence (second half) the causal KF is within 10 % of the offline
    batch LS. Single flights scatter (±20 %: the unmodelled slow external field dominates both
    errors), so the claim is on the mean over 40 seeds with a 95 % confidence bound
    (an exploratory run gave a mean ratio of 1.035 over seeds 0–15)."""
    ratios = []
    for seed in range(40):
        f = simulate_flight(preset("nominal"), seed)
        truth = f.vector("truth_interf")
        half = np.arange(f.n) >= f.n // 2
        y, t_b, td = _inputs(f, "central")
        lsq = fit_vector_lsq(y, t_b, td).predict(t_b, td)
        kf = run_filter(FilterConfig(), *_inputs(f)).interference
        err = [np.sqrt(np.mean((truth - e)[half] ** 2)) for e in (kf, lsq)]
        ratios.append(err[0] / err[1])
    mean, sem = np.mean(ratios), np.std(ratios, ddof=1) / np.sqrt(len(ratios))
    assert mean + 2.02 * sem < 1.10  # t(0.975, 39 dof) = 2.02


def test_a_sample_is_valid_when_every_axis_of_every_input_is_finite(short_paper):
    y, t_b, td = (a[:20].copy() for a in short_paper)
    for row, (a, axis, bad) in enumerate(
        [(y, 0, np.nan), (y, 2, np.inf), (t_b, 1, -np.inf), (td, 0, np.nan), (td, 2, np.inf)]
    ):
        a[2 * row, axis] = bad
    state = FilterState(FilterConfig(), y, t_b, td)
    expected = np.all(np.isfinite(y) & np.isfinite(t_b) & np.isfinite(td), axis=1)
    np.testing.assert_array_equal(state.valid, expected)
    assert state.valid.shape == (20,) and np.count_nonzero(~state.valid) == 5


def test_nonfinite_samples_are_skipped_and_counted(short_paper):
    y, t_b, td = (a.copy() for a in short_paper)
    y[100:110] = np.nan
    td[500, 1] = np.inf
    res = run_filter(FilterConfig(r_std_nt=20.0), y, t_b, td)
    assert res.skipped == 11
    assert np.all(np.isnan(res.innovations[100:110]))
    assert np.all(np.isfinite(res.interference[td[:, 1] != np.inf]))
    assert np.all(np.isfinite(res.states))


def test_divergence_is_detected_and_recovered(short_paper):
    y, t_b, td = (a.copy() for a in short_paper)
    y[700] = 1e300  # an absurd sample throws the state out of any physical range
    res = run_filter(FilterConfig(r_std_nt=20.0), y, t_b, td)
    assert res.divergences == 1
    assert np.all(np.isfinite(res.states)) and np.all(np.isfinite(res.interference))
    state = FilterState(FilterConfig(r_std_nt=20.0), *short_paper)
    state.advance(300)
    state.scale_noise(1e300, 1.0)  # a runaway Q: the covariance overflows
    state.advance(1500)
    res = state.result()
    assert res.divergences == 1
    assert np.all(np.isfinite(res.states)) and np.all(np.isfinite(res.interference))
    assert np.all(np.isfinite(res.final_covariance))


def test_window_by_window_equals_one_run(short_paper):
    cfg = paper_filter_config("fakf")
    whole = run_filter(cfg, *short_paper)
    state = FilterState(cfg, *short_paper)
    for k1 in range(10, 1501, 10):
        state.advance(k1)
    np.testing.assert_array_equal(state.result().states, whole.states)


def test_fakf_raises_a_too_small_r():
    """Paper setting: R(0) = 2e-3 nT² against 20 nT noise → ROR ≫ 1, so the rules grow R."""
    y, t_b, td = _inputs(simulated("paper", 2))
    res = run_filter(paper_filter_config("fakf"), y, t_b, td)
    assert res.r_scale[-1] > 1e4
    plain = run_filter(paper_filter_config("kf"), y, t_b, td)
    assert np.nanmedian(plain.ror[len(y) // 2 :]) > 10


def test_config_errors_are_one_line():
    with pytest.raises(ConfigError, match="method must be one of"):
        FilterConfig(method="ukf")
    with pytest.raises(ConfigError, match="window must be"):
        FilterConfig(window=1)


def test_sage_husa_innovation_form_matches_reference(short_paper):
    cfg = FilterConfig(method="sage-husa", r_std_nt=20.0, sage_husa_form="innovation")
    fast, ref = run_filter(cfg, *short_paper), run_reference(cfg, *short_paper)
    _assert_columns_close(fast.states, ref.states, 1e-8)
    np.testing.assert_allclose(fast.r_scale, ref.r_scale, rtol=1e-8)


def test_sage_husa_forms_from_a_far_too_small_r():
    """Paper setting, R(0) = 2e-3 nT² against 20 nT noise: the post-fit form stays stuck (its
    residual shrinks with R), the innovation form recovers the noise level (documented)."""
    y, t_b, td = _inputs(simulated("paper", 2))
    base = paper_filter_config("sage-husa")
    stuck = run_filter(base, y, t_b, td)
    recovered = run_filter(replace(base, sage_husa_form="innovation"), y, t_b, td)
    assert np.sqrt(stuck.final_r[0, 0]) < 1.0
    assert 15.0 < np.sqrt(np.mean(np.diag(recovered.final_r))) < 25.0
