"""Accuracy on real survey data, where no truth exists: band-passed spreads, the improvement
ratio, and the comparison with the vendor's own compensated channel.

On a survey line the compensated field still holds the crustal geology, so its plain spread
measures the ground, not the compensation. MagNav.jl reports the spread in the 0.1–0.9 Hz band
(4-pole zero-phase Butterworth, :func:`aeromag_env.compensation.dsp.bandpass_finite`), where the
aircraft's manoeuvre-driven interference lives and geology at survey altitude does not:

* :func:`headline` — band-passed std of the uncompensated and compensated field, their ratio
  (the improvement ratio), and the FOM where the calibration manoeuvres are labelled or, in a
  file without labels, detected from the attitude (:mod:`aeromag_env.flight.maneuvers`);
* :func:`vendor_comparison` — when the file carries the vendor's compensated channel
  (``mag_1_c`` for ``mag_1_uc``), the band-passed std of the uncompensated scalar, of the vendor's
  field and of ours, and both improvement ratios.

Every series is band-passed per continuous segment (:func:`aeromag_env.flight.quality.segments`:
a filter never runs across a time gap) and per run of finite samples; the statistics pool the
segments, each de-meaned (:func:`aeromag_env.compensation.metrics.residual_std`), over the samples
finite in every series compared and inside the span scored. The span is the second half of the
flight by default, as in the ``metrics`` block (an online filter is still converging in the
first); ``whole_flight`` repeats the figures over every sample. All values in [nT] except the
ratios [-].
"""

from __future__ import annotations

from typing import Any

import numpy as np

from aeromag_env.compensation.dsp import bandpass_finite
from aeromag_env.compensation.metrics import figure_of_merit, residual_std
from aeromag_env.errors import AeromagError
from aeromag_env.flight.data import Flight
from aeromag_env.flight.maneuvers import Maneuver, detect_maneuvers, last_box, maneuver_labels
from aeromag_env.flight.quality import segments, spike_flags

#: MagNav.jl's band for compensation figures [Hz].
BAND_HZ = (0.1, 0.9)
#: FOM high-pass cutoff, as the ``metrics`` block's [Hz].
FOM_HIGHPASS_HZ = 0.05
#: Segments listed one by one in a report (the pooled figures cover all).
MAX_SEGMENTS_LISTED = 20
FOM_NEEDS_LABELS = (
    "FOM needs the calibration box's manoeuvres: none are labelled (a 'maneuver' field, windows "
    "1–12 per box) and no complete box (4 headings × roll, pitch, yaw) was found in the attitude"
)


def vendor_channel(flight: Flight, scalar: str | None) -> str | None:
    """The vendor's compensated channel of ``scalar`` (``mag_1_uc`` → ``mag_1_c``) if present."""
    if scalar is None or not scalar.endswith("_uc"):
        return None
    name = scalar.removesuffix("_uc") + "_c"
    return name if name in flight else None


def bandpassed(
    flight: Flight,
    x: np.ndarray,
    band_hz: tuple[float, float] = BAND_HZ,
    parts: list[slice] | None = None,
) -> np.ndarray:
    """``x`` (n,) band-passed on each continuous segment (``parts``, default the flight's) and
    finite run; NaN elsewhere."""
    parts = segments(flight.tt) if parts is None else parts
    return bandpass_finite(x, flight.sample_rate_hz, *band_hz, segments=parts)


def second_half(flight: Flight) -> np.ndarray:
    """(n,) bool: the second half of the flight's samples, the span ``metrics`` scores."""
    return np.arange(flight.n) >= flight.n // 2


def spreads(
    flight: Flight, series: dict[str, np.ndarray], span: np.ndarray | None = None
) -> dict[str, Any]:
    """Band-passed std of each series over the samples finite in all of them and inside ``span``
    ((n,) bool; None: all), pooled and per continuous segment:
    ``{"samples", "std_nt": {name: …}, "segments": [...], "segment_count"}``."""
    parts = segments(flight.tt)
    common = np.all([np.isfinite(v) for v in series.values()], axis=0)
    bp = {
        k: bandpassed(flight, np.where(common, v, np.nan), parts=parts) for k, v in series.items()
    }
    ok = np.all([np.isfinite(v) for v in bp.values()], axis=0)
    if span is not None:
        ok &= span
    seg_id = np.zeros(flight.n)
    per_segment = []
    for i, seg in enumerate(parts):
        seg_id[seg] = i
        k = np.flatnonzero(ok[seg]) + seg.start
        if k.size:
            std = {name: float(np.std(v[k])) for name, v in bp.items()}
            t0, t1 = float(flight.tt[seg.start]), float(flight.tt[seg.stop - 1])
            per_segment.append(
                {"t_start_s": t0, "t_end_s": t1, "samples": int(k.size), "std_nt": std}
            )
    return {
        "samples": int(ok.sum()),
        "std_nt": {name: _std(v, ok, seg_id) for name, v in bp.items()},
        "segments": per_segment[:MAX_SEGMENTS_LISTED],
        "segment_count": len(per_segment),
    }


def headline(
    flight: Flight, before: np.ndarray, after: np.ndarray, fom_nt: float | None
) -> dict[str, Any]:
    """The accuracy figures of real survey data for one compensated series.

    Parameters
    ----------
    flight : Flight
    before, after : ndarray, shape (n,)
        Uncompensated and compensated total field [nT].
    fom_nt : float or None
        The FOM of ``after`` from labelled manoeuvres (None when there are none).
    """
    out: dict[str, Any] = {
        "bandpass_hz": list(BAND_HZ),
        "span": "second half of the flight",
        **span_figures(flight, before, after, second_half(flight)),
        "whole_flight": span_figures(flight, before, after, None),
        "fom_nt": fom_nt,
        "fom_source": "labelled manoeuvres (metrics.fom_nt)" if fom_nt is not None else None,
    }
    if fom_nt is None and flight.maneuver_windows():
        out["fom_note"] = (
            "the 'maneuver' field holds no complete box of 12 windows with finite data"
        )
    elif fom_nt is None:
        out.update(detected_fom(flight, before, after))
    return out


def detected_fom(flight: Flight, before: np.ndarray, after: np.ndarray) -> dict[str, Any]:
    """FOM on the last compensation box found in the attitude
    (:mod:`aeromag_env.flight.maneuvers`), with its windows; ``fom_note`` when there is none or
    a window holds a gap."""
    box = last_box(detect_maneuvers(flight))
    if box is None:
        return {"fom_note": FOM_NEEDS_LABELS}
    labels = maneuver_labels(flight.n, box)
    args = (flight.tt, labels, flight.sample_rate_hz, FOM_HIGHPASS_HZ)
    try:
        fom, fom_before = figure_of_merit(after, *args), figure_of_merit(before, *args)
    except AeromagError as exc:
        return {"fom_note": f"a box was found in the attitude, but {exc}"}
    windows = [_window(flight, w) for w in box]
    return {
        "fom_nt": fom,
        "fom_uncompensated_nt": fom_before,
        "fom_source": "manoeuvres detected from the attitude",
        "fom_windows": windows,
    }


def _window(flight: Flight, w: Maneuver) -> dict[str, Any]:
    t0, t1 = float(flight.tt[w.start]), float(flight.tt[w.stop - 1])
    return {"axis": w.axis, "heading_deg": w.heading_deg, "t_start_s": t0, "t_end_s": t1}


def vendor_comparison(
    flight: Flight, scalar: str, ours_before: np.ndarray, ours_after: np.ndarray, ours_name: str
) -> dict[str, Any] | None:
    """Our compensation against the vendor's, when the file has ``scalar``'s ``_c`` channel.

    Parameters
    ----------
    flight : Flight
    scalar : str
        The uncompensated scalar channel (``mag_1_uc``).
    ours_before, ours_after : ndarray, shape (n,)
        Our uncompensated and compensated total field [nT] (the scalar for Tolles–Lawson, the
        fluxgate's magnitude for the vector methods).
    ours_name : str
        Which sensor ours is (``mag_1_uc``, ``flux_a``).

    Returns
    -------
    dict or None
        None without a vendor channel. Our improvement ratio is against our own uncompensated
        input, the vendor's against the uncompensated scalar (the same for Tolles–Lawson).
        Samples flagged as spikes in the scalar or the vendor's channel are left out.
    """
    vendor = vendor_channel(flight, scalar)
    if vendor is None:
        return None
    flags = spike_flags(flight, [scalar, vendor])
    spiky = flags[scalar] | flags[vendor]
    series = {
        "uncompensated": flight[scalar],
        "vendor": flight[vendor],
        "ours_uncompensated": ours_before,
        "ours": ours_after,
    }
    series = {k: np.where(spiky, np.nan, v) for k, v in series.items()}
    s = spreads(flight, series, second_half(flight))
    std = s["std_nt"]
    return {
        "scalar": scalar,
        "vendor_channel": vendor,
        "ours_sensor": ours_name,
        "bandpass_hz": list(BAND_HZ),
        "span": "second half of the flight",
        "samples": s["samples"],
        "std_uncompensated_nt": std["uncompensated"],
        "std_vendor_nt": std["vendor"],
        "std_ours_nt": std["ours"],
        "improvement_ratio_vendor": _ratio(std["uncompensated"], std["vendor"]),
        "improvement_ratio_ours": _ratio(std["ours_uncompensated"], std["ours"]),
        "segments": s["segments"],
        "segment_count": s["segment_count"],
    }


def span_figures(
    flight: Flight, before: np.ndarray, after: np.ndarray, span: np.ndarray | None
) -> dict[str, Any]:
    """Samples, segments, band-passed stds and their ratio over ``span`` (bool (n,), None: all)."""
    s = spreads(flight, {"uncompensated": before, "compensated": after}, span)
    std = s["std_nt"]
    return {
        "samples": s["samples"],
        "segments": s["segment_count"],
        "std_uncompensated_nt": std["uncompensated"],
        "std_compensated_nt": std["compensated"],
        "improvement_ratio": _ratio(std["uncompensated"], std["compensated"]),
    }


def _std(x: np.ndarray, ok: np.ndarray, seg_id: np.ndarray) -> float | None:
    """Pooled std of ``x`` over ``ok``, each segment de-meaned; None without samples."""
    try:
        return residual_std(np.where(ok, x, np.nan), seg_id)
    except AeromagError:
        return None


def _ratio(a: float | None, b: float | None) -> float | None:
    return None if a is None or b is None or b == 0 else a / b
