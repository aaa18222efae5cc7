"""Statistics of the innovations and of the flight that the tuning environment observes.

Each is compiled and reads the filter's arrays in place (:mod:`aeromag_env.compensation.arrays`):
the innovations of the last samples (whiteness), the circular window of the last M updates
(recent ROR, innovation powers, the two-window change statistic, the innovation bias) and the
model field in body axes (the turn rate). :func:`aeromag_env.environment.kernels.env_step`
writes them into the observation (:mod:`aeromag_env.environment.observe`); their meaning is in
the registry :mod:`aeromag_env.environment.observations`.

The statistics over the whole window of M read running sums (the ``*_running`` functions and
:func:`window_power`: O(1) a step, the sums kept by :mod:`aeromag_env.environment.window_sums`
and the filter's window); those over the last ``recent`` updates or the decision window loop over
them (O(K) a step). A centred sum ``Σ |r − mean|²`` taken from running sums as
``Σ |r|² − n |mean|²`` loses the digits of the mean; when it would lose more than
:data:`CENTRED_RATIO` of them, the statistic is computed afresh by the two-pass loop
(:func:`whiteness`, :func:`step_statistic`, :func:`innovation_bias`), which is also the
definition the running forms are tested against.
"""

from __future__ import annotations

import math

import numpy as np

from aeromag_env.compensation.kernel_layout import ACC, INTS
from aeromag_env.environment.layout import RUN
from aeromag_env.environment.window_sums import finite_row as _finite_row
from aeromag_env.environment.window_sums import per_step
from aeromag_env.numba_cache import njit

#: A centred sum ``Σ |r|² − n |mean|²`` is taken from the running sums when ``Σ |r|²`` is at
#: most CENTRED_RATIO times the result (at most 4 of 16 digits lost: with the running sums'
#: own error, 1e-8 relative at the worst, below the float32 observation's 6e-8); otherwise
#: the statistic is computed afresh. Clean runs get there only while an interference step
#: holds the innovations' mean beyond 100 times their spread.
CENTRED_RATIO = 1e4


@per_step
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


@per_step
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


@per_step
def recent_ratio(m: int, ints: np.ndarray, rbuf: np.ndarray, sbuf: np.ndarray) -> float:
    """ROR over the last ``m`` updates only: ``Σ|r|² / Σ tr S`` (NaN before any update)."""
    m = min(m, ints[INTS.updates])
    num, den, w = 0.0, 0.0, ints[INTS.pos]
    for _ in range(m):  # newest first
        w = _previous(w, ints[INTS.window])
        num += rbuf[w, 0] ** 2 + rbuf[w, 1] ** 2 + rbuf[w, 2] ** 2
        den += sbuf[w]
    return num / den if den > 0.0 else np.nan


@per_step
def window_power(ints: np.ndarray, acc: np.ndarray) -> float:
    """The mean innovation power ``mean |r|²`` over the updates in the window [nT²] (NaN
    before any update), from the filter's running sum of ``|r|²`` (``acc[ACC.rr]``)."""
    count = ints[INTS.updates]
    return acc[ACC.rr] / count if count > 0 else np.nan


@per_step
def power_of_mean(m: int, ints: np.ndarray, rbuf: np.ndarray) -> float:
    """The power of the mean innovation ``|mean r|²`` over the last ``m`` updates [nT²] (NaN
    before any update): noise averages out of it, a step does not."""
    m = min(m, ints[INTS.updates])
    if m == 0:
        return np.nan
    s0, s1, s2, w = 0.0, 0.0, 0.0, ints[INTS.pos]
    for _ in range(m):  # newest first
        w = _previous(w, ints[INTS.window])
        s0, s1, s2 = s0 + rbuf[w, 0], s1 + rbuf[w, 1], s2 + rbuf[w, 2]
    return (s0 * s0 + s1 * s1 + s2 * s2) / (m * m)


@per_step
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


@per_step
def log10_or_zero(v: float) -> float:
    return math.log10(v) if v > 0.0 and np.isfinite(v) else 0.0


@per_step
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


@per_step
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


@per_step
def _centred(total: float, square_of_sum: float, count: float) -> float:
    """``Σ |r|² − |Σ r|² / n`` from ``total = Σ |r|²``, ``square_of_sum = |Σ r|²`` and
    ``count = n``; NaN when that would lose more than :data:`CENTRED_RATIO` of the digits (or is
    not positive): the caller then computes afresh."""
    centred = total - square_of_sum / count
    return centred if centred * CENTRED_RATIO >= total and centred > 0.0 else np.nan


@per_step
def whiteness_running(k1: int, window: int, innov: np.ndarray, run: np.ndarray) -> float:
    """:func:`whiteness` from the running sums over the samples ``max(0, k1 − window) ≤ k < k1``
    (:func:`aeromag_env.environment.window_sums.slide_samples`): with ``c = r − mean``, the sum
    of ``c_p · c_k`` over consecutive finite rows is ``Σ r_p · r_k − mean · (2 Σ r − r_first −
    r_last) + (rows − 1) |mean|²`` and that of ``|c|²`` is ``Σ |r|² − rows |mean|²``."""
    rows = run[RUN.white_rows]
    if rows < 3:
        return 0.0
    s0, s1, s2 = run[RUN.white_r], run[RUN.white_r + 1], run[RUN.white_r + 2]
    square_of_sum = s0 * s0 + s1 * s1 + s2 * s2
    den = _centred(run[RUN.white_rr], square_of_sum, rows)
    if not den > 0.0:  # NaN: too many digits lost
        return whiteness(k1, window, innov)
    first, last = max(0, k1 - window), k1 - 1
    while not _finite_row(innov, first):
        first += 1
    while not _finite_row(innov, last):
        last -= 1
    ends = 0.0  # mean · (2 Σ r − r_first − r_last), times rows
    for i in range(3):
        s = run[RUN.white_r + i]
        ends += s * (2.0 * s - innov[first, i] - innov[last, i])
    num = run[RUN.white_link] - ends / rows + (rows - 1.0) * square_of_sum / (rows * rows)
    return num / den


@per_step
def innovation_bias_running(ints: np.ndarray, rbuf: np.ndarray, run: np.ndarray) -> float:
    """:func:`innovation_bias` from the running sums of ``r`` and ``|r|²`` over the window
    (:func:`aeromag_env.environment.window_sums.put_updates`)."""
    count = ints[INTS.updates]
    if count < 3:
        return np.nan
    s0, s1, s2 = run[RUN.win_r], run[RUN.win_r + 1], run[RUN.win_r + 2]
    square_of_sum = s0 * s0 + s1 * s1 + s2 * s2
    sq = _centred(run[RUN.win_rr], square_of_sum, count)
    if not sq > 0.0:
        return innovation_bias(ints, rbuf)
    return square_of_sum / count / (sq / (count - 1))


@per_step
def step_statistic_running(m: int, ints: np.ndarray, rbuf: np.ndarray, run: np.ndarray) -> float:
    """:func:`step_statistic` with the earlier updates' sums taken as the window's running sums
    minus those of the last ``m`` updates (summed here: O(m))."""
    count = ints[INTS.updates]
    m = min(m, count)
    earlier = count - m
    if m < 1 or earlier < 3:
        return np.nan
    size, w = ints[INTS.window], ints[INTS.pos]
    recent0, recent1, recent2, recent_rr = 0.0, 0.0, 0.0, 0.0
    for _ in range(m):  # newest first
        w = _previous(w, size)
        recent0, recent1, recent2 = recent0 + rbuf[w, 0], recent1 + rbuf[w, 1], recent2 + rbuf[w, 2]
        recent_rr += rbuf[w, 0] ** 2 + rbuf[w, 1] ** 2 + rbuf[w, 2] ** 2
    before0 = run[RUN.win_r] - recent0
    before1 = run[RUN.win_r + 1] - recent1
    before2 = run[RUN.win_r + 2] - recent2
    square_of_sum = before0 * before0 + before1 * before1 + before2 * before2
    sq = _centred(run[RUN.win_rr] - recent_rr, square_of_sum, earlier)
    if not (sq > 0.0 and run[RUN.win_rr] <= CENTRED_RATIO * sq):
        return step_statistic(m, ints, rbuf)
    tr_c = sq / (earlier - 1)
    change = (
        (recent0 / m - before0 / earlier) ** 2
        + (recent1 / m - before1 / earlier) ** 2
        + (recent2 / m - before2 / earlier) ** 2
    )
    return m * change / tr_c
