"""Small plausible flights built directly from IGRF and an attitude series (no simulator).

Provenance: 10 Hz, 60 m/s near 45°N 75°W at 3000 m on 2020-06-01; the fluxgate ``flux_a`` is
IGRF-14 (``earth.igrf_ned``) rotated into the body frame with ``frames.dcm_from_euler`` /
``nav_to_body`` plus a constant cabin offset of a few hundred nT and 1 nT white noise; the scalar
``mag_1_uc`` is the IGRF magnitude plus 0.1 nT noise.
"""

from __future__ import annotations

import json

import numpy as np

from aeromag_env.flight.data import ATTITUDE_NAMES, Flight
from aeromag_env.geo.earth import igrf_ned
from aeromag_env.geo.frames import dcm_from_euler, nav_to_body

DATE = "2020-06-01"
FS_HZ = 10.0
SPEED_M_S = 60.0
OFFSET_NT = np.array([300.0, -200.0, 150.0])  # constant cabin field at the fluxgate [nT]
_M_PER_DEG = 111_195.0  # metres per degree of latitude (spherical Earth; enough for a track)


def flight_from_attitude(
    roll_deg: np.ndarray, pitch_deg: np.ndarray, yaw_deg: np.ndarray, seed: int = 0
) -> Flight:
    """A complete flight whose track, fluxgate and scalar follow the given attitude [deg]."""
    rng = np.random.default_rng(seed)
    n = yaw_deg.size
    tt = np.arange(n) / FS_HZ
    yaw = np.deg2rad(yaw_deg)
    north = np.cumsum(SPEED_M_S * np.cos(yaw) / FS_HZ)  # [m]
    east = np.cumsum(SPEED_M_S * np.sin(yaw) / FS_HZ)  # [m]
    lat = 45.0 + north / _M_PER_DEG
    lon = -75.0 + east / (_M_PER_DEG * np.cos(np.deg2rad(45.0)))
    alt = np.full(n, 3000.0)
    b_ned = igrf_ned(np.deg2rad(lat), np.deg2rad(lon), alt, DATE)
    c_nb = dcm_from_euler(np.deg2rad(roll_deg), np.deg2rad(pitch_deg), yaw)
    flux = nav_to_body(c_nb, b_ned) + OFFSET_NT + rng.normal(0.0, 1.0, (n, 3))
    maneuver = np.zeros(n)
    for mid, (t0, t1) in enumerate([(5.0, 10.0), (55.0, 60.0), (70.0, 80.0)], start=1):
        maneuver[(tt >= t0) & (tt <= t1)] = mid
    fields = {
        "tt": tt,
        "lat": lat,
        "lon": lon,
        "alt": alt,
        "ins_roll": roll_deg,
        "ins_pitch": pitch_deg,
        "ins_yaw": yaw_deg,
        "flux_a_x": flux[:, 0],
        "flux_a_y": flux[:, 1],
        "flux_a_z": flux[:, 2],
        "mag_1_uc": np.linalg.norm(b_ned, axis=1) + rng.normal(0.0, 0.1, n),
        "cur_strb": 5.0 + rng.normal(0.0, 0.1, n),
        "maneuver": maneuver,
        "line": np.where(tt < 45.0, 1001.0, 1002.0),
    }
    config = json.dumps({"preset": "test", "seed": seed, "speed_m_s": SPEED_M_S})
    return Flight(
        {k: np.asarray(v, dtype=np.float64) for k, v in fields.items()},
        {"date": DATE, "config": config},
    )


def turning_flight(seed: int = 0, n: int = 900) -> Flight:
    """North, a 180° right turn banked 25° (20–50 s), then south; attitude in degrees."""
    tt = np.arange(n) / FS_HZ
    turning = (tt > 20.0) & (tt < 50.0)
    yaw = np.clip((tt - 20.0) * 6.0, 0.0, 180.0) + 0.5 * np.sin(0.3 * tt)
    roll = np.where(turning, 25.0, 0.0) + 1.0 * np.sin(0.7 * tt)
    pitch = 2.0 + 1.0 * np.sin(0.4 * tt)
    return flight_from_attitude(roll, pitch, yaw, seed)


def northbound_flight(seed: int = 0, n: int = 600) -> Flight:
    """A straight northbound line in degrees: every angle is small (|yaw| ≤ 2.5°, span 5°)."""
    tt = np.arange(n) / FS_HZ
    yaw = 2.5 * np.sin(2.0 * np.pi * tt / 30.0)
    roll = 1.0 * np.sin(0.7 * tt)
    pitch = 2.0 + 0.5 * np.sin(0.4 * tt)
    return flight_from_attitude(roll, pitch, yaw, seed)


def with_fields(flight: Flight, **changes: np.ndarray | None) -> Flight:
    """Copy with fields replaced (an array) or removed (None); order kept, new ones appended."""
    fields = {k: v.copy() for k, v in flight.fields.items()}
    for name, values in changes.items():
        if values is None:
            fields.pop(name, None)
        else:
            fields[name] = np.asarray(values, dtype=np.float64)
    return Flight(fields, dict(flight.attrs))


def only(flight: Flight, *names: str) -> Flight:
    """Copy with only the named fields, in the order given."""
    return Flight({nm: flight[nm].copy() for nm in names}, dict(flight.attrs))


def in_radians(flight: Flight) -> Flight:
    """Copy with the attitude fields converted to radians (the unit mistake under test)."""
    return with_fields(flight, **{nm: np.deg2rad(flight[nm]) for nm in ATTITUDE_NAMES})
