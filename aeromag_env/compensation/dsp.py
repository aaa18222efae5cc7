"""Zero-phase Butterworth filters for flight series (MagNav.jl ``get_bpf`` / ``bpf_data`` style).

Every filter here runs forward and backward (``scipy.signal.sosfiltfilt``), so there is no phase
shift and the amplitude gain is the square of one pass's: ``|H(f)|² = 1 / (1 + (f / f_c)^(2 n))``
for an order-``n`` low-pass (``f / f_c`` bilinear-warped: ``tan(π f / fs) / tan(π f_c / fs)``).

Conventions shared with MagNav.jl:

* ``low_hz <= 0`` → low-pass only; ``high_hz >= fs / 2`` → high-pass only; both → no filtering
  (a copy of the input is returned);
* columns that are constant (a bias column, an unused channel) are returned unchanged.

Filters cannot skip gaps. :func:`bandpass` rejects non-finite samples (the caller decides whether
to fill, cut or skip them); :func:`bandpass_finite` filters each contiguous finite run of a series
on its own and leaves the gaps as NaN; given the flight's continuous segments, it never filters
across a time gap either.
"""

from __future__ import annotations

import math

import numpy as np

from aeromag_env.errors import AeromagError


def bandpass(
    x: np.ndarray, fs_hz: float, low_hz: float, high_hz: float, order: int = 4
) -> np.ndarray:
    """Zero-phase Butterworth band-pass along axis 0.

    Parameters
    ----------
    x : ndarray, shape (n,) or (n, m)
        Series, time first [any unit].
    fs_hz : float
        Sample rate [Hz].
    low_hz, high_hz : float
        Pass band edges [Hz]. ``low_hz <= 0`` gives a low-pass at ``high_hz``; ``high_hz >= fs/2``
        gives a high-pass at ``low_hz``; both give no filtering.
    order : int
        Butterworth order of one pass (MagNav's ``pole``); zero-phase doubles the dB attenuation.

    Returns
    -------
    ndarray, same shape as ``x``
        Filtered copy; constant columns are copied unchanged. Raises :class:`AeromagError` on
        non-finite samples (fill, cut, or use :func:`bandpass_finite`), on a series shorter
        than the filter's padding needs (the message names the minimum) and on invalid edges.
    """
    x = np.array(x, dtype=float)  # a copy: the result never aliases the input
    sos = _design(fs_hz, low_hz, high_hz, order)
    if x.ndim not in (1, 2):
        raise AeromagError(f"bandpass expects a (n,) or (n, m) array, got shape {x.shape}")
    if sos is None:
        return x
    _check_filterable(x, sos)
    cols = x.reshape(x.shape[0], -1)
    varying = ~_constant_columns(cols)
    if np.any(varying):
        from scipy.signal import sosfiltfilt  # lazy: keeps `import aeromag_env` light

        cols[:, varying] = sosfiltfilt(sos, cols[:, varying], axis=0)
    return cols.reshape(x.shape)


def highpass(x: np.ndarray, fs_hz: float, cutoff_hz: float, order: int = 4) -> np.ndarray:
    """Zero-phase Butterworth high-pass, 0 < ``cutoff_hz`` < fs/2 [Hz] (see :func:`bandpass`)."""
    check_cutoff(fs_hz, cutoff_hz)
    return bandpass(x, fs_hz, cutoff_hz, fs_hz / 2.0, order)


def lowpass(x: np.ndarray, fs_hz: float, cutoff_hz: float, order: int = 4) -> np.ndarray:
    """Zero-phase Butterworth low-pass, 0 < ``cutoff_hz`` < fs/2 [Hz] (see :func:`bandpass`)."""
    check_cutoff(fs_hz, cutoff_hz)
    return bandpass(x, fs_hz, 0.0, cutoff_hz, order)


def bandpass_finite(
    x: np.ndarray,
    fs_hz: float,
    low_hz: float,
    high_hz: float,
    order: int = 4,
    segments: list[slice] | None = None,
) -> np.ndarray:
    """:func:`bandpass` applied to each contiguous run of finite samples of a 1-D series.

    Parameters
    ----------
    x : ndarray, shape (n,)
    fs_hz, low_hz, high_hz, order
        As in :func:`bandpass`.
    segments : list of slice, optional
        Continuous parts of the series (between time gaps): a run never spans two. None: one.

    Returns
    -------
    ndarray, shape (n,)
        Filtered runs; non-finite samples, and runs too short to filter, are NaN.
    """
    x = np.asarray(x, dtype=float)
    if x.ndim != 1:
        raise AeromagError(f"bandpass_finite expects a (n,) array, got shape {x.shape}")
    sos = _design(fs_hz, low_hz, high_hz, order)
    need = 1 if sos is None else min_length(sos)
    out = np.full(x.shape, np.nan)
    finite = np.isfinite(x)
    parts = [slice(0, x.size)] if segments is None else segments
    for run in (
        slice(p.start + r.start, p.start + r.stop) for p in parts for r in finite_runs(finite[p])
    ):
        if run.stop - run.start >= need:
            out[run] = bandpass(x[run], fs_hz, low_hz, high_hz, order)
    return out


def is_all_pass(fs_hz: float, low_hz: float, high_hz: float) -> bool:
    """True when the band edges mean "no filtering" (``low <= 0`` and ``high >= fs/2``)."""
    return low_hz <= 0 and high_hz >= fs_hz / 2.0


def finite_runs(ok: np.ndarray) -> list[slice]:
    """Contiguous runs of ``True`` in a boolean (n,) array, as slices, in order."""
    edges = np.diff(np.concatenate([[0], np.asarray(ok, dtype=np.int8), [0]]))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    return [slice(int(a), int(b)) for a, b in zip(starts, stops, strict=True)]


def bandpass_min_length(fs_hz: float, low_hz: float, high_hz: float, order: int = 4) -> int:
    """Fewest samples :func:`bandpass` accepts with these settings (1 when it does not filter)."""
    sos = _design(fs_hz, low_hz, high_hz, order)
    return 1 if sos is None else min_length(sos)


def min_length(sos: np.ndarray) -> int:
    """Fewest samples ``sosfiltfilt`` accepts with its default odd-extension padding."""
    zeros = min(int(np.sum(sos[:, 2] == 0)), int(np.sum(sos[:, 5] == 0)))
    return 3 * (2 * len(sos) + 1 - zeros) + 1


#: Lowest band edge, as a fraction of the Nyquist frequency: below about 2e-9 the Butterworth
#: sections' padding solve is singular (measured at 10 Hz: 1e-7 Hz works, 1e-8 Hz fails); 1e-6
#: keeps a margin of 500, and a cutoff that low (5 µHz at 10 Hz: a period of 2 days) does
#: nothing on a flight anyway.
MIN_EDGE = 1e-6


def _design(fs_hz: float, low_hz: float, high_hz: float, order: int) -> np.ndarray | None:
    """Second-order sections of the Butterworth filter, or None for "no filtering"."""
    if not (math.isfinite(fs_hz) and fs_hz > 0):
        raise AeromagError(f"sample rate must be a finite number > 0 Hz, got {fs_hz}")
    if not (math.isfinite(low_hz) and math.isfinite(high_hz)):
        raise AeromagError(f"band edges must be finite, got ({low_hz}, {high_hz}) Hz")
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or order < 1:
        raise AeromagError(f"filter order must be an integer ≥ 1, got {order!r}")
    nyquist = fs_hz / 2.0
    use_low, use_high = low_hz > 0, high_hz < nyquist
    if use_low and use_high and not low_hz < high_hz:
        raise AeromagError(f"band edges must satisfy low < high, got ({low_hz}, {high_hz}) Hz")
    if use_high and high_hz <= 0:
        raise AeromagError(f"low-pass cutoff must be > 0 Hz, got {high_hz}")
    if use_low and low_hz >= nyquist:
        raise AeromagError(f"high-pass cutoff must be < fs/2 = {nyquist} Hz, got {low_hz}")
    lowest = MIN_EDGE * nyquist
    for edge, used in ((low_hz, use_low), (high_hz, use_high)):
        if used and edge < lowest:
            raise AeromagError(
                f"band edge {edge:g} Hz is below {lowest:g} Hz ({MIN_EDGE:g} × fs/2), where the "
                "filter cannot be designed; use 0 for no high-pass"
            )
    from scipy.signal import butter

    if use_low and use_high:
        return butter(order, [low_hz, high_hz], btype="bandpass", fs=fs_hz, output="sos")
    if use_low:
        return butter(order, low_hz, btype="highpass", fs=fs_hz, output="sos")
    if use_high:
        return butter(order, high_hz, btype="lowpass", fs=fs_hz, output="sos")
    return None


def _check_filterable(x: np.ndarray, sos: np.ndarray) -> None:
    """One-line errors for gaps and for series shorter than the filter's padding."""
    if not np.all(np.isfinite(x)):
        bad = int(np.count_nonzero(~np.isfinite(x)))
        raise AeromagError(
            f"cannot filter {bad} non-finite sample(s); fill or cut them first "
            "(or filter each finite run with bandpass_finite)"
        )
    need = min_length(sos)
    if x.shape[0] < need:
        raise AeromagError(f"series too short to filter: {x.shape[0]} samples, need ≥ {need}")


def _constant_columns(cols: np.ndarray) -> np.ndarray:
    """(m,) bool: columns whose spread is at rounding level (MagNav skips them: std ≤ eps)."""
    scale = np.maximum(np.max(np.abs(cols), axis=0), np.finfo(float).tiny)
    return np.ptp(cols, axis=0) <= 4 * np.finfo(float).eps * scale


def check_cutoff(fs_hz: float, cutoff_hz: float) -> None:
    """Raise unless ``0 < cutoff_hz < fs_hz / 2`` (a single-edge filter that really filters)."""
    if not (math.isfinite(cutoff_hz) and 0 < cutoff_hz < fs_hz / 2):
        raise AeromagError(f"cutoff must be in (0, fs/2 = {fs_hz / 2} Hz), got {cutoff_hz} Hz")
