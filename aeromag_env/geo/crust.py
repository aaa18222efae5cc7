"""Crustal magnetic anomaly: a random potential field over a flat local grid, evaluated at
aircraft positions as a vector (NED) [nT].

Model
-----
Flat earth: the ground is the surface at altitude 0 m (the track's ``alt``), and the magnetised
sources fill a layer from ``depth_to_source_m`` d to ``d + source_thickness_m`` t below it.
Above the sources the field is ``B = −∇V`` with ``∇²V = 0``. In local coordinates x north,
y east, z down (altitude ``h = −z``), a horizontal Fourier mode ``exp(i (k_n x + k_e y))`` of V
is harmonic as ``exp(|k| z) = exp(−|k| h)`` — it decays upwards, away from the sources — so
with ``B_n = −∂V/∂x``, ``B_e = −∂V/∂y``, ``B_d = −∂V/∂z``::

    B̂_d(k, h) = B̂_d(k, 0) exp(−|k| h)           upward continuation
    B̂_n = (i k_n / |k|) B̂_d,   B̂_e = (i k_e / |k|) B̂_d
    ∂B̂/∂h = −|k| B̂

(the horizontal components are the Riesz transforms of the down component: for a field that
varies along north only, ``B_n = −H[B_d]`` with H the Hilbert transform). ``B_d`` at the ground
is a Gaussian random field with the spectrum of a layer of scaling (fractal) magnetisation,
after Spector & Grant (1970, Geophysics 35, 293) and Maus & Dimri (1995, GRL 22, 1345)::

    P(k) ∝ |k|^(−β) (1 − exp(−|k| t))² exp(−2 |k| d)

``β`` is ``fractal_exponent``; ``t`` sets the longest wavelengths (a correlation length of a few
``t``), ``d`` the shortest. The realisation is scaled so that the total-field anomaly (the field
along the main-field direction, what a scalar magnetometer sees) has ``rms_nt`` RMS over the
grid at ``reference_altitude_m``; its mean over the grid is zero.

The grid is periodic (FFT), so it is padded around the track by several correlation lengths:
no two track points are closer through the periodic image than directly. Along a track the
field is sampled from grids at a few altitudes (geometric in ``h + d``): periodic cubic splines
across, cubic Hermite (value and exact ``∂B/∂h``) in altitude; tested against the exact Fourier
series. The field depends on position only, and the realisation on the rng and the grid: here
(:func:`random_crust`) the grid follows from the track's extent and altitudes; for one ground
shared by every flight over a survey area, :mod:`aeromag_env.geo.crust_area` fixes the grid and
the altitude levels from the configuration alone.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass

import numpy as np

from aeromag_env.errors import ConfigError
from aeromag_env.geo.frames import earth_radii_m

#: Grid spacing = (lowest altitude + depth to source) / this [-]: a mode at the grid's Nyquist
#: wavenumber is attenuated by exp(−5π) ≈ 2e-7 at the lowest altitude.
_NODES_PER_DEPTH = 5.0
#: Padding around the track, in correlation lengths (the larger of the source thickness and the
#: highest altitude above the sources), and at least this [m].
_PAD_SCALES, _PAD_MIN_M = 3.0, 5_000.0
#: Least grid span, in those correlation lengths: the longer wavelengths the grid lacks hold a
#: few % of the variance at the highest altitude (tested against the spectrum's integral).
_SPAN_SCALES = 20.0
#: Most grid nodes: beyond, the spacing grows (≤ half the lowest height above the sources).
_MAX_NODES = 2**22
#: Ratio of successive ``h + d`` of the altitude levels [-]: with the splines across, within
#: 0.05 % of the RMS of the exact Fourier series (tested).
_LEVEL_RATIO = 1.5


@dataclass(frozen=True)
class CrustField:
    """A crustal anomaly on a periodic local grid.

    Attributes
    ----------
    spectrum : ndarray, shape (n_north, n_east // 2 + 1), complex
        ``rfft2`` of the down component at the ground (altitude 0) [nT].
    shape : (int, int)
        Grid nodes (north, east).
    spacing_m : float
        Node spacing, both directions [m].
    origin_m : (float, float)
        North and east of node (0, 0) in the local frame [m].
    lat0_rad, lon0_rad : float
        Origin of the local frame (north = east = 0) [rad].
    depth_to_source_m : float
        Depth of the sources' top below the ground [m]; the field exists above it.
    level_base_m : float or None
        Lowest of fixed altitude levels [m] (geometric in ``h + d`` from it), so that every
        evaluation samples the same levels; None: the levels span the altitudes asked for.
    """

    spectrum: np.ndarray
    shape: tuple[int, int]
    spacing_m: float
    origin_m: tuple[float, float]
    lat0_rad: float
    lon0_rad: float
    depth_to_source_m: float
    level_base_m: float | None = None

    def wavenumbers(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``k_n`` (n_north, 1), ``k_e`` (1, n_east // 2 + 1) and ``|k|`` [rad/m]."""
        return _wavenumbers(self.shape, self.spacing_m)

    @functools.cached_property
    def _operators(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``|k|`` [rad/m], the Riesz factors ``i k_n/|k|``, ``i k_e/|k|`` (2, …) and the
        periodic cubic B-spline's DFT ``(2 + cos k_n Δ)(2 + cos k_e Δ)/9``, computed once."""
        k_n, k_e, k = self.wavenumbers()
        with np.errstate(invalid="ignore", divide="ignore"):
            riesz = np.stack(
                [np.where(k > 0, 1j * k_n / k, 0.0), np.where(k > 0, 1j * k_e / k, 0.0)]
            )
        spline = (2 + np.cos(k_n * self.spacing_m)) * (2 + np.cos(k_e * self.spacing_m)) / 9.0
        return k, riesz, spline


def _wavenumbers(
    shape: tuple[int, int], spacing_m: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:meth:`CrustField.wavenumbers` of a grid [rad/m]."""
    k_n = 2 * np.pi * np.fft.fftfreq(shape[0], spacing_m)[:, None]
    k_e = 2 * np.pi * np.fft.rfftfreq(shape[1], spacing_m)[None, :]
    return k_n, k_e, np.hypot(k_n, k_e)


def local_north_east(
    lat: np.ndarray, lon: np.ndarray, lat0: float, lon0: float
) -> tuple[np.ndarray, np.ndarray]:
    """Flat-earth north and east [m] of geodetic positions [rad] from ``(lat0, lon0)`` [rad],
    with the WGS84 radii of curvature at ``lat0``."""
    r_m, r_n = earth_radii_m(np.asarray(lat0, float))
    north = (np.asarray(lat, float) - lat0) * float(r_m)
    east = (np.asarray(lon, float) - lon0) * float(r_n) * math.cos(lat0)
    return north, east


def source_spectrum(
    k: np.ndarray, *, depth_to_source_m: float, source_thickness_m: float, fractal_exponent: float
) -> np.ndarray:
    """``P(k) = |k|^(−β) (1 − exp(−|k| t))² exp(−2 |k| d)`` [arbitrary units], 0 at ``k = 0``."""
    k = np.asarray(k, float)
    safe = np.where(k > 0, k, 1.0)
    p = safe ** (-fractal_exponent) * (-np.expm1(-safe * source_thickness_m)) ** 2
    return np.where(k > 0, p * np.exp(-2.0 * safe * depth_to_source_m), 0.0)


def random_crust(
    lat: np.ndarray,
    lon: np.ndarray,
    alt_m: np.ndarray,
    rng: np.random.Generator,
    *,
    rms_nt: float,
    reference_altitude_m: float,
    depth_to_source_m: float,
    source_thickness_m: float,
    fractal_exponent: float,
    main_field_ned: np.ndarray | None = None,
) -> CrustField:
    """Draw a crustal anomaly on a grid that covers a track.

    Parameters
    ----------
    lat, lon : ndarray, shape (n,)
        Track positions [rad]; the first is the local frame's origin.
    alt_m : ndarray, shape (n,)
        Track altitudes above the ground [m]; they set the grid spacing and padding.
    rng : numpy.random.Generator
        Source of the white noise that the spectrum colours (one draw per grid node).
    rms_nt : float
        RMS of the total-field anomaly over the grid at ``reference_altitude_m`` [nT].
    reference_altitude_m, depth_to_source_m, source_thickness_m : float
        [m], see the module docstring.
    fractal_exponent : float
        ``β`` of the spectrum [-].
    main_field_ned : ndarray, shape (3,), optional
        Main-field direction defining the total-field anomaly; default straight down.

    Returns
    -------
    CrustField
    """
    lat0, lon0 = float(lat[0]), float(lon[0])
    north, east = local_north_east(lat, lon, lat0, lon0)
    alt = np.asarray(alt_m, float)
    shape, spacing, origin = _grid(north, east, alt, depth_to_source_m, source_thickness_m)
    grid = CrustField(
        spectrum=np.empty((0, 0), complex),
        shape=shape,
        spacing_m=spacing,
        origin_m=origin,
        lat0_rad=lat0,
        lon0_rad=lon0,
        depth_to_source_m=depth_to_source_m,
    )
    return draw_crust(
        grid,
        rng,
        rms_nt=rms_nt,
        reference_altitude_m=reference_altitude_m,
        source_thickness_m=source_thickness_m,
        fractal_exponent=fractal_exponent,
        main_field_ned=main_field_ned,
    )


def draw_crust(
    grid: CrustField,
    rng: np.random.Generator,
    *,
    rms_nt: float,
    reference_altitude_m: float,
    source_thickness_m: float,
    fractal_exponent: float,
    main_field_ned: np.ndarray | None = None,
) -> CrustField:
    """Draw a crustal anomaly on a given grid: ``grid`` with its ``spectrum`` replaced.

    White noise (``rng.standard_normal(grid.shape)``) coloured by :func:`source_spectrum` at
    ``grid.depth_to_source_m``, scaled so that the total-field anomaly along ``main_field_ned``
    (default straight down) has ``rms_nt`` RMS over the grid at ``reference_altitude_m`` [m];
    the other arguments as in :func:`random_crust`.
    """
    p = source_spectrum(
        _wavenumbers(grid.shape, grid.spacing_m)[2],
        depth_to_source_m=grid.depth_to_source_m,
        source_thickness_m=source_thickness_m,
        fractal_exponent=fractal_exponent,
    )
    crust = dataclasses.replace(
        grid, spectrum=np.fft.rfft2(rng.standard_normal(grid.shape)) * np.sqrt(p)
    )
    down = np.array([0.0, 0.0, 1.0])
    direction = down if main_field_ned is None else np.asarray(main_field_ned, float)
    direction = direction / np.linalg.norm(direction)
    tmi = np.tensordot(direction, field_grid(crust, reference_altitude_m), 1)
    rms = float(np.sqrt(np.mean(tmi**2)))
    return dataclasses.replace(crust, spectrum=crust.spectrum * (rms_nt / rms if rms > 0 else 0.0))


def _grid(
    north: np.ndarray, east: np.ndarray, alt_m: np.ndarray, depth_m: float, thickness_m: float
) -> tuple[tuple[int, int], float, tuple[float, float]]:
    """Grid shape, spacing [m] and origin (north, east of node 0) [m] covering a track."""
    from scipy.fft import next_fast_len

    low, high = float(np.min(alt_m)) + depth_m, float(np.max(alt_m)) + depth_m
    if not low > 0:
        raise ConfigError(
            f"the track goes down to {low - depth_m:.0f} m, below the crustal sources' top "
            f"at {-depth_m:.0f} m"
        )
    correlation_m = max(thickness_m, high)
    pad, least = max(_PAD_MIN_M, _PAD_SCALES * correlation_m), _SPAN_SCALES * correlation_m
    span_n, span_e = (max(np.ptp(x) + 2 * pad, least) for x in (north, east))
    spacing = max(low / _NODES_PER_DEPTH, math.sqrt(span_n * span_e / _MAX_NODES))
    if spacing > low / 2:
        extent = f"{np.ptp(north) / 1e3:.0f} km × {np.ptp(east) / 1e3:.0f} km"
        raise ConfigError(
            f"the track spans {extent}: too large for a crustal grid down to {low - depth_m:.0f} m"
        )
    shape = (
        next_fast_len(math.ceil(span_n / spacing) + 1, real=True),
        next_fast_len(math.ceil(span_e / spacing) + 1, real=True),
    )
    return shape, spacing, (float(np.min(north)) - pad, float(np.min(east)) - pad)


def component_spectra(crust: CrustField, altitude_m: float) -> np.ndarray:
    """``rfft2`` of ``[B_n, B_e, B_d]`` at ``altitude_m`` [m], shape (3, n_north, n_east//2+1)
    [nT]; the module docstring gives the formulas."""
    k, riesz, _ = crust._operators
    b_d = crust.spectrum * np.exp(-k * altitude_m)  # upward continuation from the ground
    return np.concatenate([riesz * b_d, b_d[None]])  # B̂_n,e = (i k_n,e / |k|) B̂_d


def field_grid(crust: CrustField, altitude_m: float) -> np.ndarray:
    """``[B_n, B_e, B_d]`` on the grid nodes at ``altitude_m`` [m], shape (3, n_north, n_east)
    [nT]; node ``(a, b)`` is at ``origin_m + (a, b) * spacing_m``."""
    return np.fft.irfft2(component_spectra(crust, altitude_m), s=crust.shape)


def field_at(
    crust: CrustField, north_m: np.ndarray, east_m: np.ndarray, alt_m: np.ndarray
) -> np.ndarray:
    """The crustal field at local positions, shape (n, 3) NED [nT].

    Parameters
    ----------
    crust : CrustField
    north_m, east_m : ndarray, shape (n,)
        Local position [m] (:func:`local_north_east`).
    alt_m : ndarray, shape (n,)
        Altitude above the ground [m], above the sources' top.

    Notes
    -----
    Grids at altitude levels ``h_j`` with ``(h_{j+1} + d) / (h_j + d) ≤ 1.5`` spanning the
    altitudes asked for; at each level the field and its exact altitude derivative, sampled by
    periodic cubic splines; between levels a cubic Hermite in altitude.
    """
    alt = np.asarray(alt_m, float)
    levels = _levels(
        float(np.min(alt)), float(np.max(alt)), crust.depth_to_source_m, crust.level_base_m
    )
    j = np.clip(np.searchsorted(levels, alt, side="right") - 1, 0, levels.size - 2)
    origin = np.reshape(crust.origin_m, (2, 1))
    coords = np.stack([np.asarray(north_m, float), np.asarray(east_m, float)]) - origin
    coords /= crust.spacing_m  # fractional node indices
    ends = np.empty((2, 2, alt.size, 3))  # [lower/upper level, value/derivative, sample, axis]
    for i, h in enumerate(levels):
        as_lower, as_upper = j == i, j == i - 1
        sel = as_lower | as_upper
        if sel.any():
            val_der = _sample_level(crust, h, coords[:, sel])
            ends[0][:, as_lower] = val_der[:, as_lower[sel]]
            ends[1][:, as_upper] = val_der[:, as_upper[sel]]
    dh = (levels[j + 1] - levels[j])[:, None]
    u = (alt[:, None] - levels[j][:, None]) / dh
    h00, h10 = (1 + 2 * u) * (1 - u) ** 2, u * (1 - u) ** 2  # cubic Hermite basis
    h01, h11 = u**2 * (3 - 2 * u), u**2 * (u - 1)
    return h00 * ends[0, 0] + h10 * dh * ends[0, 1] + h01 * ends[1, 0] + h11 * dh * ends[1, 1]


def _levels(alt_min: float, alt_max: float, depth_m: float, base_m: float | None) -> np.ndarray:
    """Altitudes [m] geometric in ``h + d`` (at least two) spanning ``alt_min`` to ``alt_max``:
    from ``alt_min`` to ``alt_max``, or, with ``base_m``, the fixed levels ``(base_m + d) 1.5^j
    − d`` that enclose them."""
    low, high = alt_min + depth_m, max(alt_max + depth_m, alt_min + depth_m + 1.0)
    if not low > 0:
        raise ConfigError(f"altitude {alt_min:.0f} m is below the crustal sources' top")
    if base_m is not None:
        step = math.log(_LEVEL_RATIO)
        first = math.floor(math.log(low / (base_m + depth_m)) / step)
        last = max(first + 1, math.ceil(math.log(high / (base_m + depth_m)) / step))
        return (base_m + depth_m) * _LEVEL_RATIO ** np.arange(first, last + 1.0) - depth_m
    count = max(1, math.ceil(math.log(high / low) / math.log(_LEVEL_RATIO)))
    return np.geomspace(low, high, count + 1) - depth_m


def _sample_level(crust: CrustField, altitude_m: float, coords: np.ndarray) -> np.ndarray:
    """Field and its altitude derivative at fractional grid ``coords`` (2, m), shape (2, m, 3)
    [nT], [nT/m], by periodic cubic B-splines.

    The splines' coefficients come straight from the spectrum: on a periodic grid, the cubic
    B-spline prefilter is a division by the spline's DFT ``2/3 + cos(k Δ)/3`` per axis.
    """
    from scipy.fft import irfft2
    from scipy.ndimage import map_coordinates

    k, _, spline = crust._operators
    spectra = component_spectra(crust, altitude_m) / spline
    coef = irfft2(np.concatenate([spectra, -k * spectra]), s=crust.shape)  # ∂/∂h = −|k|
    out = np.empty((6, coords.shape[1]))
    for c in range(6):
        out[c] = map_coordinates(coef[c], coords, order=3, mode="grid-wrap", prefilter=False)
    return out.reshape(2, 3, -1).transpose(0, 2, 1)


def field_at_positions(
    crust: CrustField, lat: np.ndarray, lon: np.ndarray, alt_m: np.ndarray
) -> np.ndarray:
    """The crustal field at geodetic positions [rad] and altitudes [m], shape (n, 3) NED [nT]."""
    north, east = local_north_east(lat, lon, crust.lat0_rad, crust.lon0_rad)
    return field_at(crust, north, east, alt_m)
