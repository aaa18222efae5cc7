"""What each recursive compensator costs per sample, against the plain KF on the same flight.

:func:`filter_costs` times the compiled loop (:func:`aeromag_env.compensation.kernels.advance`)
of every method asked for on one flight, side by side: each repeat runs every method once, in
turn, so that a load on the machine falls on all of them alike, and the figure is the median
over the repeats. The ratios to ``kf`` are what carries over between machines.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from aeromag_env.compensation.kalman import FilterState
from aeromag_env.compensation.model import FilterConfig
from aeromag_env.errors import AeromagError

#: The methods timed by default: the plain KF first (the reference of the ratios), then the
#: classical adaptive filters and the variational and multiple-model ones.
COST_METHODS = ("kf", "sage-husa", "ding", "fakf", "vbakf", "vbakf-pr", "imm")


@dataclass(frozen=True)
class FilterCost:
    """One method's cost on one flight.

    Attributes
    ----------
    method : str
    seconds_per_sample : median over the repeats of the compiled loop's time per sample [s]
    ratio_to_kf : ``seconds_per_sample`` over the plain KF's, from the same repeats [-]
    repeats : int
    """

    method: str
    seconds_per_sample: float
    ratio_to_kf: float
    repeats: int


def filter_costs(
    y: np.ndarray,
    t_b: np.ndarray,
    tdot_b: np.ndarray,
    methods: Sequence[str] = COST_METHODS,
    repeats: int = 7,
    window: int | None = None,
    cfg: FilterConfig | None = None,
) -> dict[str, FilterCost]:
    """The compiled cost per sample of each of ``methods`` on one flight, side by side.

    Parameters
    ----------
    y, t_b, tdot_b : ndarray, shape (n, 3)
        The flight's ``T_m − T`` [nT], model field [nT] and its rate [nT/s].
    methods : the methods to time (``kf`` is added first when missing: the ratios' reference).
    repeats : runs of every method (≥ 1); the medians are reported.
    window : samples per call of the loop (a tuning environment's decision window), or None
        for the whole flight in one call.
    cfg : the settings (its ``method`` replaced by each one), default :class:`FilterConfig`.

    Returns
    -------
    dict of method → FilterCost, ``kf`` first.

    Notes
    -----
    Each method is compiled and run once before the timing; the filter's arrays are built
    outside the timed part, which is the loop alone.
    """
    if repeats < 1:
        raise AeromagError(f"filter_costs: repeats must be ≥ 1, got {repeats}")
    if window is not None and window < 1:
        raise AeromagError(f"filter_costs: window must be ≥ 1 samples or None, got {window}")
    order = ["kf", *[m for m in dict.fromkeys(methods) if m != "kf"]]
    base = cfg or FilterConfig()
    configs = {m: replace(base, method=m) for m in order}
    for c in configs.values():
        _time_once(c, y[:50], t_b[:50], tdot_b[:50], window)  # compile outside the timing
    times: dict[str, list[float]] = {m: [] for m in order}
    for _ in range(repeats):
        for method, c in configs.items():
            times[method].append(_time_once(c, y, t_b, tdot_b, window) / y.shape[0])
    kf = np.asarray(times["kf"])
    return {
        m: FilterCost(
            method=m,
            seconds_per_sample=float(np.median(t)),
            ratio_to_kf=float(np.median(np.asarray(t) / kf)),
            repeats=repeats,
        )
        for m, t in times.items()
    }


def _time_once(
    cfg: FilterConfig, y: np.ndarray, t_b: np.ndarray, tdot_b: np.ndarray, window: int | None
) -> float:
    """Seconds the compiled loop takes over the flight (in calls of ``window`` samples)."""
    state = FilterState(cfg, y, t_b, tdot_b, store_states=False)
    stops = [state.n] if window is None else [*range(window, state.n, window), state.n]
    t0 = time.perf_counter()
    for k1 in stops:
        state.advance(k1)
    return time.perf_counter() - t0
