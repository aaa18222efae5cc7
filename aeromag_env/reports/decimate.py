"""Decimation for display: the samples a plot needs to look like the whole series.

A screen shows a long series in a few thousand pixel columns; per column it draws a vertical
stroke from the column's lowest to its highest value. :func:`extreme_indices` keeps, per
column, the sample of the lowest and of the highest value (and the first non-finite one, so a
line still breaks at a gap), which draws the same picture from at most ~3 samples per column:
a single-sample spike is the extreme of its column and is never dropped. numpy only.
"""

from __future__ import annotations

import numpy as np

#: Pixel columns a decimated series keeps: more than a laptop screen is wide.
COLUMNS = 2000


def extreme_indices(y: np.ndarray, columns: int = COLUMNS) -> np.ndarray:
    """Indices of the samples to draw ``y`` with ``columns`` pixel columns, in order.

    Parameters
    ----------
    y : (n,) float
        The series (NaN allowed: a gap).
    columns : int
        Columns of equal sample count; series of at most ``2 * columns`` samples are kept whole.

    Returns
    -------
    (m,) int
        Sorted indices into ``y``: per column, its minimum, its maximum and its first
        non-finite sample (when it has one); m ≤ 3 · columns.
    """
    y = np.asarray(y, dtype=float)
    n = y.size
    if n <= 2 * columns:
        return np.arange(n)
    width = -(-n // columns)  # samples per column, the last one padded
    rows = -(-n // width)
    pad = np.full(rows * width, np.nan)
    pad[:n] = y
    grid = pad.reshape(rows, width)
    finite = np.isfinite(grid)
    base = np.arange(rows) * width
    lo = np.argmin(np.where(finite, grid, np.inf), axis=1) + base
    hi = np.argmax(np.where(finite, grid, -np.inf), axis=1) + base
    has = finite.any(axis=1)
    real = np.arange(rows * width).reshape(rows, width) < n  # not padding
    gap = ~finite & real
    first_gap = np.argmax(gap, axis=1) + base
    keep = np.concatenate([lo[has], hi[has], first_gap[gap.any(axis=1)]])
    return np.unique(keep)


def extreme_indices_many(series: list[np.ndarray], columns: int = COLUMNS) -> np.ndarray:
    """The union of :func:`extreme_indices` over several series of the same length (one x
    for all of them: each keeps its own extremes)."""
    if not series:
        return np.arange(0)
    return np.unique(np.concatenate([extreme_indices(y, columns) for y in series]))


def time_gaps(tt: np.ndarray, factor: float = 3.0) -> np.ndarray:
    """Indices ``k`` where the time step ``tt[k+1] − tt[k]`` exceeds ``factor`` times the
    median step (a gap in the recording) [s]."""
    tt = np.asarray(tt, dtype=float)
    if tt.size < 3:
        return np.arange(0)
    dt = np.diff(tt)
    return np.flatnonzero(dt > factor * np.median(dt))


def with_breaks(
    x: np.ndarray, ys: list[np.ndarray], idx: np.ndarray, gaps: np.ndarray
) -> tuple[np.ndarray, list[np.ndarray]]:
    """The decimated samples ``idx`` of ``x`` and every ``ys``, with a NaN inserted after each
    gap index in ``gaps`` so that a drawn line breaks there instead of bridging the gap.

    Parameters
    ----------
    x : (n,) float
    ys : list of (n,) float
    idx : (m,) int, sorted, from :func:`extreme_indices`
    gaps : (g,) int, the last sample before each gap (:func:`time_gaps`)

    Returns
    -------
    x, ys : (m + g',) float each, g' the gaps inside the kept span
    """
    keep = np.union1d(idx, gaps).astype(int)
    xs = np.asarray(x, dtype=float)[keep]
    out = [np.asarray(y, dtype=float)[keep] for y in ys]
    if gaps.size:
        where = np.searchsorted(keep, gaps) + 1  # after the gap's last sample
        xs = np.insert(xs, where, np.asarray(x, dtype=float)[gaps])
        out = [np.insert(y, where, np.nan) for y in out]
    return xs, out


def runs(tt: np.ndarray, mask: np.ndarray) -> list[tuple[float, float]]:
    """The runs of ``mask`` (n,) as time windows ``(t_first, t_last)`` [s] of ``tt`` (n,)."""
    if not mask.any():
        return []
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return [(float(tt[a]), float(tt[b - 1])) for a, b in zip(edges[::2], edges[1::2], strict=True)]
