"""Earth field along a track: IGRF-14 core field (via ``ppigrf``) and external variation.

IGRF varies slowly along a flight, so it is evaluated on a coarse time grid along the track and
interpolated; the small altitude excursions between grid points (pitch maneuvers) are carried by
the vertical gradient, evaluated on the same grid. The interpolation agrees with a direct
``ppigrf`` call to well under 0.1 nT (tested).
"""

from __future__ import annotations

import datetime as _dt
import functools
import warnings

import numpy as np

from aeromag_env.noise import fogm

#: Altitude step for the finite-difference vertical gradient [m].
_DH_M = 100.0
#: The dates IGRF-14 covers: its first main-field epoch and the end of its secular variation,
#: the first and last dates of ppigrf's coefficient file (tested). Outside, ppigrf's field is
#: NaN (before) or the 2030 field held (after).
IGRF_FIRST_DATE = _dt.datetime(1900, 1, 1)
IGRF_LAST_DATE = _dt.datetime(2030, 1, 1)
IGRF_VALID_YEARS = f"IGRF-14's valid years {IGRF_FIRST_DATE.year}–{IGRF_LAST_DATE.year}"


class ModelDateError(ValueError):
    """A readable date that the Earth-field model does not cover (:func:`check_model_date`)."""


def check_model_date(date: _dt.datetime, source: str) -> _dt.datetime:
    """``date`` if IGRF-14 covers it, else :class:`ModelDateError` on one line.

    ``source`` names where the date came from, with its value (``"date attribute '26-06-01'"``,
    ``"year 26, doy 152 at the first sample"``); the message adds the date read and the valid
    years, and a hint when the year has two digits.
    """
    if IGRF_FIRST_DATE <= date <= IGRF_LAST_DATE:
        return date
    hint = " (a two-digit year?)" if date.year < 100 else ""
    raise ModelDateError(f"{source} is {date.date().isoformat()}, outside {IGRF_VALID_YEARS}{hint}")


def parse_date(date: str | _dt.date | _dt.datetime) -> _dt.datetime:
    """ISO date/datetime string or date object → naive UTC ``datetime``."""
    if isinstance(date, _dt.datetime):
        return date.replace(tzinfo=None)
    if isinstance(date, _dt.date):
        return _dt.datetime(date.year, date.month, date.day)
    try:
        return _dt.datetime.fromisoformat(str(date)).replace(tzinfo=None)
    except ValueError:
        raise ValueError(f"date must be ISO 8601 (e.g. 2026-06-01), got {date!r}") from None


def igrf_ned(
    lat: np.ndarray, lon: np.ndarray, alt_m: np.ndarray, date: str | _dt.datetime
) -> np.ndarray:
    """IGRF-14 core field in NED at geodetic positions, as ``ppigrf.igrf`` computes it.

    Parameters
    ----------
    lat, lon : ndarray, shape (n,)
        Geodetic latitude and longitude [rad].
    alt_m : ndarray, shape (n,)
        Height above the WGS84 ellipsoid [m].
    date : str or datetime
        Epoch of the field model (one date for all points).

    Returns
    -------
    ndarray, shape (n, 3)
        ``[B_north, B_east, B_down]`` [nT].

    Notes
    -----
    ``ppigrf.igrf`` re-reads the coefficient file and interpolates it in time with pandas on
    every call (~25 ms, most of a simulated episode's reset). Here that step is done once per
    date (:func:`_igrf_coefficients`) and the synthesis follows ``ppigrf.igrf_gc`` operation
    for operation with ppigrf's own Legendre functions and coordinate conversions, so the
    result equals ``ppigrf.igrf``'s (tested to 1e-9 nT).
    """
    from ppigrf.ppigrf import RE, geoc2geod, geod2geoc, get_legendre

    lat, lon, alt_m = np.broadcast_arrays(
        np.atleast_1d(np.asarray(lat, float)),
        np.atleast_1d(np.asarray(lon, float)),
        np.atleast_1d(np.asarray(alt_m, float)),
    )
    h_km = np.ravel(alt_m) / 1000.0
    theta, r, _, _ = geod2geoc(np.rad2deg(np.ravel(lat)), h_km, h_km, h_km)
    keys, gh = _igrf_coefficients(parse_date(date))
    r, theta, phi = (np.reshape(x, (-1, 1)) for x in (r, theta, np.rad2deg(np.ravel(lon))))
    n, m = np.array(keys).T.reshape(2, 1, -1)
    p, dp = get_legendre(theta, keys)
    phi_rad = np.radians(phi)
    cos_mphi, sin_mphi = np.cos(phi_rad * m), np.sin(phi_rad * m)
    nn, mm = np.tile(n, 2), np.tile(m, 2)
    b_r = ((RE / r) ** (nn + 2) * (nn + 1) * np.hstack((p * cos_mphi, p * sin_mphi))).dot(gh.T).T
    g_theta = -((RE / r) ** (nn + 1)) * np.hstack((dp * cos_mphi, dp * sin_mphi)) * RE / r
    b_theta = g_theta.dot(gh.T).T
    g_phi = (
        -((RE / r) ** (nn + 1))
        * mm
        * np.hstack((-p * sin_mphi, p * cos_mphi))
        * RE
        / r
        / np.sin(np.radians(theta))
    )
    b_phi = g_phi.dot(gh.T).T
    _, _, b_n, b_u = geoc2geod(theta.ravel(), r.ravel(), b_theta.ravel(), b_r.ravel())
    return np.column_stack([np.ravel(b_n), np.ravel(b_phi), -np.ravel(b_u)])


@functools.lru_cache(maxsize=32)
def _igrf_coefficients(date: _dt.datetime) -> tuple[list[tuple[int, int]], np.ndarray]:
    """IGRF Gauss coefficients at ``date``: the ``(n, m)`` keys and ``[g, h]``, shape (1, 2K).

    Read and interpolated in time exactly as ``ppigrf.igrf_gc`` does it.
    """
    from ppigrf.ppigrf import read_shc

    g, h = read_shc()
    if not g.index[0] <= date <= g.index[-1]:
        warnings.warn(
            f"date {date:%Y-%m-%d} is outside the IGRF coefficient file "
            f"({g.index[0]:%Y-%m-%d} to {g.index[-1]:%Y-%m-%d})",
            stacklevel=3,
        )
    when = np.array([date])
    index = g.index.union(when)
    g = g.reindex(index).groupby(index).first().interpolate(method="time").loc[when, :]
    h = h.reindex(index).groupby(index).first().interpolate(method="time").loc[when, :]
    return list(g.columns), np.hstack((g.values, h.values))


def igrf_ned_along_track(
    tt: np.ndarray,
    lat: np.ndarray,
    lon: np.ndarray,
    alt_m: np.ndarray,
    date: str | _dt.datetime,
    grid_spacing_s: float = 10.0,
) -> np.ndarray:
    """IGRF-14 in NED along a track, from a coarse grid plus the vertical gradient.

    Parameters
    ----------
    tt : ndarray, shape (n,)
        Sample times [s].
    lat, lon : ndarray, shape (n,)
        Geodetic latitude and longitude [rad].
    alt_m : ndarray, shape (n,)
        Height [m].
    date : str or datetime
    grid_spacing_s : float
        Time between grid points [s].

    Returns
    -------
    ndarray, shape (n, 3) [nT]

    Notes
    -----
    ``B(t) ≈ S_B(t) + S_g(t) (h(t) - S_h(t))`` where ``S_B``, ``S_g`` and ``S_h`` are cubic
    splines through the grid values of the field, its vertical gradient ``∂B/∂h`` and the
    altitude; the last term carries altitude changes faster than the grid. A track evaluated
    before is remembered (:func:`_remembered_track`): every episode of a training run flies the
    same pattern, and the splines cost milliseconds.
    """
    tt, lat, lon, alt_m = (np.asarray(x, dtype=float) for x in (tt, lat, lon, alt_m))
    if tt.size < 4:
        return igrf_ned(lat, lon, alt_m, date)
    key = (str(parse_date(date)), float(grid_spacing_s))
    hit = _remembered_track(key, (tt, lat, lon, alt_m))
    if hit is None:
        hit = _along_track(tt, lat, lon, alt_m, date, grid_spacing_s)
        if tt.size <= _TRACK_CACHE_MAX_SAMPLES:
            _remember_track(key, (tt, lat, lon, alt_m), hit)
    return hit.copy()


def _along_track(
    tt: np.ndarray,
    lat: np.ndarray,
    lon: np.ndarray,
    alt_m: np.ndarray,
    date: str | _dt.datetime,
    grid_spacing_s: float,
) -> np.ndarray:
    """:func:`igrf_ned_along_track` computed (float64 inputs, at least 4 samples)."""
    from scipy.interpolate import CubicSpline

    n = tt.size
    step = max(1, round(grid_spacing_s / float(np.median(np.diff(tt)))))
    idx = np.unique(np.r_[np.arange(0, n, step), n - 1])
    if idx.size < 4:
        idx = np.unique(np.linspace(0, n - 1, 4).round().astype(int))
    g_lat, g_lon, g_alt = lat[idx], lon[idx], alt_m[idx]
    both = _igrf_grid(np.r_[g_lat, g_lat], np.r_[g_lon, g_lon], np.r_[g_alt, g_alt + _DH_M], date)
    b_grid, b_up = both[: idx.size], both[idx.size :]
    grad = (b_up - b_grid) / _DH_M
    t_grid = tt[idx]
    b = CubicSpline(t_grid, b_grid, axis=0)(tt)
    dh = alt_m - CubicSpline(t_grid, g_alt)(tt)
    return b + CubicSpline(t_grid, grad, axis=0)(tt) * dh[:, None]


#: Grid evaluations kept by :func:`_igrf_grid` (a few hundred points each).
_GRID_CACHE_SIZE = 16
_grid_cache: dict[tuple, np.ndarray] = {}


def _igrf_grid(
    lat: np.ndarray, lon: np.ndarray, alt_m: np.ndarray, date: str | _dt.datetime
) -> np.ndarray:
    """:func:`igrf_ned` at grid points, remembered by their exact values: a training run flies
    the same pattern again and again, and each IGRF synthesis costs milliseconds in ppigrf's
    Python Legendre loop however few the points. The key is the points' bytes and the date, so
    a hit returns exactly what the synthesis would."""
    key = (lat.tobytes(), lon.tobytes(), alt_m.tobytes(), str(parse_date(date)))
    hit = _grid_cache.get(key)
    if hit is None:
        hit = igrf_ned(lat, lon, alt_m, date)
        hit.flags.writeable = False
        if len(_grid_cache) >= _GRID_CACHE_SIZE:
            del _grid_cache[next(iter(_grid_cache))]  # the oldest
        _grid_cache[key] = hit
    return hit


#: Tracks kept by :func:`_remember_track`, and the longest one kept [samples] (a training
#: flight has 12 000–15 000; a long survey file is evaluated once).
_TRACK_CACHE_SIZE, _TRACK_CACHE_MAX_SAMPLES = 8, 100_000
_track_cache: list[tuple[tuple[str, float], tuple[np.ndarray, ...], np.ndarray]] = []


def _remembered_track(key: tuple[str, float], track: tuple[np.ndarray, ...]) -> np.ndarray | None:
    """The field remembered for ``track`` (tt, lat, lon, alt) with ``key`` (date, grid
    spacing), or None. The arrays are compared bit for bit (not ``==``: -0.0 and 0.0 differ
    here), so a hit returns exactly what the evaluation would."""
    for known_key, known, field in _track_cache:
        if known_key == key and all(_same_bits(a, b) for a, b in zip(known, track, strict=True)):
            return field
    return None


def _remember_track(
    key: tuple[str, float], track: tuple[np.ndarray, ...], field: np.ndarray
) -> None:
    """Keep ``field`` (made read-only) for a copy of ``track``, forgetting the oldest if full."""
    if len(_track_cache) >= _TRACK_CACHE_SIZE:
        del _track_cache[0]  # the oldest
    field.flags.writeable = False
    _track_cache.append((key, tuple(a.copy() for a in track), field))


def _same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    """Float64 arrays ``a`` and ``b`` hold the same bits (NaN payloads and zero signs too)."""
    return a.shape == b.shape and np.array_equal(
        np.ascontiguousarray(a).view(np.int64), np.ascontiguousarray(b).view(np.int64)
    )


def clear_caches() -> None:
    """Forget remembered IGRF grid and track evaluations (benchmarks time a cold simulation)."""
    _grid_cache.clear()
    _track_cache.clear()


def first_order_lag(x: np.ndarray, dt_s: float, tau_s: float) -> np.ndarray:
    """``y' = (x − y) / τ``, exactly discretised, started at ``y[0] = x[0]`` (along axis 0)."""
    from scipy.signal import lfilter

    a = float(np.exp(-dt_s / tau_s))
    y, _ = lfilter([1.0 - a], [1.0, -a], x, axis=0, zi=(a * x[:1]))
    return y


def external_variation_ned(
    tt: np.ndarray,
    start: _dt.datetime,
    daily_amplitude_nt: float,
    fogm_std_nt: float,
    fogm_tau_s: float,
    rng: np.random.Generator,
    smoothing_s: float = 60.0,
) -> np.ndarray:
    """External (diurnal) field variation in NED, fixed in the navigation frame.

    The variation is referenced to the start of the flight (zero at ``tt = 0``), as a base
    station's diurnal record is used in practice; a constant external or Earth-model offset is a
    different effect (it rotates with heading like an Earth-model error) and is simulated only
    when asked for, not hidden in the variation.

    Parameters
    ----------
    tt : ndarray, shape (n,)
        Sample times [s] since ``start``.
    start : datetime
        UTC time of ``tt = 0``; sets the phase of the daily (Sq) cycle.
    daily_amplitude_nt : float
        Amplitude of the daily cycle [nT]; shared by the three components with random phases
        and weights (the horizontal components dominate, as for the Sq variation).
    fogm_std_nt, fogm_tau_s : float
        Irregular part per component [nT], [s]: a FOGM of this std and correlation time,
        smoothed by a first-order lag of ``smoothing_s`` — a quiet-day variation with almost no
        power in the 0.1–1 Hz band of the compensation maneuvers.
    smoothing_s : float
        Time constant of that lag [s].
    rng : numpy.random.Generator

    Returns
    -------
    ndarray, shape (n, 3) [nT]
    """
    tt = np.asarray(tt, dtype=float)
    seconds_of_day = start.hour * 3600 + start.minute * 60 + start.second
    phase = rng.uniform(0.0, 2.0 * np.pi, 3)
    weights = np.array([1.0, 0.5, 0.3]) * rng.uniform(0.7, 1.3, 3)
    omega = 2.0 * np.pi / 86_400.0
    cycle = np.sin(omega * (seconds_of_day + tt)[:, None] + phase) * weights * daily_amplitude_nt
    dt = float(np.median(np.diff(tt))) if tt.size > 1 else 1.0
    irregular = fogm(tt.size, dt, fogm_std_nt, fogm_tau_s, rng, dims=3)
    variation = cycle + first_order_lag(irregular, dt, smoothing_s)
    return variation - variation[0]
