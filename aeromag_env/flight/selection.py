"""Which part of a flight to use: lines, a time segment, and the calibration line.

A survey flight is a calibration box (a high-altitude square flown with pitch, roll and yaw
manoeuvres on four headings) followed by survey lines. The industry fits Tolles–Lawson on the box
and applies the fit to the lines; the lines themselves carry crustal geology, so a method is judged
on the box (FOM) or in a band, never by the lines' raw residual. This module turns the options
``--line N[,M…]``, ``--segment T0:T1`` and ``--calibration-line [N]`` into sample masks:

* :func:`line_mask` and :func:`segment_mask` select samples by the ``line`` field and by ``tt``;
* :func:`find_calibration_line` names the calibration line: the line that holds the labelled
  manoeuvres (``maneuver`` field) when there is one, else the line with the most attitude
  activity (roll and pitch with their slow part removed: the manoeuvres' swings, not the banks
  of the turns) among those flown on at least three headings, which a straight survey line is
  not. It says which rule decided;
* :func:`subset` keeps the selected samples (the time jumps between kept parts are gaps that
  :mod:`aeromag_env.flight.quality` reports and the compensators respect).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import median_filter

from aeromag_env.errors import AeromagError, ArgumentError
from aeromag_env.flight.data import Flight

#: A line counts as manoeuvring when the RMS of its roll plus that of its pitch, each with a
#: moving median over ACTIVITY_WINDOW_S removed, exceeds this [deg]: the calibration box swings
#: ±5–10° with periods of 4–12 s (≈ 3° in simulated boxes), a survey line holds attitude to a few
#: tenths of a degree (≤ 0.45° in simulated lines with turbulence), and the removed slow part is
#: the bank of a turn.
MIN_ACTIVITY_DEG = 1.0
ACTIVITY_WINDOW_S = 20.0
#: Headings (quadrants of 90°) a calibration box covers at least; a survey line covers one.
MIN_HEADINGS = 3
#: A selection must keep at least this many samples [-].
MIN_SAMPLES = 100


@dataclass(frozen=True)
class CalibrationLine:
    """The calibration line of a flight: its id, its samples and why it was chosen."""

    line: float
    mask: np.ndarray  #: (n,) bool
    reason: str

    def to_dict(self) -> dict[str, object]:
        line = int(self.line) if float(self.line).is_integer() else self.line
        return {"line": line, "samples": int(self.mask.sum()), "reason": self.reason}


def line_mask(flight: Flight, lines: tuple[float, ...]) -> np.ndarray:
    """Samples whose ``line`` is one of ``lines``; a one-line error naming the file's lines
    when the flight has no ``line`` field or a requested line is not in it."""
    if "line" not in flight:
        raise ArgumentError("lines", "needs a 'line' field, which this flight has not")
    line = flight["line"]
    missing = [v for v in lines if not np.any(line == v)]
    if missing:
        have = _line_ids(line)
        shown = ", ".join(f"{v:g}" for v in have[:20]) + (" …" if len(have) > 20 else "")
        raise ArgumentError(
            "lines",
            f"names line {', '.join(f'{v:g}' for v in missing)}, not in this flight (it has "
            f"{shown})",
        )
    return np.isin(line, lines)


def segment_mask(
    flight: Flight, segment: tuple[float, float], option: str = "--segment"
) -> np.ndarray:
    """Samples with ``T0 ≤ tt ≤ T1``; a one-line error naming ``option`` when that keeps too
    few."""
    t0, t1 = segment
    mask = (flight.tt >= t0) & (flight.tt <= t1)
    if mask.sum() < MIN_SAMPLES:
        shown = f"{t0:g}:{t1:g}" if option == "--segment" else f"{t0:g} {t1:g}"
        raise AeromagError(
            f"{option} {shown} holds {int(mask.sum())} samples (need ≥ {MIN_SAMPLES}); "
            f"the flight spans {flight.tt[0]:g}–{flight.tt[-1]:g} s"
        )
    return mask


def find_calibration_line(flight: Flight, line: float | None = None) -> CalibrationLine:
    """The calibration line: ``line`` when given, else found (module docstring).

    Raises
    ------
    AeromagError
        No ``line`` field, the given line is absent, or no line looks like a calibration box.
    """
    if line is not None:
        mask = line_mask(flight, (line,))
        return CalibrationLine(line, mask, "given with --calibration-line")
    if "line" not in flight:
        raise ArgumentError(
            "calibration_line",
            "needs a 'line' field, which this flight has not; give the calibration part as a "
            "calibration window T0 T1 [s] instead",
        )
    ids = flight["line"]
    labelled = _labelled_line(flight, ids)
    if labelled is not None:
        return labelled
    return _most_active_line(flight, ids)


def subset(flight: Flight, mask: np.ndarray, what: str) -> Flight:
    """The samples of ``mask`` as a flight of their own (attributes kept, the selection named
    in the attribute ``selection``)."""
    if mask.sum() < MIN_SAMPLES:
        raise AeromagError(f"{what} keeps {int(mask.sum())} samples (need ≥ {MIN_SAMPLES})")
    fields = {name: values[mask] for name, values in flight.fields.items()}
    return Flight(fields, {**flight.attrs, "selection": what})


def _line_ids(line: np.ndarray) -> list[float]:
    """Distinct finite line ids in order of appearance."""
    finite = line[np.isfinite(line)]
    ids, first = np.unique(finite, return_index=True)
    return [float(v) for v in ids[np.argsort(first)]]


def _labelled_line(flight: Flight, ids: np.ndarray) -> CalibrationLine | None:
    """The line holding most samples inside labelled manoeuvres, if any are labelled."""
    if "maneuver" not in flight:
        return None
    inside = flight.maneuver_ids() > 0
    if not inside.any():
        return None
    values, counts = np.unique(ids[inside & np.isfinite(ids)], return_counts=True)
    if values.size == 0:
        return None
    best = float(values[np.argmax(counts)])
    return CalibrationLine(
        best, ids == best, f"line {best:g} holds the labelled calibration manoeuvres"
    )


def _most_active_line(flight: Flight, ids: np.ndarray) -> CalibrationLine:
    """The line with the most attitude activity among those flown on ≥ MIN_HEADINGS headings."""
    needed = ("ins_roll", "ins_pitch", "ins_yaw")
    if not all(name in flight for name in needed):
        raise ArgumentError(
            "calibration_line",
            "auto needs labelled manoeuvres or the attitude to find them by, which this flight "
            "has not; name the line",
        )
    scores = {v: _activity(flight, ids == v) for v in _line_ids(ids)}
    boxes = {v: s for v, s in scores.items() if s is not None}
    if not boxes:
        raise ArgumentError(
            "calibration_line",
            "auto found no line flown with manoeuvres on several headings; name the line",
        )
    best = max(boxes, key=lambda v: boxes[v])
    return CalibrationLine(
        best,
        ids == best,
        f"line {best:g} has the most roll/pitch activity ({boxes[best]:.2g}° RMS, slow part "
        f"removed) of "
        f"the lines flown on ≥ {MIN_HEADINGS} headings (no labelled manoeuvres)",
    )


def _activity(flight: Flight, mask: np.ndarray) -> float | None:
    """RMS of high-passed roll plus that of pitch [deg] of a line flown on ≥ MIN_HEADINGS
    headings with at least MIN_ACTIVITY_DEG of it, else None."""
    k = np.flatnonzero(mask)
    roll, pitch, yaw = (flight[name][k] for name in ("ins_roll", "ins_pitch", "ins_yaw"))
    ok = np.isfinite(roll) & np.isfinite(pitch) & np.isfinite(yaw)
    if ok.sum() < MIN_SAMPLES:
        return None
    window = 2 * round(ACTIVITY_WINDOW_S * flight.sample_rate_hz / 2) + 1
    activity = 0.0
    for x in (roll[ok], pitch[ok]):
        fast = x - median_filter(x, size=window, mode="nearest")
        activity += float(np.sqrt(np.mean(fast**2)))
    quadrants = np.unique(np.floor(np.mod(yaw[ok] + 45.0, 360.0) / 90.0))
    if quadrants.size < MIN_HEADINGS or activity < MIN_ACTIVITY_DEG:
        return None
    return activity


@dataclass(frozen=True)
class Selected:
    """The part of a flight a run uses (:func:`select`).

    Attributes
    ----------
    flight : the selected samples (the whole flight when nothing was selected)
    keep : (n of the input,) bool, the samples kept
    calibration : (n,) bool over ``flight``: where to fit, None for the whole of it
    report : what was selected and why, for ``report.json``
    """

    flight: Flight
    keep: np.ndarray
    calibration: np.ndarray | None
    report: dict[str, object]


def select(
    flight: Flight,
    lines: tuple[float, ...] | None = None,
    segment_s: tuple[float, float] | None = None,
    calibration_line: float | str | None = None,
    calibration_window: tuple[float, float] | None = None,
) -> Selected:
    """Apply ``--line``, ``--segment`` and ``--calibration-line`` (``"auto"`` or a line id) or
    ``--calibration-window``: the selected lines and segment are kept, together with the
    calibration part, which a fit needs wherever it is in the flight.

    Raises
    ------
    AeromagError
        Both calibration options, or any error of the functions above.
    """
    if calibration_line is not None and calibration_window is not None:
        raise ArgumentError(
            "calibration_line", "cannot be given with a calibration window: give one, not both"
        )
    report: dict[str, object] = {}
    what = []  # the selection in words, for the attribute ``selection``
    keep = np.ones(flight.n, dtype=bool)
    if lines is not None:
        keep &= line_mask(flight, lines)
        report["lines"] = [int(v) if float(v).is_integer() else v for v in lines]
        what.append("lines " + ", ".join(f"{v:g}" for v in lines))
    if segment_s is not None:
        keep &= segment_mask(flight, segment_s)
        report["segment_s"] = list(segment_s)
        what.append(f"segment {segment_s[0]:g}–{segment_s[1]:g} s")
    calibration = None
    if calibration_line is not None:
        given = None if calibration_line == "auto" else float(calibration_line)
        found = find_calibration_line(flight, given)
        calibration = found.mask
        report["calibration_line"] = found.to_dict()
        what.append(f"calibration line {found.line:g}")
    elif calibration_window is not None:
        calibration = segment_mask(flight, calibration_window, "--calibration-window")
        report["calibration_window_s"] = list(calibration_window)
        what.append(f"calibration window {calibration_window[0]:g}–{calibration_window[1]:g} s")
    if calibration is not None and (lines is not None or segment_s is not None):
        keep |= calibration
    report["samples"] = int(keep.sum())
    if keep.all():
        return Selected(flight, keep, calibration, report)
    part = subset(flight, keep, "; ".join(what))
    return Selected(part, keep, None if calibration is None else calibration[keep], report)
