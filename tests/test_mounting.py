"""Tests for aeromag_env.flight.mounting: the fluxgate mount recovered from a simulated flight whose
fluxgate is turned by a known rotation, against scipy's Wahba solver and the body-aligned flight."""

from __future__ import annotations

import numpy as np
import pytest

from aeromag_env.compensation.compensate import compensate_vector, score
from aeromag_env.errors import AeromagError
from aeromag_env.flight.data import Flight, vector_names
from aeromag_env.flight.mounting import (
    Mount,
    estimate_mount,
    mount_residual_nt,
    mount_warning,
    solve_wahba,
)
from aeromag_env.simulation.config import preset, with_overrides
from aeromag_env.simulation.simulate import simulate_flight

#: Sensor x, y, z = body right, down, forward (the SGL flux_a layout, roughly).
AXIS_SWAP = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
MOUNTS = {
    "axis_swap": AXIS_SWAP,
    "45_deg": Mount.from_angles_deg(10.0, -20.0, 45.0).rotation,
}


@pytest.fixture(scope="module")
def box() -> Flight:
    """A 15-minute nominal calibration box (seed 3), fluxgate along the body axes."""
    cfg = with_overrides(
        preset("nominal"), {"trajectory.pattern": "calibration", "trajectory.duration_s": 900.0}
    )
    return simulate_flight(cfg, rng=3)


def _remounted(flight: Flight, rotation: np.ndarray) -> Flight:
    """The same flight with ``flux_a`` read in the axes of a sensor mounted by ``rotation``."""
    fields = dict(flight.fields)
    turned = flight.vector("flux_a") @ rotation.T  # m_s = R m_b per row
    fields.update(zip(vector_names("flux_a"), turned.T, strict=True))
    return Flight(fields=fields, attrs=dict(flight.attrs))


@pytest.mark.parametrize("name", MOUNTS)
def test_mount_recovered_within_a_degree(box: Flight, name: str) -> None:
    true = Mount(MOUNTS[name])
    est = estimate_mount(_remounted(box, true.rotation), "flux_a")
    # 1° [deg]: the bound; the rest is the antisymmetric part of the induced matrix A,
    # which a rotation cannot be told apart from (module docstring)
    assert true.angle_to_deg(est) < 1.0
    assert est.source == "estimated" and est.samples == box.n
    # the fit explains the reading to the interference's size, not the Earth field's [nT]
    assert est.residual_nt < 200.0
    assert mount_residual_nt(Mount.identity(), box.vector("flux_a") @ true.rotation.T,
                             box.vector("truth_earth")) > 10_000.0  # fmt: skip


def test_solver_agrees_with_scipy_on_centred_data() -> None:
    """Our wrapper returns scipy's Kabsch solution of the centred problem, offset included."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(0)
    t = rng.normal(0.0, 20_000.0, (500, 3))
    true = Rotation.from_euler("ZYX", [30.0, -10.0, 70.0], degrees=True).as_matrix()
    m = t @ true.T + np.array([300.0, -150.0, 80.0]) + rng.normal(0.0, 5.0, (500, 3))
    est = solve_wahba(m, t)
    ref = Rotation.align_vectors(m - m.mean(0), t - t.mean(0))[0].as_matrix()
    np.testing.assert_allclose(est.rotation, ref, atol=1e-12)
    assert Mount(true).angle_to_deg(est) < 0.01  # 5 nT noise on 20 000 nT [deg]
    assert est.residual_nt == pytest.approx(5.0 * np.sqrt(3), rel=0.1)  # 3 axes of 5 nT [nT]


@pytest.mark.parametrize("name", MOUNTS)
@pytest.mark.parametrize("method", ["lsq", "kf"])
def test_compensation_with_the_estimated_mount_matches_the_aligned_flight(
    box: Flight, name: str, method: str
) -> None:
    """The compensated field (residual std, improvement ratio, FOM) is within 10 % of the
    body-aligned flight's. The interference vector itself is known only up to the rotation the
    mount absorbs from A (about 0.1° here, ~40 nT of 50 000): without the mount it is the whole
    Earth field turned (tens of thousands of nT)."""
    turned = _remounted(box, MOUNTS[name])
    mount = estimate_mount(turned, "flux_a")
    aligned = score(box, compensate_vector(box, method))
    mounted = score(turned, compensate_vector(turned, method, mount=mount))
    ignored = score(turned, compensate_vector(turned, method))
    for key in ("residual_std_nt", "improvement_ratio", "fom_nt"):
        assert mounted[key] == pytest.approx(aligned[key], rel=0.10), key
    angle_rad = np.deg2rad(Mount(MOUNTS[name]).angle_to_deg(mount))
    # the unidentifiable part: about |T| · angle (|T| ≈ 50 000 nT in this box) [nT]
    assert mounted["compensation_rmse_nt"] < 60_000.0 * angle_rad
    assert ignored["compensation_rmse_nt"] > 10_000.0


def test_warning_names_the_angle_only_when_the_mount_is_wrong(box: Flight) -> None:
    turned = _remounted(box, AXIS_SWAP)
    est = estimate_mount(turned, "flux_a")
    message = mount_warning(Mount.identity(), est, "flux_a")
    assert message is not None and "119.9°" in message and message.startswith("flux_a:")
    assert mount_warning(Mount(AXIS_SWAP, source="file"), est, "flux_a") is None
    assert mount_warning(Mount.identity(), estimate_mount(box, "flux_a"), "flux_a") is None


def test_mount_round_trips_through_angles() -> None:
    mount = Mount.from_angles_deg(12.0, -33.0, 140.0)
    assert mount.angles_deg() == pytest.approx((12.0, -33.0, 140.0))
    np.testing.assert_allclose(mount.rotation @ mount.rotation.T, np.eye(3), atol=1e-12)
    v = np.array([[1.0, 2.0, 3.0]])
    np.testing.assert_allclose(mount.to_body(v @ mount.rotation.T), v)  # sensor → body undoes it


def test_too_little_attitude_variation_is_refused() -> None:
    """A straight, level leg on one heading moves the field along one direction only, which
    cannot fix a rotation: a one-line error, not a guess."""
    rng = np.random.default_rng(1)
    drift = np.outer(np.linspace(0.0, 1.0, 600), [30.0, 5.0, -20.0])  # IGRF along track [nT]
    t = np.array([20_000.0, 1_000.0, 45_000.0]) + drift
    m = t @ AXIS_SWAP.T + rng.normal(0.0, 0.01, t.shape)  # 0.01 nT sensor noise [nT]
    with pytest.raises(AeromagError, match="too little attitude variation"):
        solve_wahba(m, t)
    with pytest.raises(AeromagError, match="valid samples"):
        solve_wahba(np.full((600, 3), np.nan), t)
