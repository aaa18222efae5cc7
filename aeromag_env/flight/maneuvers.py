"""The calibration box's manoeuvres found from the attitude alone, for files that do not label them.

The compensation box flies four headings and, at each, a roll, a pitch and a yaw oscillation
(±10°, ±5°, ±5° with periods of 4–6 s, a few cycles each) on an otherwise straight leg; the FOM
sums the peak-to-peak of the compensated field over these 12 windows. A simulated file labels
them (``maneuver`` field); a real one usually does not. :func:`detect_maneuvers` finds them:

1. each attitude angle minus its running median over :data:`MEDIAN_WINDOW_S` — the median of a
   monotone stretch is its middle sample, so a turn's heading ramp and the bank held through a
   turn leave (almost) nothing, while an oscillation about a constant stays;
2. its envelope: the running maximum of the absolute value over :data:`ENVELOPE_WINDOW_S` (about
   half the longest period);
3. a sample is manoeuvring when an envelope exceeds :data:`THRESHOLD_DEG` (a survey line holds
   attitude to a few tenths of a degree); it belongs to the axis whose envelope, relative to
   that axis's nominal amplitude, is largest;
4. a window is a run of samples of one axis at least :data:`MIN_WINDOW_S` long, its heading the
   circular mean of ``ins_yaw`` over it.

:func:`last_box` then takes the last 12 consecutive windows that form a box: four groups of
three, each group on one heading (within :data:`HEADING_TOL_DEG`) and holding a roll, a pitch
and a yaw window, the four headings distinct.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aeromag_env.flight.data import ATTITUDE_NAMES, Flight

#: Running-median window that removes turns and held banks [s].
MEDIAN_WINDOW_S = 21.0
#: Running-maximum window of the envelope (about half the longest period) [s].
ENVELOPE_WINDOW_S = 2.5
#: Envelope above which a sample is manoeuvring [deg].
THRESHOLD_DEG = 1.5
#: Nominal amplitudes (roll, pitch, yaw) that the envelopes are compared relative to [deg].
NOMINAL_AMPLITUDE_DEG = (10.0, 5.0, 5.0)
#: Shortest manoeuvre window [s].
MIN_WINDOW_S = 6.0
#: Windows of one heading group differ by less than this; groups by more [deg].
HEADING_TOL_DEG = 30.0
AXES = ("roll", "pitch", "yaw")


@dataclass(frozen=True)
class Maneuver:
    """One detected manoeuvre window: samples ``start:stop``, its axis and heading [deg]."""

    start: int
    stop: int
    axis: str
    heading_deg: float


def detect_maneuvers(flight: Flight) -> list[Maneuver]:
    """The manoeuvre windows of a flight, in time order (module docstring); [] without
    attitude or with too short a flight."""
    if any(nm not in flight for nm in ATTITUDE_NAMES) or flight.n < 10:
        return []
    from scipy.ndimage import maximum_filter1d, median_filter  # lazy: light import

    fs = flight.sample_rate_hz
    angles = np.column_stack([flight[nm] for nm in ATTITUDE_NAMES])
    angles[:, 2] = np.rad2deg(np.unwrap(np.deg2rad(_filled(angles[:, 2]))))
    angles[:, :2] = np.column_stack([_filled(angles[:, i]) for i in range(2)])
    med = median_filter(angles, size=(_odd(MEDIAN_WINDOW_S * fs), 1), mode="nearest")
    size = _odd(ENVELOPE_WINDOW_S * fs)
    envelope = maximum_filter1d(np.abs(angles - med), size=size, axis=0, mode="nearest")
    active = envelope.max(axis=1) > THRESHOLD_DEG
    axis = np.argmax(envelope / np.asarray(NOMINAL_AMPLITUDE_DEG), axis=1)
    label = np.where(active, axis, -1)
    edges = np.flatnonzero(np.diff(label)) + 1
    out = []
    for a, b in zip(np.r_[0, edges], np.r_[edges, flight.n], strict=True):
        if label[a] >= 0 and (b - a) >= MIN_WINDOW_S * fs:
            out.append(Maneuver(int(a), int(b), AXES[label[a]], _heading(flight["ins_yaw"][a:b])))
    return out


def last_box(windows: list[Maneuver]) -> list[Maneuver] | None:
    """The last 12 consecutive windows that form a compensation box, or None."""
    for end in range(len(windows), 11, -1):
        box = windows[end - 12 : end]
        groups = [box[i : i + 3] for i in range(0, 12, 3)]
        headings = [g[0].heading_deg for g in groups]
        if all(_is_group(g) for g in groups) and _distinct(headings):
            return box
    return None


def maneuver_labels(n: int, box: list[Maneuver]) -> np.ndarray:
    """(n,) window ids as in a ``maneuver`` field: 0 outside, 1–12 inside the box's windows."""
    ids = np.zeros(n)
    for k, w in enumerate(box, start=1):
        ids[w.start : w.stop] = k
    return ids


def _is_group(group: list[Maneuver]) -> bool:
    """Three windows on one heading, one per axis."""
    same = all(_angle(w.heading_deg, group[0].heading_deg) < HEADING_TOL_DEG for w in group)
    return same and {w.axis for w in group} == set(AXES)


def _distinct(headings: list[float]) -> bool:
    return all(
        _angle(a, b) >= HEADING_TOL_DEG for i, a in enumerate(headings) for b in headings[i + 1 :]
    )


def _angle(a: float, b: float) -> float:
    """Absolute difference of two headings, wrapped to [0, 180] [deg]."""
    return abs((a - b + 180.0) % 360.0 - 180.0)


def _heading(yaw_deg: np.ndarray) -> float:
    """Circular mean of a heading series [deg]."""
    rad = np.deg2rad(yaw_deg[np.isfinite(yaw_deg)])
    if rad.size == 0:
        return 0.0
    return float(np.rad2deg(np.arctan2(np.sin(rad).mean(), np.cos(rad).mean())))


def _filled(x: np.ndarray) -> np.ndarray:
    """Non-finite samples filled by linear interpolation (zeros when none is finite)."""
    ok = np.isfinite(x)
    if ok.all() or not ok.any():
        return np.where(ok, x, 0.0)
    return np.interp(np.arange(x.size), np.flatnonzero(ok), x[ok])


def _odd(samples: float) -> int:
    return max(3, round(samples) | 1)
