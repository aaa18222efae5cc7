"""The model Earth field along a flight: what a fluxgate should read if the aircraft were clean.

IGRF-14 at the flight's positions and date (:mod:`aeromag_env.geo.earth`), plus the base
station's ``diurnal`` along the main field, rotated into the body frame by the INS attitude. The
compensators take ``y = T_m − T`` against it, and the fluxgate mount is estimated against it.

The rate ``Ṫ`` never differences across a time gap or a missing sample: it is computed on each run
of finite field samples inside each continuous segment (:func:`field_rate`). The first sample of
a run takes the one-sided difference, as the first sample of a flight always has: the
``backward`` scheme copies the second sample's rate (so that one sample is not strictly causal),
the ``central`` scheme uses its second-order one-sided formula. A run of a single sample has no
rate (NaN). On a flight without gaps or missing samples this is the plain
:func:`~aeromag_env.geo.frames.time_derivative`.
"""

from __future__ import annotations

import datetime as _dt

import numpy as np

from aeromag_env.flight.data import POSITION_NAMES, Flight
from aeromag_env.flight.quality import runs, segments
from aeromag_env.geo.earth import igrf_ned, igrf_ned_along_track
from aeromag_env.geo.frames import dcm_from_euler, nav_to_body, time_derivative

#: Median relative disagreement between the measured field magnitude and IGRF-14 above which
#: the position, date or units are suspect [-]. Aircraft interference is at most a few % of
#: the Earth field (hundreds to ~2000 nT against 22 000–67 000 nT) and crustal anomalies at
#: survey altitude rarely reach 5 %; lat/lon in radians (a position near 0°N 0°E), a wrong
#: date (decades of secular variation, or a two-digit year) or a field in another unit move
#: the model or the measurement by far more.
MODEL_MISMATCH_FRACTION = 0.2
#: Samples compared, evenly spread over the finite ones (IGRF synthesis costs ~µs a point).
_MISMATCH_POINTS = 200


def earth_model_ned(flight: Flight) -> np.ndarray:
    """Model Earth field in NED (n, 3) [nT]: IGRF-14 plus ``diurnal`` along the main field.

    NaN where the position is not finite. Raises KeyError without position or without a date
    the model can use (unreadable, or outside IGRF-14's years: :meth:`Flight.date` says why, and
    the message repeats it): the callers that can do without the model (``tl``'s residual
    against it) treat both alike.
    """
    lat, lon, alt = flight.position_rad()
    date = model_date(flight)
    ok = np.isfinite(flight.tt) & np.isfinite(lat) & np.isfinite(lon) & np.isfinite(alt)
    t_n = np.full((flight.n, 3), np.nan)
    t_n[ok] = igrf_ned_along_track(flight.tt[ok], lat[ok], lon[ok], alt[ok], date)
    if "diurnal" in flight:  # a base station sees the external field along the main field
        t_n += (t_n / np.linalg.norm(t_n, axis=1, keepdims=True)) * flight["diurnal"][:, None]
    return t_n


def model_date(flight: Flight) -> _dt.datetime:
    """The flight's date for the Earth-field model; KeyError without one it can use."""
    try:
        return flight.date()
    except (ValueError, OverflowError) as exc:
        raise KeyError(f"no usable date: {exc}") from exc


def earth_model(
    flight: Flight, scheme: str = "backward", parts: list[slice] | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Model Earth field in body axes and its rate, (n, 3) [nT] and [nT/s]; NaN where unknown.

    ``parts`` are the flight's continuous segments (default:
    :func:`aeromag_env.flight.quality.segments` of its time); the rate is :func:`field_rate`.
    """
    t_b = nav_to_body(dcm_from_euler(*flight.attitude_rad()), earth_model_ned(flight))
    parts = segments(flight.tt) if parts is None else parts
    return t_b, field_rate(t_b, flight.tt, scheme, parts)


def field_rate(x: np.ndarray, tt: np.ndarray, scheme: str, parts: list[slice]) -> np.ndarray:
    """Time derivative of ``x`` (n, 3) on each run of finite rows inside each of ``parts`` [x/s].

    NaN on non-finite rows and on runs of one sample (no neighbour to difference with).
    """
    ok = np.all(np.isfinite(x), axis=1)
    found = runs(ok, parts)
    if len(found) == 1 and found[0] == slice(0, x.shape[0]):
        return time_derivative(x, tt, scheme)  # one uninterrupted run: the whole flight
    rate = np.full(x.shape, np.nan)
    for run in found:
        if run.stop - run.start > 1:
            rate[run] = time_derivative(x[run], tt[run], scheme)
    return rate


def model_mismatch(flight: Flight, scalar: str | None, fluxgate: str | None) -> str | None:
    """A one-line warning when the measured field disagrees with IGRF-14, else None.

    The measured magnitude is the scalar magnetometer's (``scalar``), else the fluxgate's
    (``fluxgate``, a prefix); the model's is IGRF-14 at the file's positions and date, at up to
    200 samples where both are finite. A median relative disagreement above
    :data:`MODEL_MISMATCH_FRACTION` names what to check. None too when the file lacks what the
    comparison needs (position, a usable date, a magnetometer): other checks report those.
    """
    name = scalar or fluxgate
    has_position = flight.altitude_name() is not None and all(nm in flight for nm in POSITION_NAMES)
    if name is None or not has_position:
        return None
    try:
        date = model_date(flight)
    except KeyError:
        return None
    with np.errstate(over="ignore"):  # |1e200 nT| is implausible (validation), not warned on
        measured = np.abs(flight[name]) if scalar else np.linalg.norm(flight.vector(name), axis=1)
    lat, lon, alt = flight.position_rad()
    ok = np.isfinite(measured) & (np.abs(lat) <= np.pi / 2) & np.isfinite(lon) & np.isfinite(alt)
    k = np.flatnonzero(ok)
    if k.size == 0:
        return None
    k = k[np.unique(np.linspace(0, k.size - 1, min(k.size, _MISMATCH_POINTS)).round().astype(int))]
    model = np.linalg.norm(igrf_ned(lat[k], lon[k], alt[k], date), axis=1)
    apart = float(np.median(np.abs(measured[k] - model) / model))
    if not apart > MODEL_MISMATCH_FRACTION:
        return None
    return (
        f"{name} reads a median {np.median(measured[k]):.0f} nT where IGRF-14 at the file's "
        f"position and date gives {np.median(model):.0f} nT, {100 * apart:.0f} % apart (more than "
        f"{100 * MODEL_MISMATCH_FRACTION:.0f} %; aircraft interference is a few %): check that lat "
        f"and lon are in degrees, alt in metres and the date ({date.date().isoformat()}) right"
    )
