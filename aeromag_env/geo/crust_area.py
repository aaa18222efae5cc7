"""The ground of a survey area: one crustal anomaly (:mod:`aeromag_env.geo.crust`) fixed in
geographic coordinates, the same for every flight over the area.

The area is a square of ``area_size_km`` side centred on a geographic point, flown no lower
than ``min_altitude_m`` above the ground. Everything about its grid follows from these and the
spectrum alone, never from a track:

* the local frame's origin is the area's centre (flat earth, WGS84 radii at the centre);
* the spacing is ``(min_altitude_m + d) / 5`` (d the depth to the sources): a mode at the
  grid's Nyquist wavenumber is attenuated by ``exp(−5π) ≈ 2e-7`` at the lowest altitude;
* the grid is padded around the area by several correlation lengths (the larger of the source
  thickness and the reference altitude above the sources, at least 5 km), as a track's grid is;
* the altitude levels at which the field is sampled are anchored at ``min_altitude_m``
  (geometric in ``h + d``, ratio 1.5), so every flight samples the same levels and two flights
  see the same vector at the same place to round-off;
* the total-field RMS is along IGRF-14 at the area's centre, at the ground, at epoch 2025.0 —
  not along a flight's mean field nor at its date (the ground does not age).

The white noise comes from ``seed`` alone. Grounds are cached (:func:`area_ground`), so many
flights over one area compute the FFT once. A track that leaves the area or flies below
``min_altitude_m`` is refused (:func:`area_field_at`).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from aeromag_env.configs import check, require_nonnegative, require_positive
from aeromag_env.errors import ConfigError
from aeromag_env.geo import crust as cr

#: ``GeologyConfig`` fields that define the area (the others define the spectrum, and ``seed``).
AREA_FIELDS = ("area_center_lat_deg", "area_center_lon_deg", "area_size_km", "min_altitude_m")
#: Epoch of the main field that defines the total-field RMS.
_EPOCH = "2025-01-01"
#: Grounds kept by :func:`area_ground` (each ~60 MB for a 100 km area at 100 m spacing).
_CACHED_GROUNDS = 4


@dataclass(frozen=True)
class AreaGround:
    """A crustal anomaly over a square survey area.

    Attributes
    ----------
    crust : CrustField
        The anomaly; its local frame's origin is the area's centre, its levels fixed.
    half_size_m : float
        Half the area's side [m]: the area is ``|north|, |east| ≤ half_size_m``.
    min_altitude_m : float
        Lowest altitude served [m].
    """

    crust: cr.CrustField
    half_size_m: float
    min_altitude_m: float


def area_grid(
    size_m: float,
    min_altitude_m: float,
    depth_m: float,
    thickness_m: float,
    reference_altitude_m: float,
) -> tuple[tuple[int, int], float, tuple[float, float]]:
    """Grid shape, spacing [m] and origin (north, east of node 0 from the centre) [m] of an
    area of side ``size_m`` [m]; ConfigError (one line) beyond ``crust._MAX_NODES`` nodes."""
    from scipy.fft import next_fast_len

    spacing = (min_altitude_m + depth_m) / cr._NODES_PER_DEPTH
    correlation_m = max(thickness_m, reference_altitude_m + depth_m)
    pad = max(cr._PAD_MIN_M, cr._PAD_SCALES * correlation_m)
    span = max(size_m + 2 * pad, cr._SPAN_SCALES * correlation_m)
    n = next_fast_len(math.ceil(span / spacing) + 1, real=True)
    if n * n > cr._MAX_NODES:
        raise ConfigError(
            f"a {size_m / 1e3:g} km area down to {min_altitude_m:g} m needs {n} × {n} crustal "
            f"grid nodes at {spacing:g} m, more than {cr._MAX_NODES}"
        )
    return (n, n), spacing, (-size_m / 2 - pad, -size_m / 2 - pad)


def check_area(geology: Any) -> None:
    """One-line :class:`ConfigError` unless ``GeologyConfig``'s area fields are valid."""
    lat, lon = geology.area_center_lat_deg, geology.area_center_lon_deg
    name = "GeologyConfig.area_center_lat_deg and area_center_lon_deg"
    check((lat is None) == (lon is None), f"{name} must be both set or both None")
    check(lat is None or -90 < lat < 90, f"{name}: latitude must be in (-90, 90) deg, got {lat}")
    check(lon is None or -360 <= lon <= 360, f"{name}: longitude out of range: {lon}")
    require_positive(geology, "area_size_km")
    require_nonnegative(geology, "min_altitude_m")
    try:
        area_grid(
            geology.area_size_km * 1e3,
            geology.min_altitude_m,
            geology.depth_to_source_m,
            geology.source_thickness_m,
            geology.reference_altitude_m,
        )
    except ValueError as e:
        raise ConfigError(f"GeologyConfig.area_size_km: {e}") from None


@functools.lru_cache(maxsize=_CACHED_GROUNDS)
def area_ground(
    seed: int,
    center_deg: tuple[float, float],
    size_km: float,
    min_altitude_m: float,
    *,
    rms_nt: float,
    reference_altitude_m: float,
    depth_to_source_m: float,
    source_thickness_m: float,
    fractal_exponent: float,
) -> AreaGround:
    """The ground of an area, drawn from ``seed`` and cached (the last few areas).

    Parameters
    ----------
    seed : int
        Seed of the white noise.
    center_deg : (float, float)
        Latitude and longitude of the area's centre [deg].
    size_km : float
        Side of the square area [km].
    min_altitude_m : float
        Lowest altitude served [m]; sets the spacing and the levels' anchor.
    rms_nt, reference_altitude_m, depth_to_source_m, source_thickness_m, fractal_exponent
        The spectrum, as in :func:`aeromag_env.geo.crust.random_crust`.

    Returns
    -------
    AreaGround
        Its spectrum is read-only: the cache shares it between flights.
    """
    from aeromag_env.geo.earth import igrf_ned

    lat0, lon0 = np.deg2rad(center_deg[0]), np.deg2rad(center_deg[1])
    shape, spacing, origin = area_grid(
        size_km * 1e3, min_altitude_m, depth_to_source_m, source_thickness_m, reference_altitude_m
    )
    grid = cr.CrustField(
        spectrum=np.empty((0, 0), complex),
        shape=shape,
        spacing_m=spacing,
        origin_m=origin,
        lat0_rad=float(lat0),
        lon0_rad=float(lon0),
        depth_to_source_m=depth_to_source_m,
        level_base_m=min_altitude_m,
    )
    main = igrf_ned(np.array([lat0]), np.array([lon0]), np.zeros(1), _EPOCH)[0]
    crust = cr.draw_crust(
        grid,
        np.random.default_rng(seed),
        rms_nt=rms_nt,
        reference_altitude_m=reference_altitude_m,
        source_thickness_m=source_thickness_m,
        fractal_exponent=fractal_exponent,
        main_field_ned=main,
    )
    crust.spectrum.flags.writeable = False
    return AreaGround(crust=crust, half_size_m=size_km * 500.0, min_altitude_m=min_altitude_m)


def crust_along_track(
    lat: np.ndarray,
    lon: np.ndarray,
    alt_m: np.ndarray,
    rng: np.random.Generator,
    *,
    main_field_ned: np.ndarray,
    start_deg: tuple[float, float],
    seed: int | None,
    area_center_lat_deg: float | None,
    area_center_lon_deg: float | None,
    area_size_km: float,
    min_altitude_m: float,
    **spectrum: float,
) -> np.ndarray:
    """The crustal field along a track, shape (n, 3) NED [nT], from ``GeologyConfig``'s fields.

    With ``seed``, the area's ground (:func:`area_ground`, cached); without, a ground drawn
    from ``rng`` on a grid around the track (:func:`aeromag_env.geo.crust.random_crust`) with
    its total-field RMS along ``main_field_ned``.

    Parameters
    ----------
    lat, lon : ndarray, shape (n,)
        Track positions [rad].
    alt_m : ndarray, shape (n,)
        Altitudes above the ground [m].
    rng : numpy.random.Generator
        The flight's geology stream (unused with ``seed``).
    main_field_ned : ndarray, shape (3,)
        The flight's mean main field (unused with ``seed``).
    start_deg : (float, float)
        The area's centre [deg] when ``area_center_lat_deg`` and ``area_center_lon_deg`` are None
        (the trajectory's configured start point).
    seed, area_center_lat_deg, area_center_lon_deg, area_size_km, min_altitude_m, **spectrum
        The ``GeologyConfig`` fields.

    Raises
    ------
    ConfigError
        One line, if with ``seed`` the track leaves the area or flies below ``min_altitude_m``.
    """
    if seed is None:
        crust = cr.random_crust(lat, lon, alt_m, rng, **spectrum, main_field_ned=main_field_ned)
        return cr.field_at_positions(crust, lat, lon, alt_m)
    center_deg = (float(start_deg[0]), float(start_deg[1]))
    if area_center_lat_deg is not None and area_center_lon_deg is not None:
        center_deg = (float(area_center_lat_deg), float(area_center_lon_deg))
    ground = area_ground(seed, center_deg, area_size_km, min_altitude_m, **spectrum)
    return area_field_at(ground, lat, lon, alt_m)


def area_field_at(
    ground: AreaGround, lat: np.ndarray, lon: np.ndarray, alt_m: np.ndarray
) -> np.ndarray:
    """The ground's field at geodetic positions [rad] and altitudes [m], shape (n, 3) NED [nT];
    ConfigError (one line) if a position is outside the area or below its lowest altitude."""
    crust = ground.crust
    north, east = cr.local_north_east(lat, lon, crust.lat0_rad, crust.lon0_rad)
    beyond = max(float(np.max(np.abs(north))), float(np.max(np.abs(east)))) - ground.half_size_m
    if beyond > 0:
        center = f"({np.rad2deg(crust.lat0_rad):.4f}°, {np.rad2deg(crust.lon0_rad):.4f}°)"
        raise ConfigError(
            f"the track leaves the {2 * ground.half_size_m / 1e3:g} km geology area around "
            f"{center} by {beyond / 1e3:.2f} km: set GeologyConfig.area_size_km or "
            f"area_center_lat_deg/area_center_lon_deg"
        )
    alt = np.asarray(alt_m, float)
    if float(np.min(alt)) < ground.min_altitude_m:
        raise ConfigError(
            f"the track flies down to {float(np.min(alt)):.0f} m, below "
            f"GeologyConfig.min_altitude_m = {ground.min_altitude_m:g} m"
        )
    return cr.field_at(crust, north, east, alt)
