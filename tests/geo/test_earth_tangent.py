"""IGRF-14 from tangent planes: within 0.01 nT of IGRF at every sample, and the same numbers
sample by sample as on a whole track."""

from __future__ import annotations

import numpy as np

from aeromag_env.geo.earth import igrf_ned
from aeromag_env.geo.earth_tangent import ANCHOR_SPACING_M, TangentTrack, tangent_track
from aeromag_env.simulation.config import preset, with_overrides
from aeromag_env.simulation.simulate import simulate_flight


def _track():
    cfg = with_overrides(
        preset("nominal"), {"trajectory.pattern": "survey", "trajectory.duration_s": 300.0}
    )
    flight = simulate_flight(cfg, 5)
    return (*flight.position_rad(), flight.date())


def test_tangent_track_is_within_a_hundredth_of_a_nanotesla_of_igrf():
    lat, lon, alt, date = _track()
    # 0.01 nT: the curvature bound over ANCHOR_SPACING_M (module docstring), far below the
    # sensors' noise
    assert ANCHOR_SPACING_M == 1000.0
    np.testing.assert_allclose(
        tangent_track(lat, lon, alt, date), igrf_ned(lat, lon, alt, date), atol=0.01
    )


def test_sample_by_sample_equals_the_whole_track_bit_for_bit():
    lat, lon, alt, date = _track()
    lat = lat.copy()
    lat[100] = np.nan  # an unknown position: NaN, the anchor kept
    whole = tangent_track(lat, lon, alt, date)
    live = TangentTrack(date)
    one = np.array([live.field(a, b, c) for a, b, c in zip(lat, lon, alt, strict=True)])
    np.testing.assert_array_equal(one, whole)
    assert np.isnan(whole[100]).all() and live.anchors > 2
