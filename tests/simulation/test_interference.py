import numpy as np

from aeromag_env.simulation.config import InterferenceConfig
from aeromag_env.simulation.interference import (
    N_STATES,
    STATE_SLICES,
    VectorCoefficients,
    draw_coefficients,
    scalar_interference,
    vector_interference,
)


def test_closed_form_single_terms():
    t_b = np.array([[10_000.0, -2_000.0, 45_000.0]])
    tdot = np.array([[100.0, 0.0, -50.0]])
    a = np.zeros((3, 3))
    a[0, 2] = 1e-3  # x picks up 1e-3 of the z field
    b = np.zeros((3, 3))
    b[2, 0] = 2e-4  # z picks up 2e-4 s of the x rate
    coef = VectorCoefficients(np.array([1.0, 2.0, 3.0]), a, b)
    np.testing.assert_allclose(vector_interference(coef, t_b, tdot)[0], [1 + 45.0, 2.0, 3 + 0.02])


def test_state_layout_round_trip():
    rng = np.random.default_rng(0)
    x = rng.normal(size=N_STATES)
    coef = VectorCoefficients.from_state(x)
    np.testing.assert_array_equal(coef.as_state(), x)
    np.testing.assert_array_equal(coef.induced.ravel(), x[STATE_SLICES["induced"]])


def test_draws_respect_explicit_values_and_scales():
    rng = np.random.default_rng(0)
    cfg = InterferenceConfig(permanent_nt=(1.0, 2.0, 3.0), induced_std=1e-3, eddy_std_s=0.0)
    coefs = [draw_coefficients(cfg, rng) for _ in range(400)]
    assert all(np.array_equal(c.permanent_nt, [1, 2, 3]) for c in coefs)
    induced = np.array([c.induced for c in coefs]).ravel()
    # 3600 draws: the sample std is within 5 % of 1e-3 with overwhelming probability (SE 1.2 %)
    np.testing.assert_allclose(induced.std(), 1e-3, rtol=0.05)
    assert all(not c.eddy_s.any() for c in coefs)


def test_scalar_interference_linearises_to_projection():
    rng = np.random.default_rng(1)
    t_b = rng.normal(size=(50, 3))
    t_b *= 50_000 / np.linalg.norm(t_b, axis=1, keepdims=True)
    tdot = rng.normal(scale=1000, size=(50, 3))
    coef = VectorCoefficients(
        rng.normal(0, 30, 3), rng.normal(0, 3e-4, (3, 3)), rng.normal(0, 5e-5, (3, 3))
    )
    exact = scalar_interference(coef, t_b, tdot)
    d = vector_interference(coef, t_b, tdot)
    linear = np.sum(t_b * d, axis=1) / np.linalg.norm(t_b, axis=1)
    perp2 = np.sum(d**2, axis=1) - linear**2
    # second-order remainder |ΔT⊥|²/(2|T|); the next term, ~|ΔT∥||ΔT⊥|²/(2|T|²), is < 2e-5 nT
    # at |ΔT| ≈ 50–100 nT, so that is the tolerance
    np.testing.assert_allclose(exact - linear, perp2 / (2 * 50_000), atol=2e-5)
