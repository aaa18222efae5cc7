"""Diagnostics: where the base model and the measurement disagree.

Decides what the report shows of the base model's residual, before any effect is named: the
60-s time blocks with the largest RMS (and those above twice the median), narrow peaks of its
spectrum, its mean in 30° heading bins, its partial correlation with every auxiliary channel
(outside the base span, on the calibration rows), and the whiteness (Ljung–Box) of the
whitened residual before and after the named effects.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from aeromag_env.discovery.base_model import BaseSpan
from aeromag_env.discovery.gap import rms
from aeromag_env.discovery.noise_model import NoiseModel
from aeromag_env.discovery.preparation import BLOCK_S, PreparedFlight


def diagnostics(
    data: PreparedFlight,
    span: BaseSpan,
    res: np.ndarray,
    noise0: NoiseModel | None,
    noise1: NoiseModel | None,
    lb0: tuple[float, float],
    lb1: tuple[float, float],
) -> dict[str, Any]:
    """Where the base model and the measurement disagree: time, frequency, heading, channels.

    Parameters
    ----------
    data : PreparedFlight
        The prepared flight.
    span : BaseSpan
        The base regressors' span on the calibration rows.
    res : numpy.ndarray
        The base model's residual (n, 3) (NaN where the sample is not usable).
    noise0, noise1 : NoiseModel or None
        Noise models before and after the named effects.
    lb0, lb1 : tuple of float
        Ljung–Box statistic and p-value of the whitened residual before and after.

    Returns
    -------
    dict
        The report's ``diagnostics`` entry: ``segments``, ``spectrum``,
        ``heading_bins_mean_nt``, ``heading_range_nt``, ``aux_partial_correlation``,
        ``whiteness``, ``noise_model_before`` and ``noise_model_after``.
    """
    ok = data.usable
    r = np.where(ok[:, None], res, 0.0)
    segments = time_segments(data, r)
    peaks = spectral_peaks(r, data.dt)
    heading = heading_bins(data, r)
    means = np.array(list(heading.values())) if heading else np.zeros((1, 3))
    corr = aux_correlation(data, span, r)
    return {
        "segments": segments,
        "spectrum": {"peaks": peaks[:8], "rms_nt": rms(r[ok])},
        "heading_bins_mean_nt": heading,
        "heading_range_nt": np.round(means.max(axis=0) - means.min(axis=0), 4).tolist(),
        "aux_partial_correlation": corr,
        "whiteness": {
            "ljung_box_lags": 20,
            "before": {"statistic": lb0[0], "p_value": lb0[1]},
            "after": {"statistic": lb1[0], "p_value": lb1[1]},
        },
        "noise_model_before": noise0.to_dict() if noise0 else None,
        "noise_model_after": noise1.to_dict() if noise1 else None,
    }


def time_segments(data: PreparedFlight, r: np.ndarray) -> dict[str, Any]:
    """RMS of the residual per :data:`~aeromag_env.discovery.preparation.BLOCK_S` block.

    Parameters
    ----------
    data : PreparedFlight
        The prepared flight.
    r : numpy.ndarray
        Residual (n, 3), zero where the sample is not usable.

    Returns
    -------
    dict
        ``block_s``, ``median_rms_nt``, the five ``worst`` blocks and the blocks ``flagged``
        above twice the median (each with ``t0_s``, ``t1_s``, ``rms_nt``).
    """
    tt, ok = data.ctx.tt, data.usable
    block = np.floor((tt - tt[0]) / BLOCK_S).astype(int)
    seg = []
    for b in np.unique(block[ok]):
        k = ok & (block == b)
        seg.append((float(tt[k][0]), float(tt[k][-1]), rms(r[k])))
    med = float(np.median([s[2] for s in seg]))
    worst = sorted(seg, key=lambda s: -s[2])[:5]
    return {
        "block_s": BLOCK_S,
        "median_rms_nt": med,
        "worst": [{"t0_s": a, "t1_s": b, "rms_nt": c} for a, b, c in worst],
        "flagged": [{"t0_s": a, "t1_s": b, "rms_nt": c} for a, b, c in seg if c > 2 * med],
    }


def spectral_peaks(r: np.ndarray, dt: float) -> list[dict[str, float]]:
    """Narrow peaks of the residual's spectrum (Welch, summed over axes): local maxima above
    ten times a 31-bin running median.

    Parameters
    ----------
    r : numpy.ndarray
        Residual (n, 3), zero where the sample is not usable.
    dt : float
        Sample interval [s].

    Returns
    -------
    list of dict
        ``frequency_hz`` and ``excess`` (power over the running median) of every peak, by
        frequency.
    """
    from scipy.signal import welch

    f, psd = welch(r, fs=1.0 / dt, nperseg=min(2048, r.shape[0]), axis=0)
    peaks = []
    total = psd.sum(axis=1)
    from scipy.ndimage import median_filter

    ref = median_filter(total, size=31, mode="nearest")
    for k in np.flatnonzero((total > 10 * ref) & (f > 0)):
        left_ok = k == 0 or total[k] >= total[k - 1]
        if left_ok and (k + 1 >= total.size or total[k] >= total[k + 1]):
            peaks.append({"frequency_hz": float(f[k]), "excess": float(total[k] / ref[k])})
    return peaks


def heading_bins(data: PreparedFlight, r: np.ndarray) -> dict[str, list[float]]:
    """Mean residual per 30° heading bin (bins with more than 10 usable samples).

    Parameters
    ----------
    data : PreparedFlight
        The prepared flight (the heading comes from its attitude).
    r : numpy.ndarray
        Residual (n, 3), zero where the sample is not usable.

    Returns
    -------
    dict
        Per bin (``"0-30"``, ``"30-60"``…), the mean residual per axis [nT].
    """
    ok = data.usable
    yaw = np.degrees(np.arctan2(data.ctx.c_nb[:, 1, 0], data.ctx.c_nb[:, 0, 0])) % 360.0
    bins = np.floor(yaw / 30.0).astype(int)
    heading = {}
    for b in range(12):
        k = ok & (bins == b)
        if k.sum() > 10:
            heading[f"{30 * b}-{30 * b + 30}"] = np.round(r[k].mean(axis=0), 4).tolist()
    return heading


def aux_correlation(data: PreparedFlight, span: BaseSpan, r: np.ndarray) -> dict[str, Any]:
    """Partial correlation of the residual with each auxiliary channel, per axis, outside the
    base span on the calibration rows.

    Parameters
    ----------
    data : PreparedFlight
        The prepared flight.
    span : BaseSpan
        The base regressors' span on the calibration rows.
    r : numpy.ndarray
        Residual (n, 3), zero where the sample is not usable.

    Returns
    -------
    dict
        Per channel, ``partial_correlation`` (3) and ``max_abs``.
    """
    corr = {}
    rows = data.calibration
    for nm, ch in data.ctx.aux.items():
        x = np.zeros((data.ctx.n, 3, 3))
        for i in range(3):
            x[:, i, i] = ch
        xp = span.perp(x).reshape(3, -1, 3)
        rr = r[rows]
        cs = []
        for i in range(3):
            u, v = xp[i, :, i], rr[:, i]
            den = float(np.linalg.norm(u) * np.linalg.norm(v))
            cs.append(float(u @ v / den) if den > 0 else 0.0)
        corr[nm] = {
            "partial_correlation": np.round(cs, 4).tolist(),
            "max_abs": float(np.max(np.abs(cs))),
        }
    return corr
