import datetime as dt

import numpy as np
import ppigrf
import pytest

from aeromag_env.geo.earth import (
    _same_bits,
    clear_caches,
    external_variation_ned,
    igrf_ned,
    igrf_ned_along_track,
    parse_date,
)
from tests._flights import simulated


def test_igrf_ned_matches_ppigrf_components():
    be, bn, bu = ppigrf.igrf(-76.0, 45.3, 3.0, dt.datetime(2026, 6, 1))
    ned = igrf_ned(np.deg2rad([45.3]), np.deg2rad([-76.0]), np.array([3000.0]), "2026-06-01")
    np.testing.assert_allclose(ned[0], [bn.item(), be.item(), -bu.item()])
    # sanity on the physics: mid-latitude northern hemisphere, field points down, ~52 000 nT
    assert ned[0, 2] > 0 and 45_000 < np.linalg.norm(ned[0]) < 60_000


@pytest.mark.parametrize("date", ["2026-06-01", "2016-03-04", "2029-12-31", "1965-01-01"])
def test_cached_coefficient_synthesis_equals_ppigrf_everywhere(date):
    """igrf_ned caches the coefficients per date; its field must still be ppigrf's, worldwide."""
    rng = np.random.default_rng(7)
    lat, lon, h = (
        rng.uniform(-89.9, 89.9, 400),
        rng.uniform(-180, 180, 400),
        rng.uniform(0, 12e3, 400),
    )
    be, bn, bu = ppigrf.igrf(lon, lat, h / 1000.0, dt.datetime.fromisoformat(date))
    ned = igrf_ned(np.deg2rad(lat), np.deg2rad(lon), h, date)
    ref = np.column_stack([bn.ravel(), be.ravel(), -bu.ravel()])
    np.testing.assert_allclose(ned, ref, rtol=0, atol=1e-9)  # [nT]


def test_igrf_date_outside_the_model_warns():
    with pytest.warns(UserWarning, match="outside the IGRF coefficient file"):
        igrf_ned(np.deg2rad([45.0]), np.deg2rad([-75.0]), np.array([0.0]), "2040-01-01")


@pytest.mark.parametrize("pattern", ["calibration", "calibration+survey"])
def test_interpolated_igrf_within_0p1_nt_of_direct(pattern):
    f = simulated("paper", 3, trajectory__pattern=pattern)
    lat, lon, alt = f.position_rad()
    direct = igrf_ned(lat, lon, alt, f.date())
    interp = igrf_ned_along_track(f.tt, lat, lon, alt, f.date(), grid_spacing_s=10.0)
    assert np.max(np.abs(interp - direct)) < 0.1  # [nT], the bound


def test_a_remembered_track_is_bitwise_its_evaluation_and_is_the_callers_to_change():
    tt = np.arange(0, 120, 0.1)
    lat = np.deg2rad(45.0) + 1e-5 * np.sin(tt / 7)
    lon = np.full(tt.size, np.deg2rad(-75.0))
    alt = 3000 + 4 * np.sin(2 * np.pi * tt / 5)
    clear_caches()
    cold = igrf_ned_along_track(tt, lat, lon, alt, "2026-06-01")
    cold[:] = 0.0  # the caller's copy: the remembered field is not touched
    warm = igrf_ned_along_track(tt, lat, lon, alt, "2026-06-01")
    clear_caches()
    again = igrf_ned_along_track(tt, lat, lon, alt, "2026-06-01")
    assert warm.tobytes() == again.tobytes()
    moved = igrf_ned_along_track(tt, lat + 1e-4, lon, alt, "2026-06-01")  # not a hit
    assert np.all(np.abs(moved - again).max(axis=0) > 0.1)  # [nT]: 0.6 km north moves it
    # the track is compared bit for bit: zero signs and NaN payloads count, == would not
    assert not _same_bits(np.array([0.0]), np.array([-0.0]))
    assert _same_bits(np.array([np.nan]), np.array([np.nan]))


def test_vertical_gradient_term_matters():
    """Pitch maneuvers move the aircraft ±4 m between grid points; without the gradient term the
    spline alone misses that by more than the 0.1 nT bound would allow for larger excursions."""
    tt = np.arange(0, 60, 0.1)
    lat = np.full(tt.size, np.deg2rad(45.0))
    lon = np.full(tt.size, np.deg2rad(-75.0))
    alt = 3000 + 50 * np.sin(2 * np.pi * tt / 5)  # ±50 m at 5 s
    direct = igrf_ned(lat, lon, alt, "2026-06-01")
    interp = igrf_ned_along_track(tt, lat, lon, alt, "2026-06-01", grid_spacing_s=10.0)
    assert np.max(np.abs(interp - direct)) < 0.05
    swing = np.ptp(direct[:, 2])
    assert swing > 1.0  # the field really changes by > 1 nT over ±50 m (~0.02 nT/m)


def test_external_variation_statistics():
    rng = np.random.default_rng(0)
    tt = np.arange(0, 3600, 0.1)
    ext = external_variation_ned(tt, dt.datetime(2026, 6, 1, 12), 0.0, 3.0, 600.0, rng)
    assert ext.shape == (tt.size, 3)
    ext_cycle = external_variation_ned(tt, dt.datetime(2026, 6, 1, 12), 30.0, 0.0, 600.0, rng)
    np.testing.assert_array_equal(ext[0], 0.0)  # referenced to the start of the flight
    # a daily cycle of 30 nT moves by at most 2π·30/24 ≈ 7.9 nT per hour per component
    assert np.all(np.ptp(ext_cycle, axis=0) < 8.0)
    assert np.ptp(ext_cycle[:, 0]) > 0.5


def test_parse_date_errors():
    assert parse_date("2026-06-01T14:00:00") == dt.datetime(2026, 6, 1, 14)
    with pytest.raises(ValueError, match="ISO 8601"):
        parse_date("June 1st")
