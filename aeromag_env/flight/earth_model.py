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

import numpy as np

from aeromag_env.flight.data import Flight
from aeromag_env.flight.quality import runs, segments
from aeromag_env.geo.earth import igrf_ned_along_track
from aeromag_env.geo.frames import dcm_from_euler, nav_to_body, time_derivative


def earth_model_ned(flight: Flight) -> np.ndarray:
    """Model Earth field in NED (n, 3) [nT]: IGRF-14 plus ``diurnal`` along the main field.

    NaN where the position is not finite. Raises KeyError without position or date.
    """
    lat, lon, alt = flight.position_rad()
    ok = np.isfinite(flight.tt) & np.isfinite(lat) & np.isfinite(lon) & np.isfinite(alt)
    t_n = np.full((flight.n, 3), np.nan)
    t_n[ok] = igrf_ned_along_track(flight.tt[ok], lat[ok], lon[ok], alt[ok], flight.date())
    if "diurnal" in flight:  # a base station sees the external field along the main field
        t_n += (t_n / np.linalg.norm(t_n, axis=1, keepdims=True)) * flight["diurnal"][:, None]
    return t_n


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
