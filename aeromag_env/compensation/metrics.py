"""Compensation metrics used in the industry and in MagNav.jl (pure functions, all in [nT]).

* :func:`compensation_rmse` — simulation only: RMS of true minus estimated interference;
* :func:`residual_std` — std after removing the mean of each flight line (MagNav ``err_segs``);
* :func:`improvement_ratio` — std before / std after compensation, on band-passed data
  (Noriega 2011, *The Leading Edge* 30(10):1122);
* :func:`figure_of_merit` — sum of the 12 maneuver peak-to-peak amplitudes of the high-passed
  compensated total field (SEG dictionary, "figure of merit": roll 10°, pitch 5°, yaw 5° at the
  north, east, south and west headings); :func:`fom_terms` gives each window's term;
* :func:`ratio_statistics` — summary of a consistency-ratio series (ROR, QOQ), ideally ≈ 1.

Non-finite samples (NaN, ±inf) are ignored: statistics use the finite samples only, and filters
run on each contiguous finite run separately
(:func:`aeromag_env.compensation.dsp.bandpass_finite`), and never across a time gap when the
flight's continuous ``segments`` are given. The one exception is a gap inside an FOM maneuver
window, which raises (see :func:`fom_terms`). A metric left with no usable sample raises a
one-line :class:`AeromagError`.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from aeromag_env.compensation.dsp import bandpass_finite, check_cutoff
from aeromag_env.errors import AeromagError

FOM_WINDOWS = range(1, 13)


def compensation_rmse(
    true_interf: np.ndarray, est_interf: np.ndarray, mask: np.ndarray | None = None
) -> float:
    """RMS of the interference error, pooled over components [nT].

    Parameters
    ----------
    true_interf, est_interf : ndarray, shape (n,) or (n, 3)
        True and estimated interference [nT].
    mask : ndarray of bool, shape (n,), optional
        Samples to include (default: all).

    Returns
    -------
    float
        ``sqrt(mean over samples and axes of (true − est)²)`` [nT], over the samples whose every
        component is finite; for (n, 3) this is ``sqrt(mean(compensation_rmse_per_axis²))``.
    """
    err = _error_rows(true_interf, est_interf, mask)
    return float(_rms(err, axis=None))


def compensation_rmse_per_axis(
    true_interf: np.ndarray, est_interf: np.ndarray, mask: np.ndarray | None = None
) -> np.ndarray:
    """RMS of the interference error per axis [nT], shape (3,) (inputs (n, 3), as above)."""
    err = _error_rows(true_interf, est_interf, mask)
    if err.ndim != 2:
        raise AeromagError(f"per-axis RMSE needs (n, 3) arrays, got shape {err.shape[:1]}")
    return np.asarray(_rms(err, axis=0))


def _rms(err: np.ndarray, axis: int | None) -> np.ndarray | float:
    """``sqrt(mean(err²))`` over ``axis``; where the squares overflow (errors of a corrupted
    channel, 1e200 nT), the RMS of ``err`` scaled by its largest |value|, times that value: a
    large finite RMS instead of inf."""
    with np.errstate(over="ignore"):
        rms = np.sqrt(np.mean(err**2, axis=axis))
    if np.all(np.isfinite(rms)):
        return rms
    scale = np.max(np.abs(err), axis=axis, keepdims=True, initial=0.0)
    safe = np.where(scale > 0, scale, 1.0)
    return np.sqrt(np.mean((err / safe) ** 2, axis=axis)) * np.squeeze(safe, axis=axis)


def residual_std(x: np.ndarray, line: np.ndarray | None = None) -> float:
    """Standard deviation after removing each flight line's mean [nT] (MagNav ``err_segs``).

    Parameters
    ----------
    x : ndarray, shape (n,)
        Residual, e.g. compensated minus reference [nT].
    line : ndarray, shape (n,), optional
        Flight-line id of each sample; None → one segment.

    Returns
    -------
    float
        Population std (``ddof = 0``; Julia's ``std`` in MagNav divides by n − 1, a relative
        difference of ≈ 1/(2n)) of the pooled de-meaned residual, over samples where ``x``
        and ``line`` are finite.
    """
    x = _series(x, "x")
    ids = np.zeros_like(x) if line is None else _series(line, "line", x.size)
    ok = np.isfinite(x) & np.isfinite(ids)
    _require(ok, "residual_std")
    x, ids = x[ok], ids[ok]
    _, inverse, counts = np.unique(ids, return_inverse=True, return_counts=True)
    means = np.bincount(inverse, weights=x) / counts
    return float(np.std(x - means[inverse]))


def improvement_ratio(
    before: np.ndarray,
    after: np.ndarray,
    fs_hz: float,
    band_hz: tuple[float, float] | None = (0.1, 0.9),
    segments: list[slice] | None = None,
) -> float:
    """Improvement ratio ``std(bandpass(before)) / std(bandpass(after))`` [-].

    Parameters
    ----------
    before, after : ndarray, shape (n,)
        Uncompensated and compensated total field [nT].
    fs_hz : float
        Sample rate [Hz].
    band_hz : (float, float) or None
        Zero-phase 4-pole Butterworth pass band [Hz] (MagNav conventions for the edges); None
        compares the plain standard deviations.
    segments : list of slice, optional
        Continuous parts of the series (between time gaps), filtered apart. None: one.

    Returns
    -------
    float
        The ratio (``inf`` if the band-passed ``after`` is exactly constant). Only samples
        finite in both series count; each finite run is filtered on its own.
    """
    before, after = _series(before, "before"), _series(after, "after", before.size)
    ok = np.isfinite(before) & np.isfinite(after)
    b, a = np.where(ok, before, np.nan), np.where(ok, after, np.nan)
    if band_hz is not None:
        b, a = (bandpass_finite(s, fs_hz, *band_hz, segments=segments) for s in (b, a))
    ok = np.isfinite(b) & np.isfinite(a)
    _require(ok, "improvement_ratio (after filtering)")
    std_after = float(np.std(a[ok]))
    return float(np.std(b[ok])) / std_after if std_after > 0 else float("inf")


def fom_terms(
    total_field: np.ndarray,
    tt: np.ndarray,
    maneuver: np.ndarray,
    fs_hz: float,
    highpass_hz: float = 0.05,
    windows: Iterable[int] = FOM_WINDOWS,
    segments: list[slice] | None = None,
) -> dict[int, float]:
    """Peak-to-peak amplitude of the high-passed field in each maneuver window [nT].

    Parameters
    ----------
    total_field : ndarray, shape (n,)
        Compensated total field [nT].
    tt : ndarray, shape (n,)
        Time [s]; its median step must be ``1 / fs_hz`` ± 1 % (the filter needs uniform steps).
    maneuver : ndarray, shape (n,)
        Window id of each sample: 0 outside, k ≥ 1 inside maneuver window k.
    fs_hz : float
        Sample rate [Hz].
    highpass_hz : float
        Zero-phase 4-pole Butterworth high-pass cutoff [Hz]: removes heading and geology trends.
    windows : iterable of int
        Window ids to use (the 12 of a compensation box by default).
    segments : list of slice, optional
        Continuous parts of the flight (between time gaps), high-passed apart. None: one.

    Returns
    -------
    dict[int, float]
        Window id → peak-to-peak [nT].
    Gaps (non-finite samples) outside the windows are skipped, each finite run being high-passed
    on its own; a window with a gap raises :class:`AeromagError` (the filter's edge transients
    would inflate its peak-to-peak). Windows within ~``1 / highpass_hz`` of a gap or an end
    see such transients too: keep straight flight around the maneuvers.
    """
    hp = _highpassed(total_field, tt, fs_hz, highpass_hz, segments)
    ids = np.nan_to_num(_series(maneuver, "maneuver", hp.size)).astype(int)
    wanted = sorted(set(windows))
    _check_windows(hp, ids, wanted)
    return {w: float(np.ptp(hp[ids == w])) for w in wanted}


def figure_of_merit(
    total_field: np.ndarray,
    tt: np.ndarray,
    maneuver: np.ndarray,
    fs_hz: float,
    highpass_hz: float = 0.05,
    windows: Iterable[int] = FOM_WINDOWS,
    segments: list[slice] | None = None,
) -> float:
    """Figure of merit: the sum of :func:`fom_terms` over the windows [nT].

    The industry FOM (SEG dictionary) sums, without regard to sign, the peak-to-peak amplitudes
    of the 12 signatures of the compensation box (roll 10°, pitch 5°, yaw 5° at four headings);
    a good installation reaches 1–2 nT or less. Arguments as in :func:`fom_terms`.
    """
    terms = fom_terms(total_field, tt, maneuver, fs_hz, highpass_hz, windows, segments)
    return float(sum(terms.values()))


def ratio_statistics(
    ratio: np.ndarray,
    mask: np.ndarray | None = None,
    within: tuple[float, float] = (0.9, 1.1),
) -> dict[str, float]:
    """Summary of a consistency-ratio series (ROR, QOQ; 1 for a consistent filter) [-].

    Parameters
    ----------
    ratio : ndarray, shape (n,)
    mask : ndarray of bool, shape (n,), optional
        Samples to include (e.g. the second half of a flight).
    within : (float, float)
        Closed interval for ``fraction_within``.

    Returns
    -------
    dict
        ``median``, ``p05``, ``p95`` (percentiles, linear interpolation), ``fraction_within``
        (share of the used samples inside ``within``), all over the finite samples, and
        ``fraction_finite`` (finite share of the selected samples: a diverged filter's ±inf and
        a warm-up's NaN are excluded from the others but show here).
    """
    r = _series(ratio, "ratio")
    sel = np.ones(r.size, bool) if mask is None else _mask(mask, r.size)
    ok = sel & np.isfinite(r)
    _require(ok, "ratio_statistics")
    v = r[ok]
    p05, median, p95 = np.percentile(v, [5, 50, 95])
    return {
        "median": float(median),
        "p05": float(p05),
        "p95": float(p95),
        "fraction_within": float(np.mean((v >= within[0]) & (v <= within[1]))),
        "fraction_finite": np.count_nonzero(ok) / np.count_nonzero(sel),
    }


def _highpassed(
    x: np.ndarray, tt: np.ndarray, fs_hz: float, cutoff_hz: float, segments: list[slice] | None
) -> np.ndarray:
    """High-pass each finite run of ``x`` after checking ``tt`` against ``fs_hz``."""
    x = _series(x, "total_field")
    tt = _series(tt, "tt", x.size)
    if x.size > 1:
        dt = float(np.median(np.diff(tt)))
        if not (dt > 0 and abs(dt * fs_hz - 1.0) <= 0.01):
            raise AeromagError(f"tt has a median interval of {dt} s, but fs_hz = {fs_hz} Hz")
    check_cutoff(fs_hz, cutoff_hz)
    return bandpass_finite(x, fs_hz, cutoff_hz, fs_hz / 2.0, segments=segments)


def _check_windows(hp: np.ndarray, ids: np.ndarray, wanted: list[int]) -> None:
    """One-line errors for absent windows and for windows with gaps."""
    absent = [w for w in wanted if not np.any(ids == w)]
    if absent:
        found = sorted(set(ids[ids > 0].tolist()))
        raise AeromagError(
            f"maneuver window(s) {', '.join(map(str, absent))} absent"
            f" (windows present: {', '.join(map(str, found)) or 'none'})"
        )
    gappy = [w for w in wanted if not np.all(np.isfinite(hp[ids == w]))]
    if gappy:
        raise AeromagError(
            f"maneuver window(s) {', '.join(map(str, gappy))} contain non-finite samples (or sit"
            " in a run too short to filter); fill the gaps or leave those windows out"
        )


def _error_rows(
    true_interf: np.ndarray, est_interf: np.ndarray, mask: np.ndarray | None
) -> np.ndarray:
    """``true − est`` restricted to selected rows whose every component is finite."""
    t, e = np.asarray(true_interf, float), np.asarray(est_interf, float)
    if t.shape != e.shape or t.ndim not in (1, 2) or (t.ndim == 2 and t.shape[1] != 3):
        raise AeromagError(
            f"interference arrays must be (n,) or (n, 3) alike: {t.shape}, {e.shape}"
        )
    err = t - e
    ok = np.isfinite(err) if err.ndim == 1 else np.all(np.isfinite(err), axis=1)
    if mask is not None:
        ok &= _mask(mask, err.shape[0])
    _require(ok, "compensation_rmse")
    return err[ok]


def _series(x: np.ndarray, name: str, n: int | None = None) -> np.ndarray:
    x = np.asarray(x, dtype=float)
    if x.ndim != 1 or (n is not None and x.size != n):
        want = "(n,)" if n is None else f"({n},)"
        raise AeromagError(f"{name} must have shape {want}, got {x.shape}")
    return x


def _mask(mask: np.ndarray, n: int) -> np.ndarray:
    m = np.asarray(mask)
    if m.shape != (n,) or m.dtype != bool:
        raise AeromagError(f"mask must be a boolean array of shape ({n},), got {m.dtype} {m.shape}")
    return m


def _require(ok: np.ndarray, what: str) -> None:
    if not np.any(ok):
        raise AeromagError(f"{what}: no finite samples to evaluate")
