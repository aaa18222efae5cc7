import json

import numpy as np

from aeromag_env.interference import VectorCoefficients, vector_interference
from aeromag_env.tolles_lawson import N_TERMS, coefficients_from_vector, design_matrix
from tests._flights import simulated


def test_design_matrix_columns_closed_form():
    b = np.array([[30_000.0, 0.0, 40_000.0]] * 3)
    b[2, 0] += 100.0  # a step: central difference at the middle sample is 50 nT
    a = design_matrix(b)
    assert a.shape == (3, N_TERMS)
    np.testing.assert_allclose(a[0, :3], [0.6, 0.0, 0.8])
    np.testing.assert_allclose(
        a[0, 3:9], np.array([0.6 * 30_000, 0, 0.6 * 40_000, 0, 0, 0.8 * 40_000]) / 5e4
    )
    np.testing.assert_allclose(a[1, 9], 0.6 * 50.0 / 5e4)  # B̂x ΔBx / Bt
    np.testing.assert_allclose(a[1, 15], 0.8 * 50.0 / 5e4)  # B̂z ΔBx / Bt


def test_tl_equals_projection_of_vector_model():
    """The TL coefficients mapped from a vector installation reproduce T̂·ΔT exactly."""
    f = simulated("noise_free", 0)
    t_b = f.vector("truth_earth")
    rng = np.random.default_rng(0)
    coef = VectorCoefficients(
        rng.normal(0, 50, 3), rng.normal(0, 5e-4, (3, 3)), rng.normal(0, 5e-5, (3, 3))
    )
    dt = 0.1
    tdot = np.gradient(t_b, dt, axis=0)
    projection = np.sum(t_b * vector_interference(coef, t_b, tdot), axis=1) / np.linalg.norm(
        t_b, axis=1
    )
    np.testing.assert_allclose(
        design_matrix(t_b) @ coefficients_from_vector(coef, dt), projection, atol=1e-8
    )


def test_simulated_scalar_follows_stored_tl_coefficients():
    f = simulated("noise_free", 0)
    tl = np.array(json.loads(f.attrs["truth_coefficients"])["mag_1_uc"]["tolles_lawson"])
    model = design_matrix(f.vector("truth_earth")) @ tl
    # the sensor reads |T + ΔT| exactly; TL is its linearisation: remainder |ΔT⊥|²/2|T| < 0.2 nT
    # for the stinger's ~50–100 nT field
    assert np.max(np.abs(f["truth_interf_mag_1"] - model)) < 0.2
    assert np.std(f["truth_interf_mag_1"]) > 5  # and the interference itself is not negligible
