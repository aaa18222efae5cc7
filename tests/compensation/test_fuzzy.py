"""Tests for aeromag_env.compensation.fuzzy: the FIS of paper §3.4 against scikit-fuzzy, a numpy
reference and the paper's three rules. All quantities are dimensionless ratios/factors [-]."""

from __future__ import annotations

import math

import numba
import numpy as np
import pytest
import skfuzzy as fuzz
from hypothesis import given, settings
from hypothesis import strategies as st

from aeromag_env.compensation.fuzzy import (
    EPSILON_R,
    ETA_Q,
    S_MAX,
    S_MIN,
    S_STEP,
    fis_scale,
    fis_scale_array,
    fis_scale_reference,
    zoomed_scale,
)
from aeromag_env.errors import ConfigError
from tests._helpers import assert_one_line_error, examples

TOLS = [EPSILON_R, ETA_Q]


def ratio_grid(tol: float) -> np.ndarray:
    """Dense linear grid on [0, 4], a log grid up to 1e6, and the band edges and centre."""
    edges = [1 - tol, 1 + tol, 1.0, 0.5 * (1 - tol), 2 + tol]
    return np.sort(np.concatenate([np.linspace(0, 4, 4001), np.logspace(-3, 6, 181), edges]))


def skfuzzy_scale(rho: float, tol: float, s_min: float = S_MIN, s_max: float = S_MAX) -> float:
    """The same Mamdani FIS built from scikit-fuzzy parts (an independent implementation)."""
    x = np.array([min(max(rho, 0.0), 1e300)])  # trapmf needs finite input
    low = fuzz.trapmf(x, [-1.0, -1.0, 0.5 * (1 - tol), 1 - tol])[0]
    ok = fuzz.trimf(x, [1 - tol, 1.0, 1 + tol])[0]
    high = fuzz.trapmf(x, [1 + tol, 2 + tol, 1e300, 1e300])[0]
    s = np.linspace(s_min, s_max, round((s_max - s_min) / S_STEP) + 1)
    decrease = fuzz.trimf(s, [s_min, s_min, 1 - tol])
    keep = fuzz.trimf(s, [1 - tol, 1.0, 1 + tol])
    increase = fuzz.trimf(s, [1 + tol, s_max, s_max])
    aggregated = np.fmax(
        np.fmin(low, decrease), np.fmax(np.fmin(ok, keep), np.fmin(high, increase))
    )
    if aggregated.sum() == 0:  # no rule fires: skfuzzy raises, our FIS means "no change"
        return 1.0
    if np.trapezoid(aggregated, s) < 1e-12:
        # skfuzzy divides by max(area, float eps): wrong for firing strengths ~1e-14 (ρ one ulp
        # off a band edge); no reference there
        return math.nan
    return float(fuzz.defuzz(s, aggregated, "centroid"))


def assert_rules(rho: float, s: float, tol: float) -> None:
    """The paper's three rules (§3.4), with the band edges classified as in the FIS."""
    if rho > 1 + tol:
        assert s > 1 + tol, (rho, s)
    elif rho < 1 - tol:
        assert s < 1 - tol, (rho, s)
    else:
        assert abs(s - 1) <= tol, (rho, s)


@pytest.mark.parametrize("tol", TOLS)
def test_matches_scikit_fuzzy(tol):
    rho = ratio_grid(tol)
    ours = fis_scale_array(rho, tol)
    ref = np.array([skfuzzy_scale(r, tol) for r in rho])
    has_ref = np.isfinite(ref)
    assert np.count_nonzero(~has_ref) <= 4  # only ρ within a few ulp of the band edges
    # same centroid definition on the same grid; differences are float64 round-off [-]
    np.testing.assert_allclose(ours[has_ref], ref[has_ref], rtol=0, atol=1e-10)


@pytest.mark.parametrize(
    ("tol", "s_min", "s_max"), [(0.05, 0.5, 2.0), (0.025, 0.5, 2.0), (0.1, 0.3, 3.0)]
)
def test_compiled_matches_numpy_reference(tol, s_min, s_max):
    rho = np.concatenate([ratio_grid(tol)[::7], [np.inf, np.nan, -1.0]])
    ours = fis_scale_array(rho, tol, s_min, s_max)
    ref = np.array([fis_scale_reference(r, tol, s_min, s_max) for r in rho])
    np.testing.assert_allclose(ours, ref, rtol=0, atol=1e-12)  # same arithmetic, reordered [-]


def test_closed_form_end_values():
    # Kinks on the grid make the piecewise-linear centroid exact: a full ramp is a triangle whose
    # centroid lies a third of the way from its peak.
    tol = EPSILON_R
    full_decrease = S_MIN + (1 - tol - S_MIN) / 3
    full_increase = S_MAX - (S_MAX - 1 - tol) / 3
    s = fis_scale_array([0.0, 0.5 * (1 - tol), 2 + tol, 10.0, 1e6], tol)
    np.testing.assert_allclose(s, [full_decrease] * 2 + [full_increase] * 3, rtol=0, atol=1e-12)


@pytest.mark.parametrize("tol", TOLS)
def test_rules_monotone_and_band(tol):
    rho = ratio_grid(tol)
    s = fis_scale_array(rho, tol)
    for r, v in zip(rho, s, strict=True):
        assert_rules(r, v, tol)
    assert np.all(np.diff(s) >= -1e-12)  # non-decreasing up to round-off [-]
    band = (rho >= 1 - tol) & (rho <= 1 + tol)
    # only `keep` fires, clipped symmetrically about 1 on a grid through 1 [-]
    np.testing.assert_allclose(s[band], 1.0, rtol=0, atol=1e-12)


def test_special_inputs():
    tol = EPSILON_R
    assert fis_scale(math.nan, tol) == 1.0
    assert fis_scale(math.inf, tol) == fis_scale(1e6, tol)
    assert fis_scale(-5.0, tol) == fis_scale(0.0, tol)
    assert fis_scale(1 - tol, tol) == 1.0  # no rule fires at the band edges
    assert fis_scale(1 + tol, tol) == 1.0
    assert fis_scale_reference(math.nan, tol) == 1.0
    assert fis_scale_reference(math.inf, tol) == pytest.approx(fis_scale(1e6, tol), abs=1e-12)


@pytest.mark.parametrize("rho", [0.2, 0.9, 1.0, 1.3, 5.0])
def test_zoom_levels(rho):
    s = fis_scale(rho, EPSILON_R)
    assert zoomed_scale(rho, EPSILON_R, 0.0) == 1.0  # b = 0: the plain Kalman filter
    assert zoomed_scale(rho, EPSILON_R, 1.0) == pytest.approx(s, abs=1e-15)
    assert zoomed_scale(rho, EPSILON_R, 2.0) == pytest.approx(s**2, abs=1e-14)
    assert fis_scale_array([rho], EPSILON_R, zoom=0.5)[0] == pytest.approx(math.sqrt(s), abs=1e-14)


def test_array_keeps_shape_and_callable_from_njit():
    rho = np.array([[0.1, 1.0], [2.0, np.inf]])
    assert fis_scale_array(rho, ETA_Q).shape == (2, 2)

    @numba.njit
    def per_window(ratios):
        return np.array([zoomed_scale(r, ETA_Q, 0.5) * fis_scale(r, ETA_Q) for r in ratios])

    np.testing.assert_allclose(
        per_window(rho.ravel()), fis_scale_array(rho.ravel(), ETA_Q) ** 1.5, rtol=0, atol=1e-14
    )


@given(
    tol=st.floats(0.01, 0.2),
    rho=st.one_of(st.floats(0.0, 3.0), st.floats(0.0, 1e6), st.floats(0.75, 1.25)),
)
@settings(max_examples=examples(300), deadline=None)
def test_rules_property(tol, rho):
    assert_rules(rho, fis_scale(rho, tol), tol)


@given(data=st.data(), tol=st.floats(0.01, 0.2))
@settings(max_examples=examples(100), deadline=None)
def test_rules_property_any_valid_universe(data, tol):
    # the tightest universes validation allows: each output ramp spans >= one grid step
    k_lo = data.draw(st.integers(1, math.floor((1 - tol) / S_STEP - 1e-9) - 1))
    k_hi = data.draw(st.integers(math.ceil((1 + tol) / S_STEP + 1e-9) + 1, 1000))
    s_min, s_max = k_lo * S_STEP, k_hi * S_STEP
    rho = data.draw(st.floats(0.0, 5.0))
    assert_rules(rho, fis_scale_array([rho], tol, s_min, s_max)[0], tol)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"tol": 0.0}, "tol"),
        ({"tol": 0.5}, "tol"),
        ({"tol": math.nan}, "tol"),
        ({"s_min": 0.0}, "s_min"),
        ({"s_min": 0.95}, "s_min"),
        ({"s_min": 0.4321}, "s_min"),
        ({"s_max": 1.05}, "s_max"),
        ({"s_max": math.inf}, "s_max"),
        ({"s_max": 2.0001}, "s_max"),
        ({"zoom": -0.1}, "zoom"),
        ({"zoom": math.nan}, "zoom"),
    ],
)
def test_bad_parameters(kwargs, name):
    params = {"tol": EPSILON_R, "s_min": S_MIN, "s_max": S_MAX} | kwargs
    zoom = params.pop("zoom", 1.0)
    with pytest.raises(ConfigError, match=rf"^{name} ") as info:
        fis_scale_array([1.0], zoom=zoom, **params)
    assert_one_line_error(info)
    if "zoom" not in kwargs:
        with pytest.raises(ConfigError, match=rf"^{name} "):
            fis_scale_reference(1.0, **params)
