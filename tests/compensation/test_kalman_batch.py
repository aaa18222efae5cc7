import numpy as np
import pytest

from aeromag_env.compensation.compensate import earth_model
from aeromag_env.compensation.kalman import FilterState, run_filter
from aeromag_env.compensation.kalman_batch import BatchFilterState
from aeromag_env.compensation.model import METHODS, FilterConfig, paper_filter_config
from tests._flights import simulated

#: Batched and single-flight filters run the same compiled per-flight loop, so they agree
#: bitwise; the issue asks for 1e-12 relative, which is what is asserted.
RTOL = 1e-12
FIELDS = (
    "interference",
    "innovations",
    "ror",
    "qoq",
    "q_scale",
    "r_scale",
    "states",
    "final_state",
    "final_covariance",
    "final_r",
    "final_q",
)


@pytest.fixture(scope="module")
def flights():
    """Three slices of different lengths of a paper flight (20 nT noise): windows fill, adapt."""
    f = simulated("paper", 1)
    t_b, td = earth_model(f, "backward")
    y = f.vector("flux_a") - t_b
    return [(y[a:b], t_b[a:b], td[a:b]) for a, b in ((0, 1500), (300, 1500), (100, 1000))]


def _configs(method):
    return [
        paper_filter_config(method),
        FilterConfig(method=method, r_std_nt=20.0),
        FilterConfig(method=method, r_std_nt=5.0, window=30),
    ]


def _assert_same(batched, single):
    for name in FIELDS:
        np.testing.assert_allclose(
            getattr(batched, name), getattr(single, name), rtol=RTOL, atol=0, err_msg=name
        )
    assert (batched.divergences, batched.skipped) == (single.divergences, single.skipped)


@pytest.mark.parametrize("method", METHODS)
def test_batch_equals_single_flight_filters(flights, method):
    cfgs = _configs(method)
    batch = BatchFilterState.from_flights(cfgs, *zip(*flights, strict=True), store_states=True)
    assert list(batch.n) == [1500, 1200, 900]
    steps = np.array([7, 10, 13])  # uneven windows: flights end at different calls
    while np.any(batch.k < batch.n):
        batch.advance(batch.k + steps)
    assert list(batch.k) == [1500, 1200, 900]
    for i, (cfg, flight) in enumerate(zip(cfgs, flights, strict=True)):
        _assert_same(batch.result(i), run_filter(cfg, *flight))


def test_scaling_noise_and_divergence_restarts_match(flights):
    """The environment's path: Q and R rescaled between windows, one flight diverging."""
    cfg = FilterConfig(r_std_nt=20.0)
    singles = [FilterState(cfg, *f, store_states=False) for f in flights]
    batch = BatchFilterState(singles)
    s_q, s_r = np.array([1.1, 0.9, 1.0]), np.array([0.95, 1.05, 1.0])
    for w in range(60):
        if w == 20:
            batch.qd[1] = 1e300  # overflows on the next predict: a restart
            singles[1].qd[:] = 1e300
        batch.scale_noise(s_q, s_r)
        batch.advance(batch.k + 10)
        for i, s in enumerate(singles):
            s.scale_noise(s_q[i], s_r[i])
            s.advance(s.k + 10)
    assert list(batch.divergences) == [0, 1, 0]
    for i, s in enumerate(singles):
        _assert_same(batch.result(i), s.result())


def test_load_replaces_one_flight_and_grows_the_padding(flights):
    """An environment's reset: a longer flight with a longer window goes into slot 0."""
    short = [(y[:200], t[:200], td[:200]) for y, t, td in flights[:2]]
    cfg, wide = FilterConfig(r_std_nt=20.0), FilterConfig(r_std_nt=20.0, window=80)
    batch = BatchFilterState.from_flights(cfg, *zip(*short, strict=True))
    batch.advance(50)
    batch.load(0, FilterState(wide, *flights[0]))  # its state history: not kept by the batch
    assert list(batch.n) == [1500, 200] and list(batch.k) == [0, 50]
    batch.advance(10_000)  # each flight stops at its own end
    assert list(batch.k) == [1500, 200]
    _assert_same(batch.result(0), run_filter(wide, *flights[0], store_states=False))
    _assert_same(batch.result(1), run_filter(cfg, *short[1], store_states=False))


def test_filter_arrays_are_the_attributes_grouped(flights):
    """The NamedTuples the compiled loop takes hold the very arrays of the filter state, every
    array once; a flight's row of the stacked arrays views that flight's rows."""
    from aeromag_env.compensation.arrays import CORE_ARRAYS, GROUPS, row
    from aeromag_env.compensation.model import MODE, FilterMode

    assert {m: int(c) for m, c in MODE.items()} == {m: i for i, m in enumerate(METHODS)}
    assert set(MODE.values()) == set(FilterMode)
    assert len(set(CORE_ARRAYS)) == len(CORE_ARRAYS) == sum(len(g._fields) for g in GROUPS)
    state = FilterState(FilterConfig(), *flights[0])
    assert type(state.mode) is int
    grouped = state.arrays()
    for group in grouped:
        for name, array in zip(group._fields, group, strict=True):
            assert array is getattr(state, name)
    batch = BatchFilterState([state, FilterState(FilterConfig(method="ding"), *flights[2])])
    second = row(batch.arrays(), 1)
    second.state.z[0] = 5.0  # views: writing one writes the stacked array
    assert batch.z[1, 0] == 5.0 and batch.z[0, 0] == 0.0
    assert np.shares_memory(second.outputs.est, batch.est[1])
    np.testing.assert_array_equal(second.signals.y[: batch.n[1]], batch.y[1, : batch.n[1]])
