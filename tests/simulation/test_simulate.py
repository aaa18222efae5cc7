import json

import numpy as np
import pytest

from aeromag_env.geo.earth import igrf_ned
from aeromag_env.geo.frames import dcm_from_euler, nav_to_body, time_derivative
from aeromag_env.simulation.simulate import clear_caches, simulate_flight
from tests._flights import config_for, simulated


def _sensor_noise(f):
    return f.vector("flux_a") - f.vector("truth_earth") - f.vector("truth_interf")


def test_body_field_is_rotated_ned_field():
    """truth_earth (body) equals the direct IGRF at the file's positions rotated by the file's
    attitude (paper preset: no external field), i.e. the simulator and an independent path agree."""
    f = simulated("paper", 11)
    lat, lon, alt = f.position_rad()
    t_n = igrf_ned(lat, lon, alt, f.date())
    t_b = nav_to_body(dcm_from_euler(*f.attitude_rad()), t_n)
    assert np.max(np.abs(f.vector("truth_earth") - t_b)) < 0.1  # [nT] the interpolation bound
    # rotation preserves magnitude
    np.testing.assert_allclose(
        np.linalg.norm(f.vector("truth_earth"), axis=1), np.linalg.norm(t_n, axis=1), atol=0.1
    )


def test_paper_preset_noise_is_white_20nt():
    f = simulated("paper", 5, trajectory__duration_s=3600.0)
    e = _sensor_noise(f)
    # n = 36 000 per axis: the sample std has a relative standard error of 1/sqrt(2n) = 0.4 %,
    # so ±5 % is far outside chance
    np.testing.assert_allclose(e.std(axis=0), 20.0, rtol=0.05)
    np.testing.assert_allclose(e.mean(axis=0), 0.0, atol=4 * 20.0 / np.sqrt(e.shape[0]))
    lag1 = [np.corrcoef(e[1:, i], e[:-1, i])[0, 1] for i in range(3)]
    np.testing.assert_allclose(lag1, 0.0, atol=4 / np.sqrt(e.shape[0]))  # white: |ρ₁| < 4σ


def test_fogm_noise_has_configured_std_and_autocorrelation():
    tau, sigma = 1.0, 5.0
    f = simulated(
        "paper",
        9,
        trajectory__duration_s=3600.0,
        fluxgate_noise__white_std_nt=0.0,
        fluxgate_noise__fogm_std_nt=sigma,
        fluxgate_noise__fogm_tau_s=tau,
    )
    e = _sensor_noise(f)
    # effective sample size ≈ n·dt/(2τ) = 1800 → std standard error ≈ 1.7 %; 5 % is 3σ
    np.testing.assert_allclose(e.std(axis=0), sigma, rtol=0.05)
    for lag in (1, 5, 10, 20):
        rho = np.mean([np.corrcoef(e[lag:, i], e[:-lag, i])[0, 1] for i in range(3)])
        # exact FOGM autocorrelation exp(-lag·dt/τ); the estimate's error is ≲ 0.03 here
        assert rho == pytest.approx(np.exp(-lag * 0.1 / tau), abs=0.04)


def test_nominal_noise_white_part_from_differences():
    """Nominal: 1 nT white + 1 nT FOGM (τ = 600 s). Differencing removes the slow FOGM, so
    std(Δe)/√2 estimates the white std (FOGM adds only σ²(1 - e^{-dt/τ}) ≈ 1.7e-4 nT²)."""
    f = simulated("nominal", 2, trajectory__duration_s=3600.0)
    e = _sensor_noise(f)
    np.testing.assert_allclose(np.diff(e, axis=0).std(axis=0) / np.sqrt(2), 1.0, rtol=0.05)


def test_interference_is_realistic_and_matches_stored_coefficients():
    f = simulated("nominal", 0)
    coef = json.loads(f.attrs["truth_coefficients"])["flux_a"]
    interf = f.vector("truth_interf")
    t_b = f.vector("truth_earth")
    rebuilt = (
        np.array(coef["permanent_nt"])
        + t_b @ np.array(coef["induced"]).T
        + time_derivative(t_b, f.tt) @ np.array(coef["eddy_s"]).T
    )
    np.testing.assert_allclose(rebuilt, interf, atol=1e-6)  # the stored truth rebuilds the field
    eddy = time_derivative(t_b, f.tt) @ np.array(coef["eddy_s"]).T
    in_maneuver = f["maneuver"] > 0
    assert 0.5 < np.abs(eddy[in_maneuver]).max() < 20  # "a few nT during maneuvers"


def test_default_interference_is_cabin_like_across_draws():
    """DESIGN.md: cabin interference of 100–1000 nT RMS. Over 400 coefficient draws on one
    calibration box, at least 95 % fall in that range (expected ≈ 97 %: T_p dominates and
    |T_p|²/200² is χ² with 3 degrees of freedom)."""
    from aeromag_env.simulation.config import InterferenceConfig
    from aeromag_env.simulation.interference import draw_coefficients, vector_interference

    f = simulated("noise_free", 0)
    t_b = f.vector("truth_earth")
    tdot = time_derivative(t_b, f.tt)
    rng = np.random.default_rng(0)
    rms = np.array(
        [
            np.sqrt(
                np.mean(
                    np.sum(
                        vector_interference(draw_coefficients(InterferenceConfig(), rng), t_b, tdot)
                        ** 2,
                        axis=1,
                    )
                )
            )
            for _ in range(400)
        ]
    )
    inside = np.mean((rms > 100) & (rms < 1000))
    assert inside >= 0.95
    assert 250 < np.median(rms) < 500


def test_scalar_magnetometer_and_diurnal():
    f = simulated("nominal", 0)
    total = np.linalg.norm(f.vector("truth_earth"), axis=1)
    resid = f["mag_1_uc"] - total - f["truth_interf_mag_1"]
    np.testing.assert_allclose(resid.std(), 0.01, rtol=0.1)  # configured scalar white noise
    assert "diurnal" in f and np.std(f["diurnal"]) > 0
    assert "mag_1_uc" not in simulated("paper", 0) and "diurnal" not in simulated("paper", 0)


def test_same_seed_same_flight_different_seed_different():
    cfg = config_for("nominal")
    a, b, c = simulate_flight(cfg, 4), simulate_flight(cfg, 4), simulate_flight(cfg, 5)
    assert a.names == b.names and a.attrs == b.attrs
    for nm in a.names:
        np.testing.assert_array_equal(a[nm], b[nm])
    assert not np.array_equal(a["flux_a_x"], c["flux_a_x"])
    assert a.attrs["truth_coefficients"] != c.attrs["truth_coefficients"]


def test_remembered_pattern_and_igrf_change_nothing():
    """The trajectory pattern and its IGRF are remembered between simulations: a warm run must
    equal a cold one bit for bit, and changing a returned flight must not reach the next."""
    cfg = config_for("nominal")
    clear_caches()
    cold = simulate_flight(cfg, 6)
    cold["flux_a_x"][:] = 0.0  # a caller scribbling on its flight
    cold["lat"][:] = 0.0
    warm = simulate_flight(cfg, 6)
    clear_caches()
    again = simulate_flight(cfg, 6)
    for nm in again.names:
        np.testing.assert_array_equal(warm[nm], again[nm], err_msg=nm)
    assert np.all(warm["lat"] != 0.0)


def test_noise_change_keeps_trajectory_and_coefficients():
    """Each stage has its own random stream: more noise must not move the aircraft."""
    a = simulated("nominal", 3)
    b = simulated("paper", 3)
    np.testing.assert_array_equal(a["ins_roll"], b["ins_roll"])
    assert (
        json.loads(a.attrs["truth_coefficients"])["flux_a"]
        == json.loads(b.attrs["truth_coefficients"])["flux_a"]
    )


def test_config_recorded_and_recreates_flight():
    from aeromag_env.configs import from_json
    from aeromag_env.simulation.config import SimulationConfig

    f = simulated("nominal", 8)
    again = simulate_flight(from_json(SimulationConfig, f.attrs["config"]), int(f.attrs["seed"]))
    np.testing.assert_array_equal(again["flux_a_z"], f["flux_a_z"])
