"""The sample checks of a calibrated model's application, the same for a file and for a stream.

Applying a :class:`~aeromag_env.compensation.calibration_model.CalibrationModel` must give the
same numbers whether the flight comes as a file or one sample at a time
(:mod:`aeromag_env.compensation.model_apply`), so its checks look at most one sample ahead and
use only what the model fixed at calibration (a file's own checks,
:mod:`aeromag_env.compensation.samples`, look at the whole flight):

* **gap**: a time step above ``gap_factor / sample_rate_hz`` [s] (the calibration flight's rate)
  starts a new continuous segment; differences never cross it.
* **non-finite**: a magnetometer sample with a non-finite value is flagged.
* **spike**: a sample that stands out from *both* neighbours of its segment in the same
  direction by more than the magnetometer's threshold [nT] (:func:`spike_statistic` above
  :func:`spike_threshold_nt`). A step, a ramp or a manoeuvre does not (one of the two differences
  is small, or they have opposite signs); a single wild sample does, and its neighbours do not.

A flagged sample's output is NaN in a file and a reported, skipped line in a stream.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from aeromag_env.flight.quality import GAP_FACTOR, SPIKE_FLOOR_NT

#: A spike stands out from both neighbours SPIKE_MARGIN times more than the calibration flight's
#: 99.9th percentile of the same statistic [-] (the box's manoeuvres are the most violent the
#: aircraft flies; 0.1 % leaves room for the calibration's own spikes).
SPIKE_MARGIN = 10.0
#: The percentile of the calibration's spike statistic the threshold scales [%].
SPIKE_PERCENTILE = 99.9
__all__ = [
    "GAP_FACTOR",
    "SampleChecks",
    "segment_starts",
    "spike_flags",
    "spike_statistic",
    "spike_threshold_nt",
    "stands_out",
]


@dataclass(frozen=True)
class SampleChecks:
    """The checks a calibrated model applies to every sample, fixed at calibration.

    Attributes
    ----------
    gap_s : float
        A time step above this is a gap [s] (``gap_factor / sample_rate_hz`` of the calibration).
    spike_threshold_nt : dict
        Magnetometer name → its spike threshold [nT] (:func:`spike_threshold_nt`).
    """

    gap_s: float
    spike_threshold_nt: dict[str, float]

    def starts(self, tt: np.ndarray) -> np.ndarray:
        """(n,) bool: the segment starts of the times ``tt`` [s] (:func:`segment_starts`)."""
        return segment_starts(tt, self.gap_s)

    def usable(self, name: str, x: np.ndarray, starts: np.ndarray) -> np.ndarray:
        """(n,) bool: magnetometer ``name``'s samples ``x`` ((n,) or (n, 3)) [nT] are finite
        and no spike."""
        finite = np.isfinite(x) if x.ndim == 1 else np.all(np.isfinite(x), axis=1)
        return finite & ~spike_flags(x, starts, self.spike_threshold_nt[name])

    def usable_one(
        self, name: str, x: np.ndarray, prev: np.ndarray | None, nxt: np.ndarray | None
    ) -> bool:
        """Whether one sample ``x`` of magnetometer ``name`` is usable, given its neighbours in
        its segment (None where there is none): the verdict :meth:`usable` gives it in a file."""
        if not bool(np.all(np.isfinite(x))):
            return False
        if prev is None or nxt is None:
            return True
        return not stands_out(x, prev, nxt) > self.spike_threshold_nt[name]


def segment_starts(tt: np.ndarray, gap_s: float) -> np.ndarray:
    """(n,) bool: sample k starts a continuous segment (the first sample, or after a step above
    ``gap_s`` [s])."""
    starts = np.ones(tt.size, dtype=bool)
    starts[1:] = np.diff(tt) > gap_s
    return starts


def spike_statistic(x: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """How far each sample stands out from both neighbours in one direction [x's unit].

    Parameters
    ----------
    x : ndarray, shape (n,) or (n, m)
        A magnetometer series (a vector one per axis) [nT].
    starts : ndarray, shape (n,)
        Segment starts (:func:`segment_starts`).

    Returns
    -------
    ndarray, shape (n,)
        ``min(|x_k − x_{k−1}|, |x_k − x_{k+1}|)`` where both differences have one sign and both
        neighbours are in the sample's segment, else 0; the largest over the axes. Non-finite
        samples and neighbours give 0 (they are flagged as non-finite, not as spikes).
    """
    x2 = x.reshape(x.shape[0], -1)
    out = np.zeros(x2.shape[0])
    if x2.shape[0] < 3:
        return out
    back = x2[1:-1] - x2[:-2]
    ahead = x2[1:-1] - x2[2:]
    with np.errstate(invalid="ignore"):
        same = (np.sign(back) == np.sign(ahead)) & (back != 0)
        stat = np.where(same, np.minimum(np.abs(back), np.abs(ahead)), 0.0)
    stat = np.where(np.isfinite(stat), stat, 0.0).max(axis=1)
    joined = ~starts[1:-1] & ~starts[2:]  # k−1, k and k+1 in one segment
    out[1:-1] = np.where(joined, stat, 0.0)
    return out


def stands_out(x: np.ndarray, prev: np.ndarray, nxt: np.ndarray) -> float:
    """:func:`spike_statistic` of one sample ``x`` (a scalar or (3,)) between its neighbours
    ``prev`` and ``nxt`` [nT] (the same arithmetic)."""
    back = np.atleast_1d(x - prev)
    ahead = np.atleast_1d(x - nxt)
    with np.errstate(invalid="ignore"):
        same = (np.sign(back) == np.sign(ahead)) & (back != 0)
        stat = np.where(same, np.minimum(np.abs(back), np.abs(ahead)), 0.0)
    return float(np.where(np.isfinite(stat), stat, 0.0).max())


def spike_flags(x: np.ndarray, starts: np.ndarray, threshold_nt: float) -> np.ndarray:
    """(n,) bool: the spikes of ``x`` (:func:`spike_statistic` above ``threshold_nt`` [nT])."""
    return spike_statistic(x, starts) > threshold_nt


def spike_threshold_nt(x: np.ndarray, starts: np.ndarray) -> float:
    """The spike threshold a calibration flight's series ``x`` sets [nT]: :data:`SPIKE_MARGIN`
    × its :data:`SPIKE_PERCENTILE` th percentile of :func:`spike_statistic`, at least
    :data:`~aeromag_env.flight.quality.SPIKE_FLOOR_NT`."""
    stat = spike_statistic(x, starts)
    level = float(np.percentile(stat, SPIKE_PERCENTILE)) if stat.size else 0.0
    return max(SPIKE_FLOOR_NT, SPIKE_MARGIN * level)
