"""Plain-numpy reference of the innovation statistics the tuning environment observes.

Each function computes one statistic of :mod:`aeromag_env.environment.statistics` from its
definition, afresh and in two passes (the mean first, then the centred sums), from the filter's
arrays as :class:`~aeromag_env.compensation.kalman.FilterState` holds them: the innovation
history ``innov`` (n, 3) [nT] (NaN rows where a sample was skipped) and the circular window of
the last M updates (``rbuf`` (M, 3) [nT], ``sbuf`` (M,) [nT²], counters ``ints``). The
compiled statistics, which read running sums, are tested against it; nothing else uses it.
"""

from __future__ import annotations

import numpy as np

from aeromag_env.compensation.kernel_layout import INTS


def window_updates(ints: np.ndarray, buffer: np.ndarray) -> np.ndarray:
    """The entries of the circular ``buffer`` (M, ...) that are in the window, oldest first."""
    size, count, pos = int(ints[INTS.window]), int(ints[INTS.updates]), int(ints[INTS.pos])
    return buffer[(pos - count + np.arange(count)) % size]


def whiteness(innov: np.ndarray, k1: int, window: int) -> float:
    """Lag-1 autocorrelation of the finite rows among the samples ``max(0, k1 − window) ≤ k <
    k1``, each axis's mean removed, pooled over axes (consecutive finite rows are neighbours);
    0 with fewer than 3 rows or no variance."""
    rows = innov[max(0, k1 - window) : k1]
    rows = rows[np.all(np.isfinite(rows), axis=1)]
    if len(rows) < 3:
        return 0.0
    c = rows - rows.mean(axis=0)
    den = float(np.sum(c * c))
    return float(np.sum(c[1:] * c[:-1])) / den if den > 0.0 else 0.0


def window_power(ints: np.ndarray, rbuf: np.ndarray) -> float:
    """Mean innovation power ``mean |r|²`` over the window's updates [nT²] (NaN: none)."""
    r = window_updates(ints, rbuf)
    return float(np.mean(np.sum(r * r, axis=1))) if len(r) else np.nan


def power_of_mean(ints: np.ndarray, rbuf: np.ndarray, m: int) -> float:
    """``|mean r|²`` over the last ``m`` updates [nT²] (NaN: none)."""
    r = window_updates(ints, rbuf)[-m:]
    return float(np.sum(r.mean(axis=0) ** 2)) if len(r) else np.nan


def recent_ratio(ints: np.ndarray, rbuf: np.ndarray, sbuf: np.ndarray, m: int) -> float:
    """ROR over the last ``m`` updates: ``Σ |r|² / Σ tr S`` (NaN: none, or no ``tr S``)."""
    r, s = window_updates(ints, rbuf)[-m:], window_updates(ints, sbuf)[-m:]
    den = float(np.sum(s))
    return float(np.sum(r * r)) / den if len(r) and den > 0.0 else np.nan


def step_statistic(ints: np.ndarray, rbuf: np.ndarray, m: int) -> float:
    """``m |mean₁ r − mean₀ r|² / tr C₀``: the last ``m`` updates' mean against the earlier
    updates' (at least 3), over the earlier ones' covariance trace (NaN otherwise)."""
    r = window_updates(ints, rbuf)
    m = min(m, len(r))
    recent, before = r[len(r) - m :], r[: len(r) - m]
    if m < 1 or len(before) < 3:
        return np.nan
    tr_c = float(np.sum(before.var(axis=0, ddof=1)))
    change = float(np.sum((recent.mean(axis=0) - before.mean(axis=0)) ** 2))
    return m * change / tr_c if tr_c > 0.0 else np.nan


def innovation_bias(ints: np.ndarray, rbuf: np.ndarray) -> float:
    """``M |mean r|² / tr C`` over the window's updates (at least 3; NaN otherwise)."""
    r = window_updates(ints, rbuf)
    if len(r) < 3:
        return np.nan
    tr_c = float(np.sum(r.var(axis=0, ddof=1)))
    return len(r) * float(np.sum(r.mean(axis=0) ** 2)) / tr_c if tr_c > 0.0 else np.nan
