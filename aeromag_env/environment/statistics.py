"""Statistics of the innovations and of the flight that the tuning environment observes.

Each is compiled and reads the filter's arrays in place (:mod:`aeromag_env.compensation.arrays`):
the innovations of the last samples (whiteness), the circular window of the last M updates
(recent ROR, innovation powers, the two-window change statistic, the innovation bias) and the
model field in body axes (the turn rate). :func:`aeromag_env.environment.kernels.env_step`
writes them into the observation (:mod:`aeromag_env.environment.observe`); their meaning is in
the registry :mod:`aeromag_env.environment.observations`.
"""

from __future__ import annotations

import math

import numpy as np

from aeromag_env.compensation.kernel_layout import INTS
from aeromag_env.numba_cache import njit


@njit(cache=True)
def _finite_row(x: np.ndarray, k: int) -> bool:
    return np.isfinite(x[k, 0]) and np.isfinite(x[k, 1]) and np.isfinite(x[k, 2])


@njit(cache=True)
def whiteness(k1: int, window: int, innov: np.ndarray) -> float:
    """Lag-1 autocorrelation of the innovations of the last ``window`` samples (finite rows,
    per-axis mean removed, pooled over axes); 0 with fewer than 3 rows or no variance."""
    lo = max(0, k1 - window)
    rows, mean0, mean1, mean2 = 0, 0.0, 0.0, 0.0
    for k in range(lo, k1):
        if _finite_row(innov, k):
            rows += 1
            mean0, mean1, mean2 = mean0 + innov[k, 0], mean1 + innov[k, 1], mean2 + innov[k, 2]
    if rows < 3:
        return 0.0
    if rows < k1 - lo:  # skipped samples in the window
        return whiteness_with_gaps(lo, k1, rows, innov)
    means = (mean0 / rows, mean1 / rows, mean2 / rows)
    num, den = 0.0, 0.0
    for i in range(3):  # the sums in the order of the loop with gaps: bitwise its result
        prev = innov[lo, i] - means[i]
        den += prev * prev
        for k in range(lo + 1, k1):
            c = innov[k, i] - means[i]
            den += c * c
            num += c * prev
            prev = c
    return num / den if den > 0.0 else 0.0


@njit(cache=True)
def whiteness_with_gaps(lo: int, k1: int, rows: int, innov: np.ndarray) -> float:
    """:func:`whiteness` over samples ``lo ≤ k < k1`` of which ``rows`` are finite rows."""
    num, den = 0.0, 0.0
    for i in range(3):
        mean = 0.0
        for k in range(lo, k1):
            if _finite_row(innov, k):
                mean += innov[k, i]
        mean /= rows
        prev, first = 0.0, True
        for k in range(lo, k1):
            if _finite_row(innov, k):
                c = innov[k, i] - mean
                den += c * c
                if not first:
                    num += c * prev
                prev, first = c, False
    return num / den if den > 0.0 else 0.0


@njit(cache=True, inline="always")
def _previous(w: int, size: int) -> int:
    """The slot before ``w`` in a circular buffer of ``size`` slots: ``(w − 1) mod size``
    without an integer division (these loops run over the window at every step)."""
    return w - 1 if w > 0 else size - 1


@njit(cache=True)
def recent_ratio(m: int, ints: np.ndarray, rbuf: np.ndarray, sbuf: np.ndarray) -> float:
    """ROR over the last ``m`` updates only: ``Σ|r|² / Σ tr S`` (NaN before any update)."""
    m = min(m, ints[INTS.updates])
    num, den, w = 0.0, 0.0, ints[INTS.pos]
    for _ in range(m):  # newest first
        w = _previous(w, ints[INTS.window])
        num += rbuf[w, 0] ** 2 + rbuf[w, 1] ** 2 + rbuf[w, 2] ** 2
        den += sbuf[w]
    return num / den if den > 0.0 else np.nan


@njit(cache=True)
def recent_power(m: int, ints: np.ndarray, rbuf: np.ndarray) -> tuple[float, float]:
    """Over the last ``m`` updates: the mean innovation power ``mean |r|²`` and the power of
    the mean innovation ``|mean r|²`` [nT²] (NaN before any update). Noise averages out of the
    second, a step does not."""
    m = min(m, ints[INTS.updates])
    if m == 0:
        return np.nan, np.nan
    power, s0, s1, s2, w = 0.0, 0.0, 0.0, 0.0, ints[INTS.pos]
    for _ in range(m):  # newest first
        w = _previous(w, ints[INTS.window])
        power += rbuf[w, 0] ** 2 + rbuf[w, 1] ** 2 + rbuf[w, 2] ** 2
        s0, s1, s2 = s0 + rbuf[w, 0], s1 + rbuf[w, 1], s2 + rbuf[w, 2]
    return power / m, (s0 * s0 + s1 * s1 + s2 * s2) / (m * m)


@njit(cache=True)
def step_statistic(m: int, ints: np.ndarray, rbuf: np.ndarray) -> float:
    """Two-window change statistic ``m |mean₁ r − mean₀ r|² / tr C₀``: the mean innovation of
    the last ``m`` updates against that of the earlier updates in the statistics window, over
    the earlier ones' innovation covariance trace. About 1 + m/(M − m) without a change,
    whatever the noise level or R; an interference step raises it by m |step|² / tr C₀. NaN
    with fewer than 3 earlier updates. (Per axis in scalars, newest first: no allocation.)"""
    count = ints[INTS.updates]
    m = min(m, count)
    earlier = count - m
    if m < 1 or earlier < 3:
        return np.nan
    size = ints[INTS.window]
    recent0, recent1, recent2, before0, before1, before2 = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    w = ints[INTS.pos]
    for j in range(count):
        w = _previous(w, size)
        if j < m:
            recent0 += rbuf[w, 0]
            recent1 += rbuf[w, 1]
            recent2 += rbuf[w, 2]
        else:
            before0 += rbuf[w, 0]
            before1 += rbuf[w, 1]
            before2 += rbuf[w, 2]
    recent0, recent1, recent2 = recent0 / m, recent1 / m, recent2 / m
    before0, before1, before2 = before0 / earlier, before1 / earlier, before2 / earlier
    sq0, sq1, sq2 = 0.0, 0.0, 0.0
    w = (ints[INTS.pos] - m) % size  # the earlier updates, newest first
    for _ in range(m, count):
        w = _previous(w, size)
        sq0 += (rbuf[w, 0] - before0) ** 2
        sq1 += (rbuf[w, 1] - before1) ** 2
        sq2 += (rbuf[w, 2] - before2) ** 2
    tr_c = (sq0 + sq1 + sq2) / (earlier - 1)
    if not tr_c > 0.0:
        return np.nan
    change = (recent0 - before0) ** 2 + (recent1 - before1) ** 2 + (recent2 - before2) ** 2
    return m * change / tr_c


@njit(cache=True)
def log10_or_zero(v: float) -> float:
    return math.log10(v) if v > 0.0 and np.isfinite(v) else 0.0


@njit(cache=True)
def turn_rate(k0: int, k1: int, t: np.ndarray, td: np.ndarray, valid: np.ndarray) -> float:
    """RMS of ``|Ṫ| / |T|`` over the samples ``k0 ≤ k < k1`` with valid inputs [rad/s]: the rate
    at which the Earth field turns in body axes, i.e. the aircraft's angular rate across the
    field (``Ṫ = −ω × T`` in level flight over a uniform field), from the attitude the filter
    already reads. 0 without such a sample."""
    total, rows = 0.0, 0
    for k in range(k0, k1):
        norm2 = t[k, 0] ** 2 + t[k, 1] ** 2 + t[k, 2] ** 2
        if valid[k] and norm2 > 0.0:
            total += (td[k, 0] ** 2 + td[k, 1] ** 2 + td[k, 2] ** 2) / norm2
            rows += 1
    return math.sqrt(total / rows) if rows > 0 else 0.0


@njit(cache=True)
def innovation_bias(ints: np.ndarray, rbuf: np.ndarray) -> float:
    """Bias statistic ``M |mean r|² / tr C`` over the ``M`` updates of the statistics window:
    the mean innovation against zero, over the innovations' covariance trace. About 1 for a
    consistent filter (zero-mean innovations) at any noise level or R; a step the filter has not
    absorbed keeps it high for as long as the bias stays, where the two-window statistic falls
    once the step fills the window. NaN with fewer than 3 updates."""
    count, size = ints[INTS.updates], ints[INTS.window]
    if count < 3:
        return np.nan
    s0, s1, s2, w = 0.0, 0.0, 0.0, ints[INTS.pos]
    for _ in range(count):
        w = _previous(w, size)
        s0, s1, s2 = s0 + rbuf[w, 0], s1 + rbuf[w, 1], s2 + rbuf[w, 2]
    m0, m1, m2 = s0 / count, s1 / count, s2 / count
    sq, w = 0.0, ints[INTS.pos]
    for _ in range(count):
        w = _previous(w, size)
        sq += (rbuf[w, 0] - m0) ** 2 + (rbuf[w, 1] - m1) ** 2 + (rbuf[w, 2] - m2) ** 2
    tr_c = sq / (count - 1)
    if not tr_c > 0.0:
        return np.nan
    return count * (m0 * m0 + m1 * m1 + m2 * m2) / tr_c
