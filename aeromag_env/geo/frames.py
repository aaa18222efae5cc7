"""Rotations between the body (FRD) and navigation (NED) frames, and time derivatives.

Conventions are those of :mod:`aeromag_env.units`: aerospace ZYX Euler angles (yaw, pitch, roll),
``C_nb`` rotates body → NED.
"""

from __future__ import annotations

import numpy as np

from aeromag_env.units import WGS84_A_M, WGS84_E2


def dcm_from_euler(roll: np.ndarray, pitch: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """Body → NED rotation matrices from ZYX Euler angles.

    Parameters
    ----------
    roll, pitch, yaw : ndarray, shape (n,)
        Attitude [rad].

    Returns
    -------
    C_nb : ndarray, shape (n, 3, 3)
        ``C_nb = R_z(yaw) @ R_y(pitch) @ R_x(roll)``, so ``v_n = C_nb @ v_b``. NaN where an
        angle is not finite (±inf included: the samples the callers flag, without a warning).
    """
    with np.errstate(invalid="ignore"):  # sin/cos(±inf) = NaN, as NaN gives NaN: no warning
        cr, sr = np.cos(roll), np.sin(roll)
        cp, sp = np.cos(pitch), np.sin(pitch)
        cy, sy = np.cos(yaw), np.sin(yaw)
    c = np.empty((np.size(roll), 3, 3))
    c[:, 0, 0] = cp * cy
    c[:, 0, 1] = sr * sp * cy - cr * sy
    c[:, 0, 2] = cr * sp * cy + sr * sy
    c[:, 1, 0] = cp * sy
    c[:, 1, 1] = sr * sp * sy + cr * cy
    c[:, 1, 2] = cr * sp * sy - sr * cy
    c[:, 2, 0] = -sp
    c[:, 2, 1] = sr * cp
    c[:, 2, 2] = cr * cp
    return c


def euler_from_dcm(c_nb: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Inverse of :func:`dcm_from_euler` (pitch in [-π/2, π/2], yaw in (-π, π]) [rad]."""
    roll = np.arctan2(c_nb[:, 2, 1], c_nb[:, 2, 2])
    pitch = -np.arcsin(np.clip(c_nb[:, 2, 0], -1.0, 1.0))
    yaw = np.arctan2(c_nb[:, 1, 0], c_nb[:, 0, 0])
    return roll, pitch, yaw


def nav_to_body(c_nb: np.ndarray, v_n: np.ndarray) -> np.ndarray:
    """Rotate NED vectors into the body frame: ``v_b = C_nb^T v_n``.

    Shapes: ``c_nb`` (n, 3, 3), ``v_n`` (n, 3) → (n, 3).
    """
    return np.einsum("kji,kj->ki", c_nb, v_n)


def body_to_nav(c_nb: np.ndarray, v_b: np.ndarray) -> np.ndarray:
    """Rotate body vectors into NED: ``v_n = C_nb v_b``. Shapes (n, 3, 3), (n, 3) → (n, 3)."""
    return np.einsum("kij,kj->ki", c_nb, v_b)


def time_derivative(x: np.ndarray, tt: np.ndarray, scheme: str = "central") -> np.ndarray:
    """Time derivative of a sampled series along axis 0 [unit of x per s].

    Parameters
    ----------
    x : ndarray, shape (n,) or (n, m)
    tt : ndarray, shape (n,)
        Sample times [s], strictly increasing.
    scheme : {"central", "backward"}
        ``central``: second-order central differences (one-sided second order at the ends;
        ``numpy.gradient``), for offline use and for the simulator's eddy field.
        ``backward``: ``(x[k] - x[k-1]) / (t[k] - t[k-1])``, causal, for online filters; the
        first sample copies the second.

    Notes
    -----
    The simulator defines the eddy-current field with the ``central`` scheme, so a batch fit
    that uses the same scheme can recover the eddy coefficients exactly on noise-free data;
    at 10 Hz and 4–6 s maneuver periods it differs from the analytic derivative by < 0.3 %.
    """
    x = np.asarray(x, dtype=float)
    if x.shape[0] < 2:
        return np.zeros_like(x)
    if scheme == "central":
        return np.gradient(x, tt, axis=0, edge_order=2 if x.shape[0] > 2 else 1)
    if scheme == "backward":
        d = np.empty_like(x)
        dt = np.diff(tt).reshape((-1,) + (1,) * (x.ndim - 1))
        d[1:] = np.diff(x, axis=0) / dt
        d[0] = d[1]
        return d
    raise ValueError(f"scheme must be 'central' or 'backward', got {scheme!r}")


def earth_radii_m(lat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """WGS84 meridian and prime-vertical radii of curvature [m] at geodetic latitude [rad]."""
    s2 = np.sin(lat) ** 2
    w = np.sqrt(1.0 - WGS84_E2 * s2)
    r_meridian = WGS84_A_M * (1.0 - WGS84_E2) / w**3
    r_normal = WGS84_A_M / w
    return r_meridian, r_normal
