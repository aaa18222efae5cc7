"""The environment's running sums over its statistics windows, kept up to date in O(K) a step.

The observations over the filter's statistics window of M (:mod:`~aeromag_env.environment
.statistics`) read sums instead of looping over the window at every step. Two windows, their
sums in the environment's running values (:class:`aeromag_env.environment.layout.Run`):

* **the last M updates** (the filter's circular buffer ``rbuf``, which holds the innovations the
  window's ROR and QOQ are made of): ``Σ r`` and ``Σ |r|²`` (``win_r``, ``win_rr``), for the
  innovation bias and the two-window change statistic. The filter overwrites an update as it
  leaves, so before it advances the step takes out of the sums the oldest updates that the
  step's updates could push out (at most one per sample: :func:`take_leaving`), and afterwards
  puts back those that stayed and adds the new ones (:func:`put_updates`).
* **the last M samples** of the innovation history ``innov`` (its rows NaN where a sample was
  skipped): the finite rows, their ``Σ r``, ``Σ |r|²`` and ``Σ r_p · r_k`` over consecutive
  finite rows p < k both in the window (``white_*``), for the whiteness
  (:func:`slide_samples`).

Each is exact in exact arithmetic. In floating point a sum is summed afresh once per lap of
the window (so rounding cannot drift), after the filter restarted (the window may have been
emptied), and whenever a term leaving carried more than :data:`SUM_RATIO` times what is left:
the actions may swing R, and with it the innovations, by decades within a window, and
subtracting a huge term from a sum of small ones leaves only rounding error. The sums stay
within a few 1e-13 of the window's own, relative (tested against a plain numpy reference).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from aeromag_env.compensation.kernel_layout import INTS
from aeromag_env.environment.layout import RUN
from aeromag_env.numba_cache import njit

#: How the environment's helpers that run at every step are compiled: they neither allocate
#: nor copy arrays, so without numba's runtime (``_nrt=False``, an option numba's type stubs do
#: not list), as the filter's per-sample helpers (:data:`aeromag_env.compensation.kernels
#: .per_sample`): with the runtime every call pays two atomic operations per array passed, and
#: a writer of the observation is passed the ~35 arrays of the environment and the filter
#: (measured: the observation's ten writers and the sums' two calls cost 2–4 µs a step more
#: with the runtime, as much as the statistics). A helper that needed the runtime would fail
#: to compile, loudly; dropping the option changes the speed, not the results.
per_step = njit(cache=True, _nrt=False)  # type: ignore[call-overload]

#: A running sum is summed afresh when a term leaving it carried more than SUM_RATIO times what
#: is left (4 of 16 digits lost to the subtraction, at most). Clean runs rarely get there (the
#: innovations' squares within a window span less than 1e4 but after an interference step).
SUM_RATIO = 1e4


@njit(cache=True, inline="always")
def _wrapped(w: int, size: int) -> int:
    """``w mod size`` for ``0 ≤ w < 2 size`` (no integer division)."""
    return w - size if w >= size else w


@per_step
def _add_update(run: np.ndarray, rbuf: np.ndarray, w: int, sign: float) -> float:
    """Add (``sign`` 1) or take out (−1) the update in slot ``w`` of the window sums; its
    ``|r|²``."""
    rr = rbuf[w, 0] ** 2 + rbuf[w, 1] ** 2 + rbuf[w, 2] ** 2
    for i in range(3):
        run[RUN.win_r + i] += sign * rbuf[w, i]
    run[RUN.win_rr] += sign * rr
    return rr


@per_step
def update_sums(ints: np.ndarray, rbuf: np.ndarray, run: np.ndarray) -> None:
    """``Σ r`` and ``Σ |r|²`` over the updates in the window, afresh (oldest first)."""
    size, count = ints[INTS.window], ints[INTS.updates]
    for i in range(3):
        run[RUN.win_r + i] = 0.0
    run[RUN.win_rr] = 0.0
    w = _wrapped(ints[INTS.pos] - count + size, size)
    for _ in range(count):
        _add_update(run, rbuf, w, 1.0)
        w = _wrapped(w + 1, size)


class WindowMark(NamedTuple):
    """Where the filter's window of updates stood before a step's advance."""

    slot: int  #: the slot its next update goes to (``ints[INTS.pos]``)
    updates: int  #: the updates it held (``ints[INTS.updates]``)
    restarts: int  #: the filter's restarts so far (``ints[INTS.div]``)


class Taken(NamedTuple):
    """What :func:`take_leaving` took out of the window sums before a step's advance."""

    updates: int  #: the oldest updates taken out (−1: the step could turn the whole window over)
    largest_rr: float  #: the largest ``|r|²`` among them [nT²]


@per_step
def window_mark(ints: np.ndarray) -> WindowMark:
    """The :class:`WindowMark` of the filter's window now (its integers ``ints``)."""
    return WindowMark(ints[INTS.pos], ints[INTS.updates], ints[INTS.div])


@per_step
def take_leaving(samples: int, ints: np.ndarray, rbuf: np.ndarray, run: np.ndarray) -> Taken:
    """Before the filter advances over ``samples`` samples: take out of the window sums the
    oldest updates that the step's updates could push out of the window (at most one update a
    sample); what was taken (:class:`Taken`: their count, −1 when the step could turn the whole
    window over and the sums are summed afresh after it, and the largest ``|r|²``)."""
    size, count = ints[INTS.window], ints[INTS.updates]
    if samples >= size:
        return Taken(-1, 0.0)
    candidates = max(0, count + samples - size)  # ≤ samples, ≤ count
    largest, w = 0.0, _wrapped(ints[INTS.pos] - count + size, size)  # from the oldest update
    for _ in range(candidates):
        largest = max(largest, _add_update(run, rbuf, w, -1.0))
        w = _wrapped(w + 1, size)
    return Taken(candidates, largest)


@per_step
def put_updates(
    taken: Taken, before: WindowMark, ints: np.ndarray, rbuf: np.ndarray, run: np.ndarray
) -> None:
    """After the filter advanced from the window ``before``, ``taken`` what :func:`take_leaving`
    took out of the sums before: put back the updates that stayed in the window and add the new
    ones; or sum afresh after a lap of the window, a restart, or when one of the updates taken
    out carried more than :data:`SUM_RATIO` times what is left."""
    pos0, count0 = before.slot, before.updates
    size, pos = ints[INTS.window], ints[INTS.pos]
    added = _wrapped(pos - pos0 + size, size)  # fewer than size: the step has fewer samples
    if taken.updates < 0 or ints[INTS.div] != before.restarts or pos0 + added >= size:
        update_sums(ints, rbuf, run)
        return
    left = max(0, count0 + added - size)  # the oldest ones: their slots hold new updates now
    w = _wrapped(pos0 - count0 + size + left, size)
    for _ in range(left, taken.updates):
        _add_update(run, rbuf, w, 1.0)
        w = _wrapped(w + 1, size)
    w = pos0
    for _ in range(added):
        _add_update(run, rbuf, w, 1.0)
        w = _wrapped(w + 1, size)
    if taken.largest_rr > 0.0 and not run[RUN.win_rr] * SUM_RATIO >= taken.largest_rr:
        update_sums(ints, rbuf, run)


@njit(cache=True, inline="always")
def finite_row(x: np.ndarray, k: int) -> bool:
    """Row k of the (n, 3) array ``x`` is finite."""
    return np.isfinite(x[k, 0]) and np.isfinite(x[k, 1]) and np.isfinite(x[k, 2])


@per_step
def _dot(x: np.ndarray, a: int, b: int) -> float:
    return x[a, 0] * x[b, 0] + x[a, 1] * x[b, 1] + x[a, 2] * x[b, 2]


@per_step
def _add_sample(run: np.ndarray, innov: np.ndarray, k: int, sign: float) -> float:
    """Add (``sign`` 1) or take out (−1) the finite row k of ``innov`` from the row count and
    the sums of ``r`` and ``|r|²``; its ``|r|²``."""
    rr = _dot(innov, k, k)
    run[RUN.white_rows] += sign
    for i in range(3):
        run[RUN.white_r + i] += sign * innov[k, i]
    run[RUN.white_rr] += sign * rr
    return rr


@per_step
def sample_sums(lo: int, k1: int, innov: np.ndarray, run: np.ndarray) -> None:
    """The whiteness sums over the samples ``lo ≤ k < k1``, afresh."""
    run[RUN.white_rows] = 0.0
    for i in range(3):
        run[RUN.white_r + i] = 0.0
    run[RUN.white_rr] = 0.0
    run[RUN.white_link] = 0.0
    last = -1
    for k in range(lo, k1):
        if finite_row(innov, k):
            _add_sample(run, innov, k, 1.0)
            if last >= 0:
                run[RUN.white_link] += _dot(innov, last, k)
            last = k
    run[RUN.white_last] = last + 1


@per_step
def slide_samples(k0: int, k1: int, size: int, innov: np.ndarray, run: np.ndarray) -> None:
    """Move the whiteness sums from the samples ``max(0, k0 − size) ≤ k < k0`` to
    ``max(0, k1 − size) ≤ k < k1``: take out the rows that left (and the link from each to the
    next finite row), add the new ones (and the link from the last finite row, if it is still
    in the window); afresh once per lap of ``size`` samples, or when a row that left carried
    more than :data:`SUM_RATIO` times what is left."""
    lo0, lo1 = max(0, k0 - size), max(0, k1 - size)
    if k1 // size != k0 // size:  # a lap (every step with K ≥ size)
        sample_sums(lo1, k1, innov, run)
        return
    largest = 0.0
    for j in range(lo0, lo1):
        if finite_row(innov, j):
            largest = max(largest, _add_sample(run, innov, j, -1.0))
            nxt = j + 1
            while nxt < k0 and not finite_row(innov, nxt):
                nxt += 1
            if nxt < k0:
                run[RUN.white_link] -= _dot(innov, j, nxt)
    last = int(run[RUN.white_last]) - 1
    for k in range(k0, k1):
        if finite_row(innov, k):
            _add_sample(run, innov, k, 1.0)
            if last >= lo1:
                run[RUN.white_link] += _dot(innov, last, k)
            last = k
    run[RUN.white_last] = last + 1
    if largest > 0.0 and not run[RUN.white_rr] * SUM_RATIO >= largest:
        sample_sums(lo1, k1, innov, run)
