import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from aeromag_env.geo.frames import (
    body_to_nav,
    dcm_from_euler,
    earth_radii_m,
    euler_from_dcm,
    nav_to_body,
    time_derivative,
)
from tests._helpers import examples

angles = st.tuples(st.floats(-np.pi, np.pi), st.floats(-1.5, 1.5), st.floats(-np.pi, np.pi))


@given(st.lists(angles, min_size=1, max_size=20))
@settings(max_examples=examples(50), deadline=None)
def test_dcm_matches_scipy_zyx(rpy):
    roll, pitch, yaw = map(np.array, zip(*rpy, strict=True))
    ours = dcm_from_euler(roll, pitch, yaw)
    ref = Rotation.from_euler("ZYX", np.column_stack([yaw, pitch, roll])).as_matrix()
    np.testing.assert_allclose(
        ours, ref, atol=1e-12
    )  # independent implementation, float64 round-off


def test_closed_form_headings():
    t_n = np.array([[20_000.0, 3_000.0, 45_000.0]])  # north, east, down [nT]
    # heading east: body x (nose) points east, body y (right wing) points south
    east = nav_to_body(dcm_from_euler(np.zeros(1), np.zeros(1), np.array([np.pi / 2])), t_n)
    np.testing.assert_allclose(east[0], [3_000.0, -20_000.0, 45_000.0], atol=1e-9)
    # right wing down 90°: body y points down, body z points left (west)
    rolled = nav_to_body(dcm_from_euler(np.array([np.pi / 2]), np.zeros(1), np.zeros(1)), t_n)
    np.testing.assert_allclose(rolled[0], [20_000.0, 45_000.0, -3_000.0], atol=1e-9)
    # nose up 90°: body x points up
    pitched = nav_to_body(dcm_from_euler(np.zeros(1), np.array([np.pi / 2]), np.zeros(1)), t_n)
    np.testing.assert_allclose(pitched[0][0], -45_000.0, atol=1e-9)


def test_round_trips():
    rng = np.random.default_rng(1)
    roll, yaw = rng.uniform(-3, 3, (2, 100))
    pitch = rng.uniform(-1.5, 1.5, 100)
    c = dcm_from_euler(roll, pitch, yaw)
    r2, p2, y2 = euler_from_dcm(c)
    np.testing.assert_allclose(dcm_from_euler(r2, p2, y2), c, atol=1e-12)
    v = rng.normal(size=(100, 3))
    np.testing.assert_allclose(body_to_nav(c, nav_to_body(c, v)), v, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(nav_to_body(c, v), axis=1), np.linalg.norm(v, axis=1))


def test_time_derivative_schemes():
    tt = np.arange(0, 10, 0.1)
    x = np.column_stack([np.sin(tt), 3 * tt**2])
    exact = np.column_stack([np.cos(tt), 6 * tt])
    central = time_derivative(x, tt, "central")
    # second order: interior error ≤ h²/6·max|x‴| = 1.7e-3, one-sided ends ≤ h²/3 = 3.3e-3;
    # exact for the quadratic
    np.testing.assert_allclose(central[1:-1], exact[1:-1], atol=1.7e-3)
    np.testing.assert_allclose(central, exact, atol=3.4e-3)
    back = time_derivative(x, tt, "backward")
    np.testing.assert_allclose(back[1:], np.diff(x, axis=0) / 0.1)
    np.testing.assert_array_equal(back[0], back[1])


def test_earth_radii_wgs84():
    r_m, r_n = earth_radii_m(np.array([0.0, np.pi / 2]))
    # WGS84 closed forms: equator R_N = a, R_M = a(1-e²); pole R_M = R_N = a/sqrt(1-e²)
    np.testing.assert_allclose(r_n[0], 6_378_137.0, rtol=1e-12)
    np.testing.assert_allclose(r_m[0], 6_335_439.327, rtol=1e-9)
    np.testing.assert_allclose(r_m[1], r_n[1], rtol=1e-12)
