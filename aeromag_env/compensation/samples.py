"""Which samples of a flight a compensator may use: the one place that decides it.

Real files have time gaps, spikes and missing values (:mod:`aeromag_env.flight.quality` finds
them). :func:`flight_samples` turns them into what the compensators and the scoring act on:

* **segments**: the continuous parts of the flight between time gaps
  (:func:`aeromag_env.flight.quality.segments`). Filters, band-passes and derivatives run on each
  segment on its own; the recursive filters continue across a gap (their state is constant
  coefficients), with the rate at a segment's first sample one-sided
  (:func:`aeromag_env.flight.earth_model.field_rate`).
* **valid samples**: a sample is valid when every input the method needs there is finite
  (attitude, position, fluxgate, scalar…) and the magnetometers it uses show no spike there
  (:func:`aeromag_env.flight.quality.spike_flags`). Invalid samples are *flagged*: left out of
  the fits (``lsq``, ``tl``), skipped by the filters' update (predict only), and their
  compensated output is NaN, never a made-up number.
* **runs**: the maximal runs of valid samples inside one segment, what a band-pass can filter
  without crossing a gap or a flagged sample (:meth:`Samples.runs`).

On a flight without gaps, spikes or missing values every sample is valid and there is one
segment: the compensators then compute exactly what they computed before this module existed.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from aeromag_env.flight.data import ATTITUDE_NAMES, POSITION_NAMES, Flight, vector_names
from aeromag_env.flight.quality import runs, segments, spike_flags

#: Times listed per channel (and segments listed) in :meth:`Samples.report`.
MAX_LISTED = 10


@dataclass(frozen=True)
class Samples:
    """The continuous segments and the flagged samples of one flight, for one method.

    Attributes
    ----------
    tt : (n,) time [s]
    segments : continuous parts, as slices in order
    spikes : channel → (n,) bool, spikes found in each magnetometer the method uses
    nonfinite : channel → (n,) bool, non-finite samples of each input the method needs (a vector
        channel such as ``flux_a`` counts a sample when any axis is non-finite)
    valid : (n,) bool, no spike and no non-finite input at that sample
    """

    tt: np.ndarray
    segments: list[slice]
    spikes: dict[str, np.ndarray]
    nonfinite: dict[str, np.ndarray]
    valid: np.ndarray

    @property
    def n_nonfinite(self) -> int:
        """Samples where some needed input is non-finite."""
        bad = np.zeros(self.tt.size, dtype=bool)
        for mask in self.nonfinite.values():
            bad |= mask
        return int(bad.sum())

    def runs(self, ok: np.ndarray | None = None) -> list[slice]:
        """Maximal runs of ``ok`` (default: the valid samples) inside one segment."""
        return runs(self.valid if ok is None else ok, self.segments)

    def report(self) -> dict[str, Any]:
        """Segments and flagged samples as plain data (the ``metrics`` block of report.json).

        ``segments``: ``count`` and the first :data:`MAX_LISTED` ``spans_s`` ``[t0, t1]`` [s];
        ``flagged_samples``: ``count`` (samples not valid) and, per channel with a flag, its
        ``spikes`` and ``nonfinite`` counts and the first :data:`MAX_LISTED` ``times_s`` [s].
        """
        spans = [[float(self.tt[s.start]), float(self.tt[s.stop - 1])] for s in self.segments]
        channels = {}
        for name in dict.fromkeys([*self.spikes, *self.nonfinite]):
            spike = self.spikes.get(name, np.zeros(self.tt.size, bool))
            bad = self.nonfinite.get(name, np.zeros(self.tt.size, bool))
            if spike.any() or bad.any():
                channels[name] = {
                    "spikes": int(spike.sum()),
                    "nonfinite": int(bad.sum()),
                    "times_s": self.tt[spike | bad][:MAX_LISTED].tolist(),
                }
        return {
            "segments": {"count": len(self.segments), "spans_s": spans[:MAX_LISTED]},
            "flagged_samples": {"count": int(np.sum(~self.valid)), "channels": channels},
        }


def flight_samples(flight: Flight, inputs: list[str], magnetic: list[str]) -> Samples:
    """Segments and valid samples of ``flight`` for a method.

    Parameters
    ----------
    flight : Flight
    inputs : field names or vector prefixes (``"flux_a"``) the method needs at every sample;
        names absent from the flight are ignored
    magnetic : magnetometers searched for spikes (fluxgate prefixes, scalar names), a subset
        of ``inputs``

    Returns
    -------
    Samples
    """
    parts = segments(flight.tt)
    nonfinite = {}
    for name in inputs:
        columns = vector_names(name) if f"{name}_x" in flight else (name,)
        if all(c in flight for c in columns):
            nonfinite[name] = ~np.all([np.isfinite(flight[c]) for c in columns], axis=0)
    spikes = spike_flags(flight, [m for m in magnetic if m in nonfinite])
    bad = np.zeros(flight.n, dtype=bool)
    for mask in (*nonfinite.values(), *spikes.values()):
        bad |= mask
    return Samples(flight.tt, parts, spikes, nonfinite, ~bad)


def vector_inputs(flight: Flight, flux: str) -> list[str]:
    """What a vector method needs at each sample: the fluxgate, attitude, position, altitude
    channel and, when present, the ``diurnal`` channel (it enters the model Earth field)."""
    alt = flight.altitude_name()
    extra = [nm for nm in (alt, "diurnal") if nm is not None and nm in flight]
    return [flux, *ATTITUDE_NAMES, *POSITION_NAMES, *extra]


def within(parts: list[slice], start: int, stop: int) -> list[slice]:
    """``parts`` clipped to ``start … stop − 1`` and shifted to start at 0 (empty ones left out):
    the segments of ``x[start:stop]``."""
    out = []
    for p in parts:
        a, b = max(p.start, start), min(p.stop, stop)
        if b > a:
            out.append(slice(a - start, b - start))
    return out
