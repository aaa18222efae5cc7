"""Fuzzy inference system (FIS) of the fuzzy adaptive Kalman filter (paper §3.4, eq. 21).

The FIS turns a consistency ratio ρ — ``ROR`` for the measurement noise ``R`` (tolerance
ε = 0.05) or ``QOQ`` for the process noise ``Q`` (tolerance η = 0.025) — into a multiplicative
scale factor ``s`` applied as ``R(k) = s_r R(k−1)``, ``Q(k) = s_a Q(k−1)`` (eq. 21). The paper
states three rules and leaves the membership functions open; with ``tol`` standing for ε or η:

1. if ``|ρ − 1| ≤ tol`` then ``|s − 1| ≤ tol``  (consistent: keep the noise level);
2. if ``ρ > 1 + tol`` then ``s > 1 + tol``  (innovations too large: increase);
3. if ``ρ < 1 − tol`` then ``s < 1 − tol``  (innovations too small: decrease).

Design (the project's documented choice)
----------------------------------------
Input ρ ≥ 0 (dimensionless), three sets:

* ``low``:  1 for ρ ≤ (1 − tol)/2, linear down to 0 at ρ = 1 − tol, 0 above;
* ``ok``:   triangle with feet 1 ± tol and peak 1 at ρ = 1;
* ``high``: 0 for ρ ≤ 1 + tol, linear up to 1 at ρ = 2 + tol, 1 above.

Output ``s`` on the universe [s_min, s_max] = [0.5, 2.0] (default), sampled at the grid
``1 + k·S_STEP`` (``S_STEP`` = 0.005, 301 points by default; 1.0 is a grid point, so the ``keep``
set is sampled symmetrically about 1), three sets:

* ``decrease``: 1 at s_min, linear down to 0 at 1 − tol;
* ``keep``:     triangle with feet 1 ± tol and peak 1 at s = 1;
* ``increase``: 0 at 1 + tol, linear up to 1 at s_max.

Rules ``low → decrease``, ``ok → keep``, ``high → increase``; Mamdani inference: min
implication (each output set clipped at its rule's firing strength), max aggregation, centroid
defuzzification of the aggregated membership taken as piecewise linear between grid points (the
exact area centroid; the definition of ``skfuzzy.defuzz(..., "centroid")``).

Why this satisfies the rules exactly: the supports of ``low`` and ``high`` stop at the tolerance
band, so inside the band only ``ok → keep`` fires; the clipped ``keep`` set is symmetric about
1 and its centroid is 1. Above the band only ``increase`` fires; its clipped, sampled membership
is non-decreasing on a support that starts less than one grid step below 1 + tol, so its centroid
lies right of the support's midpoint, which is > 1 + tol when s_max ≥ 1 + tol + S_STEP (rule 3 is
the mirror image, with s_min ≤ 1 − tol − S_STEP). The map ρ ↦ s is non-decreasing: from
≈ s_min + (1 − tol − s_min)/3 (ρ ≤ (1 − tol)/2) through 1 (the band) to ≈ 1 + tol +
2(s_max − 1 − tol)/3 (ρ ≥ 2 + tol), with jumps at the band edges, where no rule fires and the
output is 1 (no change). A NaN ratio gives 1 (no adaptation on an undefined statistic), +inf
counts as very large (``high`` fully active), a negative ratio as 0.

Zoom levels (eq. 21 discussion): the applied factor is ``s = s_FIS ** b`` with ``b ≥ 0``;
``b = 0`` is the plain Kalman filter, ``0 < b < 1`` damps the adaptation, ``b > 1`` magnifies it.

``fis_scale`` and ``zoomed_scale`` are compiled (numba's ``njit``), allocation-free and callable
from other compiled code (the filter loop); they do not validate their arguments.
``fis_scale_array`` is the validated, vectorised Python entry point and ``fis_scale_reference``
a plain-numpy implementation that builds the membership arrays explicitly, for tests.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from aeromag_env.errors import ConfigError
from aeromag_env.numba_cache import njit

EPSILON_R = 0.05  # tolerance ε of the R (ROR) FIS, paper §4 [-]
ETA_Q = 0.025  # tolerance η of the Q (QOQ) FIS, paper §4 [-]
S_MIN = 0.5  # lower end of the output universe [-]
S_MAX = 2.0  # upper end of the output universe [-]
S_STEP = 0.005  # output grid step [-]


@njit(cache=True)
def _ramp_down(x: float, a: float, b: float) -> float:
    """1 for x ≤ a, 0 for x ≥ b, linear in between (a < b)."""
    if x <= a:
        return 1.0
    if x >= b:
        return 0.0
    return (b - x) / (b - a)


@njit(cache=True)
def _ramp_up(x: float, a: float, b: float) -> float:
    """0 for x ≤ a, 1 for x ≥ b, linear in between (a < b)."""
    if x <= a:
        return 0.0
    if x >= b:
        return 1.0
    return (x - a) / (b - a)


@njit(cache=True)
def _triangle(x: float, a: float, m: float, c: float) -> float:
    """Triangle with feet a, c and peak 1 at m (a < m < c)."""
    if x <= a or x >= c:
        return 0.0
    if x <= m:
        return (x - a) / (m - a)
    return (c - x) / (c - m)


@njit(cache=True)
def _firing_strengths(rho: float, tol: float) -> tuple[float, float, float]:
    """Memberships of ρ ≥ 0 (may be +inf) in ``low``, ``ok``, ``high``."""
    low = _ramp_down(rho, 0.5 * (1.0 - tol), 1.0 - tol)
    ok = _triangle(rho, 1.0 - tol, 1.0, 1.0 + tol)
    high = _ramp_up(rho, 1.0 + tol, 2.0 + tol)
    return low, ok, high


@njit(cache=True)
def _aggregated(
    s: float, low: float, ok: float, high: float, tol: float, s_lo: float, s_hi: float
) -> float:
    """Aggregated output membership at s: max of the three clipped output sets."""
    decrease = min(low, _ramp_down(s, s_lo, 1.0 - tol))
    keep = min(ok, _triangle(s, 1.0 - tol, 1.0, 1.0 + tol))
    increase = min(high, _ramp_up(s, 1.0 + tol, s_hi))
    return max(decrease, keep, increase)


@njit(cache=True)
def _centroid(low: float, ok: float, high: float, tol: float, s_min: float, s_max: float) -> float:
    """Centroid of the aggregated output membership, piecewise linear on the grid ``1 + k·S_STEP``.

    Per interval ``[x₀, x₁]``: ``∫ μ ds = Δx (μ₀ + μ₁) / 2``,
    ``∫ s μ ds = Δx (x₀ (2μ₀ + μ₁) + x₁ (μ₀ + 2μ₁)) / 6``; 1.0 if the area is 0.
    """
    n_lo = round((1.0 - s_min) / S_STEP)
    n_hi = round((s_max - 1.0) / S_STEP)
    s_lo = 1.0 - n_lo * S_STEP
    s_hi = 1.0 + n_hi * S_STEP
    x0 = s_lo
    y0 = _aggregated(x0, low, ok, high, tol, s_lo, s_hi)
    area = 0.0
    moment = 0.0
    for k in range(1 - n_lo, n_hi + 1):
        x1 = 1.0 + k * S_STEP
        y1 = _aggregated(x1, low, ok, high, tol, s_lo, s_hi)
        dx = x1 - x0
        area += 0.5 * dx * (y0 + y1)
        moment += dx * (x0 * (2.0 * y0 + y1) + x1 * (y0 + 2.0 * y1)) / 6.0
        x0 = x1
        y0 = y1
    if area <= 0.0:
        return 1.0
    return moment / area


@njit(cache=True)
def fis_scale(ratio: float, tol: float, s_min: float = S_MIN, s_max: float = S_MAX) -> float:
    """Scale factor ``s = FIS(ratio)`` of the paper's three rules (§3.4).

    Parameters
    ----------
    ratio : float
        Consistency ratio ρ (``ROR`` or ``QOQ``) [-]; NaN gives 1, negative counts as 0.
    tol : float
        Tolerance band half-width (ε or η) [-], ``0 < tol < 0.5``.
    s_min, s_max : float
        Ends of the output universe [-], snapped to the ``S_STEP`` grid through 1.

    Returns
    -------
    float
        Multiplicative factor for Q or R [-], in (s_min, s_max); 1.0 when no rule fires.

    Notes
    -----
    Mamdani min–max inference, then ``s = ∫ s μ ds / ∫ μ ds`` with the aggregated membership μ
    piecewise linear on the grid ``1 + k·S_STEP`` (see `_centroid`). No validation, no allocation.
    """
    rho = float(ratio)
    if math.isnan(rho):
        return 1.0
    low, ok, high = _firing_strengths(max(rho, 0.0), tol)
    if low == 0.0 and ok == 0.0 and high == 0.0:
        return 1.0
    return _centroid(low, ok, high, tol, s_min, s_max)


@njit(cache=True)
def zoomed_scale(
    ratio: float, tol: float, zoom: float, s_min: float = S_MIN, s_max: float = S_MAX
) -> float:
    """Zoomed scale factor ``s = FIS(ratio) ** zoom`` (eq. 21 zoom levels ``b_a``, ``b_r``).

    Parameters
    ----------
    ratio, tol, s_min, s_max : float
        As in `fis_scale`.
    zoom : float
        Zoom level b ≥ 0 [-]: 0 is the plain KF (s = 1), 0 < b < 1 damps, b > 1 magnifies.

    Returns
    -------
    float
        Multiplicative factor for Q or R [-].
    """
    return fis_scale(ratio, tol, s_min, s_max) ** zoom


@njit(cache=True)
def _zoomed_many(
    ratios: np.ndarray, tol: float, zoom: float, s_min: float, s_max: float
) -> np.ndarray:
    """`zoomed_scale` over a 1-D array."""
    out = np.empty(ratios.size)
    for i in range(ratios.size):
        out[i] = zoomed_scale(ratios[i], tol, zoom, s_min, s_max)
    return out


def _on_grid(value: float) -> bool:
    """Whether ``value`` is ``1 + k·S_STEP`` for an integer k (to 1e-9 steps)."""
    k = (value - 1.0) / S_STEP
    return abs(k - round(k)) < 1e-9


def validate_parameters(tol: float, s_min: float, s_max: float, zoom: float = 1.0) -> None:
    """Check the FIS parameters; raise `ConfigError` (one line) naming the first bad one.

    Requires ``0 < tol < 0.5``; ``s_min`` and ``s_max`` on the ``S_STEP`` grid with
    ``0 < s_min ≤ 1 − tol − S_STEP`` and ``s_max ≥ 1 + tol + S_STEP`` (each ramp spans at least
    one grid step, which makes rules 2 and 3 hold exactly); ``zoom ≥ 0``. All are finite.
    """
    if not (math.isfinite(tol) and 0.0 < tol < 0.5):
        raise ConfigError(f"tol must be in (0, 0.5) [-], got {tol!r}")
    if not (math.isfinite(s_min) and 0.0 < s_min <= 1.0 - tol - S_STEP + 1e-12):
        raise ConfigError(f"s_min must be in (0, 1 - tol - {S_STEP}] [-], got {s_min!r}")
    if not _on_grid(s_min):
        raise ConfigError(f"s_min must be a multiple of {S_STEP} [-], got {s_min!r}")
    if not (math.isfinite(s_max) and s_max >= 1.0 + tol + S_STEP - 1e-12):
        raise ConfigError(f"s_max must be finite and >= 1 + tol + {S_STEP} [-], got {s_max!r}")
    if not _on_grid(s_max):
        raise ConfigError(f"s_max must be a multiple of {S_STEP} [-], got {s_max!r}")
    if not (math.isfinite(zoom) and zoom >= 0.0):
        raise ConfigError(f"zoom must be finite and >= 0 [-], got {zoom!r}")


def fis_scale_array(
    ratios: ArrayLike,
    tol: float,
    s_min: float = S_MIN,
    s_max: float = S_MAX,
    zoom: float = 1.0,
) -> np.ndarray:
    """Vectorised, validated `zoomed_scale` (for plots, tests and batch use).

    Parameters
    ----------
    ratios : array_like, any shape
        Consistency ratios ρ [-].
    tol, s_min, s_max : float
        As in `fis_scale`; validated by `validate_parameters`.
    zoom : float
        Zoom level b ≥ 0 [-]; 1 (default) gives the plain FIS output.

    Returns
    -------
    ndarray, same shape as ``ratios``, float64
        Scale factors [-].
    """
    validate_parameters(tol, s_min, s_max, zoom)
    rho = np.asarray(ratios, dtype=np.float64)
    return _zoomed_many(rho.ravel(), tol, zoom, s_min, s_max).reshape(rho.shape)


def fis_scale_reference(
    ratio: float, tol: float, s_min: float = S_MIN, s_max: float = S_MAX
) -> float:
    """Plain-numpy `fis_scale` with explicit membership arrays (readable; a test reference).

    Parameters and return value as in `fis_scale`; the parameters are validated.
    """
    validate_parameters(tol, s_min, s_max)
    if math.isnan(ratio):
        return 1.0
    rho = max(ratio, 0.0)
    low = float(np.interp(rho, [0.5 * (1 - tol), 1 - tol], [1.0, 0.0]))
    ok = float(np.interp(rho, [1 - tol, 1.0, 1 + tol], [0.0, 1.0, 0.0]))
    high = float(np.interp(rho, [1 + tol, 2 + tol], [0.0, 1.0]))
    if low == ok == high == 0.0:
        return 1.0  # no rule fires (ρ = 1 ± tol): no change
    n_lo, n_hi = round((1 - s_min) / S_STEP), round((s_max - 1) / S_STEP)
    s = 1.0 + np.arange(-n_lo, n_hi + 1) * S_STEP
    decrease = np.interp(s, [s[0], 1 - tol], [1.0, 0.0])
    keep = np.interp(s, [1 - tol, 1.0, 1 + tol], [0.0, 1.0, 0.0])
    increase = np.interp(s, [1 + tol, s[-1]], [0.0, 1.0])
    mu = np.maximum.reduce(
        [np.minimum(low, decrease), np.minimum(ok, keep), np.minimum(high, increase)]
    )
    x0, x1, y0, y1 = s[:-1], s[1:], mu[:-1], mu[1:]
    area = np.sum(0.5 * (x1 - x0) * (y0 + y1))  # ∫ μ ds, μ linear between grid points
    moment = np.sum((x1 - x0) * (x0 * (2 * y0 + y1) + x1 * (y0 + 2 * y1)) / 6)  # ∫ s μ ds
    return float(moment / area)
