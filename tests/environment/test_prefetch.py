import numpy as np

from aeromag_env.environment.prefetch import FlightKey, FlightPrefetcher, simulate
from aeromag_env.environment.vec_env import AeroMagCompensationVecEnv
from tests._helpers import observations


def _same(a, b):
    for x, y in zip(a, b, strict=True):
        if isinstance(x, dict):
            assert x.keys() == y.keys()
            for key in x:
                np.testing.assert_array_equal(x[key], y[key], err_msg=key)
        else:
            np.testing.assert_array_equal(x, y)


def test_prefetched_flights_are_the_flights_a_reset_simulates():
    """Over three autoresets, and after a reseeding reset that discards a prepared flight."""
    kw = {"scenario": "misspecified", "duration_s": 10.0, "observations": observations()}
    ahead, here = (
        AeroMagCompensationVecEnv(2, prefetch=True, **kw),
        AeroMagCompensationVecEnv(2, **kw),
    )
    _same(ahead.reset(seed=3), here.reset(seed=3))
    actions = np.full((2, 2), 0.5)
    for k in range(35):
        if k == 15:  # environment 1 reseeded: its prepared flight is not the one wanted
            mask = {"reset_mask": np.array([False, True])}
            _same(
                ahead.reset(seed=[None, 99], options=dict(mask)),
                here.reset(seed=[None, 99], options=dict(mask)),
            )
        _same(ahead.step(actions), here.step(actions))
    ahead.close()


def test_a_stopped_worker_falls_back_to_simulating_here():
    prefetcher = FlightPrefetcher()
    key = FlightKey("nominal", 5, 5.0)
    prefetcher.expect(0, key)
    prefetcher.close()
    prefetcher.expect(1, key)  # the worker is gone
    for slot in (0, 1):
        got, want = prefetcher.take(slot, key), simulate(key)
        np.testing.assert_array_equal(got.y, want.y)
        assert got.filter_cfg == want.filter_cfg


def test_a_flight_the_worker_has_delivered_is_taken_from_it(monkeypatch):
    """A ready flight comes from the worker (here: simulating would fail), and equals the flight
    simulated here."""
    from aeromag_env.environment import prefetch

    want = simulate(FlightKey("nominal", 5, 5.0))
    prefetcher = FlightPrefetcher()
    key = FlightKey("nominal", 5, 5.0)
    prefetcher.expect(0, key)
    # the worker's answer, however long it takes: the worker runs at a lower priority, and on
    # two busy cores a time limit here (120 s) ran out by chance; a worker that dies resolves
    # the future with an error, so the wait cannot outlive it
    prefetcher._pending[0][1].result()

    def no_simulation(key):
        raise AssertionError("simulated here, not taken from the worker")

    monkeypatch.setattr(prefetch, "simulate", no_simulation)
    got = prefetcher.take(0, key)
    np.testing.assert_array_equal(got.y, want.y)
    np.testing.assert_array_equal(got.truth_interf, want.truth_interf)
    prefetcher.close()
