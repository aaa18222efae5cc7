"""Filter speed for ``aeromag bench``: the compiled loop, the batched loop and two references,
all on the same samples of the same flight.

* ``filter_compiled_samples_per_s`` — one flight through
:class:`~aeromag_env.compensation.kalman.FilterState`
  (the numba loop), plain KF.
* ``filter_batched_samples_per_s`` — :data:`BATCH` copies of that flight advanced together by
  :class:`~aeromag_env.compensation.kalman_batch.BatchFilterState` (all cores), total samples per
  second.
* ``filter_numpy_samples_per_s`` — :func:`aeromag_env.compensation.kalman_reference.run_reference`,
the
  plain-numpy transcription.
* ``filterpy_samples_per_s`` — ``filterpy.kalman.KalmanFilter`` doing the same 21-state predict
  and update (its own Joseph form; the tests check it gives our states).

Building the filter states is outside the timing; only the pass over the samples is timed.
The four alternate within each repeat, so that a slow minute of the host (these machines
drift) falls on all of them alike rather than on whichever ran then.
"""

from __future__ import annotations

import importlib.util
import statistics
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from aeromag_env.compensation.kalman import FilterState
from aeromag_env.compensation.kalman_batch import BatchFilterState
from aeromag_env.compensation.kalman_reference import run_reference
from aeromag_env.compensation.model import FilterConfig, measurement_rows
from aeromag_env.flight.data import Flight
from aeromag_env.simulation.interference import N_STATES

#: Flights advanced together for ``filter_batched_samples_per_s``.
BATCH = 64


def median_rates(
    cases: dict[str, tuple[Callable[[], Any], Callable[[Any], object], float]], repeats: int
) -> dict[str, float]:
    """For each named case ``(setup, run, count)``: the median of ``count / seconds`` of
    ``run(setup())`` over ``repeats`` runs (setup untimed), the cases alternating."""
    rates: dict[str, list[float]] = {name: [] for name in cases}
    for _ in range(repeats):
        for name, (setup, run, count) in cases.items():
            arg = setup()
            t0 = time.perf_counter()
            run(arg)
            rates[name].append(count / (time.perf_counter() - t0))
    return {name: statistics.median(r) for name, r in rates.items()}


def run_filterpy(cfg: FilterConfig, y: np.ndarray, t_b: np.ndarray, tdot_b: np.ndarray) -> None:
    """The plain KF of ``cfg`` with filterpy 2.0 (unscaled state, ``F = I``)."""
    from filterpy.kalman import KalmanFilter

    kf = KalmanFilter(dim_x=N_STATES, dim_z=3)
    kf.x = cfg.initial_state().reshape(N_STATES, 1)
    kf.P = cfg.initial_covariance()
    kf.Q = np.diag(cfg.process_noise())
    kf.R = cfg.measurement_noise()
    kf.F = np.eye(N_STATES)
    h_all = measurement_rows(t_b, tdot_b)
    for k in range(y.shape[0]):
        kf.predict()
        kf.update(y[k].reshape(3, 1), H=h_all[k])


def bench_filters(
    y: np.ndarray, t_b: np.ndarray, tdot_b: np.ndarray, repeats: int
) -> dict[str, float | None]:
    """Samples per second of the four filters on ``y``, ``t_b``, ``tdot_b`` (n, 3); filterpy's
    is None when filterpy (a ``dev`` extra) is not installed."""
    cfg, n = FilterConfig(), y.shape[0]
    flight = (cfg, y, t_b, tdot_b)
    FilterState(*flight).advance(n)  # warm: load the compiled loops
    BatchFilterState([FilterState(*flight)] * 2).advance(n)
    cases: dict[str, tuple[Callable[[], Any], Callable[[Any], object], float]] = {
        "filter_compiled_samples_per_s": (
            lambda: FilterState(*flight, store_states=False),
            lambda s: s.advance(n),
            n,
        ),
        "filter_batched_samples_per_s": (
            lambda: BatchFilterState([FilterState(*flight, store_states=False)] * BATCH),
            lambda b: b.advance(n),
            BATCH * n,
        ),
        "filter_numpy_samples_per_s": (lambda: None, lambda _: run_reference(*flight), n),
    }
    if importlib.util.find_spec("filterpy") is not None:
        cases["filterpy_samples_per_s"] = (lambda: None, lambda _: run_filterpy(*flight), n)
    figures: dict[str, float | None] = {"filterpy_samples_per_s": None}
    return figures | median_rates(cases, repeats)


def bench_filter_figures(flight: Flight, samples: int, repeats: int) -> dict[str, float | None]:
    """:func:`bench_filters` on the first ``samples`` samples of ``flight``'s fluxgate
    ``flux_a``."""
    from aeromag_env.compensation.compensate import earth_model

    t_b, tdot_b = earth_model(flight)
    y = flight.vector("flux_a") - t_b
    return bench_filters(y[:samples], t_b[:samples], tdot_b[:samples], repeats)
