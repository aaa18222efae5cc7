"""Faults of real flight files that the readers let through: time gaps and spikes.

A real file is not a simulator's: the logger drops seconds (a *gap*: a time step well above the
file's usual one), and a magnetometer throws single wild samples (*spikes*). Neither is an error
of the file, and both ruin a filter, a band-pass or a derivative that runs across them, silently.
This module finds them, and every reader's validation warns about them
(:func:`aeromag_env.flight.validation.validate`), so ``aeromag info``, ``compensate`` and
``discover`` say so. The compensators run filters, band-passes and derivatives on each
continuous segment and leave flagged samples out (:mod:`aeromag_env.compensation.samples`).

* Gaps: a step ``tt[k] − tt[k−1]`` above :data:`GAP_FACTOR` times the median step. The flight
  splits into continuous segments there (:func:`segments`).
* Spikes: a Hampel-type test per continuous segment (Pearson 2002). A sample is flagged when it
  stands out from the :data:`NEIGHBOURS` samples on *both* sides and their straight-line trend (a
  manoeuvre or a step does not; a spike does, :func:`two_sided_residual`) by more than
  :data:`HAMPEL_SIGMAS` robust standard deviations and :data:`SPIKE_FLOOR_NT`. The robust standard
  deviation is 1.4826 × the median absolute difference from the neighbours' median over the
  :data:`HAMPEL_WINDOW_S` window around the sample (or over the whole segment where that is
  larger): noise and manoeuvre curvature raise it, a single spike does not.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from aeromag_env.flight.data import MAX_MANEUVER_ID, Flight, vector_names
from aeromag_env.units import WGS84_A_M

#: A time step above this many median steps is a gap [-].
GAP_FACTOR = 3.0
#: Hampel window (centred) [s], threshold [robust σ] and absolute floor [nT].
HAMPEL_WINDOW_S = 2.0
HAMPEL_SIGMAS = 12.0
#: Samples on each side a spike must stand out from [samples].
NEIGHBOURS = 2
SPIKE_FLOOR_NT = 10.0
#: Robust σ of a normal distribution per MAD [-].
MAD_TO_SIGMA = 1.4826


@dataclass(frozen=True)
class Gap:
    """A time gap: samples ``index − 1`` and ``index`` are ``duration_s`` apart."""

    index: int
    t_start_s: float
    t_end_s: float

    @property
    def duration_s(self) -> float:
        """Time between the two samples [s]."""
        return self.t_end_s - self.t_start_s

    def to_dict(self) -> dict[str, float | int]:
        return {
            "index": self.index,
            "t_start_s": self.t_start_s,
            "t_end_s": self.t_end_s,
            "duration_s": self.duration_s,
        }


def find_gaps(tt: np.ndarray) -> list[Gap]:
    """The gaps of a strictly increasing time series ``tt`` (n,) [s]."""
    if tt.size < 3:
        return []
    dt = np.diff(tt)
    big = np.flatnonzero(dt > GAP_FACTOR * np.median(dt))
    return [Gap(int(k) + 1, float(tt[k]), float(tt[k + 1])) for k in big]


def segments(tt: np.ndarray) -> list[slice]:
    """The continuous segments of ``tt`` (n,): slices between the gaps, in order."""
    edges = [0, *(g.index for g in find_gaps(tt)), tt.size]
    return [slice(a, b) for a, b in itertools.pairwise(edges)]


def runs(ok: np.ndarray, parts: list[slice] | None = None) -> list[slice]:
    """Maximal runs of ``True`` in ``ok`` (n,) that lie inside one of ``parts`` (default: the
    whole series), as slices in order: where a filter or a derivative may run uninterrupted."""
    ok = np.asarray(ok, dtype=bool)
    out = []
    for part in parts if parts is not None else [slice(0, ok.size)]:
        start = part.start or 0
        edges = np.diff(np.concatenate([[0], ok[part].astype(np.int8), [0]]))
        starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
        out += [slice(start + int(a), start + int(b)) for a, b in zip(starts, stops, strict=True)]
    return out


def hampel_flags(x: np.ndarray, window: int) -> np.ndarray:
    """Spikes of one continuous series ``x`` (n,): bool (n,), True where flagged.

    ``window`` [samples] is the full (odd) window of the robust scale. Non-finite samples are
    never flagged (they are missing already); the :data:`NEIGHBOURS` samples at each end are
    not tested (a trend and a spike look alike there).
    """
    from scipy.ndimage import median_filter  # lazy: keeps `import aeromag_env` light

    ok = np.isfinite(x)
    flags = np.zeros(x.shape, dtype=bool)
    m = NEIGHBOURS
    if ok.sum() < 2 * m + 3:
        return flags
    xf = np.where(ok, x, np.interp(np.arange(x.size), np.flatnonzero(ok), x[ok]))
    spread = np.abs(xf - neighbour_median(xf, m))  # noise and curvature, spikes included
    local = median_filter(spread, size=window, mode="reflect")
    scale = MAD_TO_SIGMA * np.maximum(local, np.median(spread))  # never below the series
    dev = np.abs(two_sided_residual(xf))
    flags[ok] = (dev[ok] > HAMPEL_SIGMAS * scale[ok]) & (dev[ok] > SPIKE_FLOOR_NT)
    flags[:m] = flags[-m:] = False
    return flags


def neighbour_median(x: np.ndarray, m: int) -> np.ndarray:
    """Median of the ``m`` samples either side of each sample, the sample itself left out (n,);
    the ends are mirrored."""
    padded = np.pad(x, m, mode="reflect")
    windows = np.lib.stride_tricks.sliding_window_view(padded, 2 * m + 1)
    return np.median(np.delete(windows, m, axis=1), axis=1)


def two_sided_residual(x: np.ndarray) -> np.ndarray:
    """How far each sample stands out from both sides (n,): the smaller of its differences from
    the straight-line extrapolations of the two samples before and of the two after, when the
    two differences have the same sign, else 0. A spike stands out from both sides; a step, a
    ramp or a turn, from one side at most. The first and last two samples get 0."""
    out = np.zeros(x.shape)
    if x.size < 5:
        return out
    centre = x[2:-2]
    with np.errstate(over="ignore"):  # a sample near the float64 limit: ±inf, still a spike
        left = centre - (2.0 * x[1:-3] - x[:-4])  # x[k] − (2 x[k−1] − x[k−2])
        right = centre - (2.0 * x[3:-1] - x[4:])  # x[k] − (2 x[k+1] − x[k+2])
    same = np.sign(left) == np.sign(right)
    out[2:-2] = np.where(same, np.sign(left) * np.minimum(np.abs(left), np.abs(right)), 0.0)
    return out


def spike_flags(flight: Flight, channels: list[str]) -> dict[str, np.ndarray]:
    """Hampel flags (n,) bool per channel name, each run per continuous segment.

    ``channels`` are field names or vector prefixes (``"flux_a"``: a sample is flagged when any
    axis is).
    """
    rate = flight.sample_rate_hz
    window = max(3, round(HAMPEL_WINDOW_S * rate) | 1) if np.isfinite(rate) else 3
    parts = segments(flight.tt)
    out = {}
    for name in channels:
        columns = vector_names(name) if f"{name}_x" in flight else (name,)
        flags = np.zeros(flight.n, dtype=bool)
        for column in columns:
            values = flight[column]
            for seg in parts:
                flags[seg] |= hampel_flags(values[seg], window)
        out[name] = flags
    return out


def magnetic_channels(flight: Flight) -> list[str]:
    """The channels spikes are searched in: every fluxgate and uncompensated scalar present."""
    return [*flight.fluxgates(), *flight.scalars()]


def fault_report(flight: Flight, max_listed: int = 10) -> dict[str, object]:
    """Gaps and spikes as plain data for ``info`` and ``report.json``."""
    gaps = find_gaps(flight.tt)
    spikes = spike_flags(flight, magnetic_channels(flight))
    return {
        "segments": len(gaps) + 1,
        "gaps": [g.to_dict() for g in gaps[:max_listed]],
        "gap_count": len(gaps),
        "spikes": {
            name: {"count": int(f.sum()), "times_s": flight.tt[f][:max_listed].tolist()}
            for name, f in spikes.items()
            if f.any()
        },
        "bad_maneuver_labels": int(flight.bad_maneuver_labels().sum()),
    }


def fault_problems(report: dict[str, object]) -> list[str]:
    """One warning line per kind of fault in a :func:`fault_report`."""
    problems = []
    gaps = report["gaps"]
    assert isinstance(gaps, list)
    if gaps:
        listed = ", ".join(
            f"{g['duration_s']:.3g} s at t = {g['t_start_s']:.6g} s" for g in gaps[:3]
        )
        problems.append(
            f"{report['gap_count']} time gap(s) ({listed}): the flight is compensated as "
            f"{report['segments']} continuous segments (filters, band-passes and derivatives "
            "restart at each)"
        )
    spikes = report["spikes"]
    assert isinstance(spikes, dict)
    for name, entry in spikes.items():
        times = ", ".join(f"{t:.6g}" for t in entry["times_s"][:3])
        problems.append(
            f"{name}: {entry['count']} spike(s) (t = {times} s…), flagged: left out wherever "
            f"{name} is used (fits, filter updates; the compensated output there is NaN)"
        )
    bad = report.get("bad_maneuver_labels", 0)
    if bad:
        problems.append(
            f"maneuver: {bad} sample(s) hold labels that are not window ids (whole numbers "
            f"0–{MAX_MANEUVER_ID}); read as 0 (outside any manoeuvre)"
        )
    return problems


#: Ground speeds an aircraft flies at [m/s]: a survey drone's 2 m/s to well above any survey
#: aircraft's 100 m/s. A median outside says that ``tt`` or the position is in another unit
#: (time in ms: 1000× slower; lat/lon in radians read as degrees: 57× slower).
GROUND_SPEED_RANGE_M_S = (2.0, 350.0)


def ground_speed(flight: Flight) -> np.ndarray:
    """Ground speed between consecutive samples (n − 1,) [m/s] from ``lat``, ``lon`` [deg] and
    ``tt`` [s]: the spherical (equirectangular) distance over the time step, accurate to well
    under 1 % at survey spacings; NaN or inf where a position is not finite or a step is not
    positive."""
    lat, lon, tt = np.deg2rad(flight["lat"]), np.deg2rad(flight["lon"]), flight.tt
    with np.errstate(invalid="ignore", divide="ignore"):
        d_north = np.diff(lat) * WGS84_A_M
        d_lon = (np.diff(lon) + np.pi) % (2 * np.pi) - np.pi  # across the antimeridian
        d_east = d_lon * WGS84_A_M * np.cos(lat[1:])
        return np.asarray(np.hypot(d_north, d_east) / np.diff(tt))


def ground_speed_problem(flight: Flight) -> str | None:
    """A one-line warning when the median :func:`ground_speed` is outside
    :data:`GROUND_SPEED_RANGE_M_S`; None otherwise or without ``lat`` and ``lon``."""
    if not all(name in flight for name in ("lat", "lon")):
        return None
    speed = ground_speed(flight)
    speed = speed[np.isfinite(speed) & (np.diff(flight.tt) > 0)]
    if speed.size == 0:
        return None
    median = float(np.median(speed))
    low, high = GROUND_SPEED_RANGE_M_S
    if low <= median <= high:
        return None
    return (
        f"median ground speed {median:.3g} m/s from lat, lon and tt, outside the {low:g}–{high:g} "
        "m/s an aircraft flies: check that tt is in seconds and lat and lon in degrees"
    )
