"""The model Earth field along a flight: what a fluxgate should read if the aircraft were clean.

IGRF-14 at the flight's positions and date (:mod:`aeromag_env.geo.earth`), plus the base
station's ``diurnal`` along the main field, rotated into the body frame by the INS attitude. The
compensators take ``y = T_m − T`` against it, and the fluxgate mount is estimated against it.
"""

from __future__ import annotations

import numpy as np

from aeromag_env.flight.data import Flight
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


def earth_model(flight: Flight, scheme: str = "backward") -> tuple[np.ndarray, np.ndarray]:
    """Model Earth field in body axes and its rate, (n, 3) [nT] and [nT/s]; NaN where unknown."""
    t_b = nav_to_body(dcm_from_euler(*flight.attitude_rad()), earth_model_ned(flight))
    return t_b, time_derivative(t_b, flight.tt, scheme)
