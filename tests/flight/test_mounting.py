"""Tests for aeromag_env.flight.mounting and mount_choice: the fluxgate mount recovered from a
simulated flight whose fluxgate is turned by a known rotation, against scipy's Wahba solver and the
body-aligned flight; ``--mount auto|identity|FILE`` through ``aeromag compensate``, ``discover``
and ``info``."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from aeromag_env.cli.main import main
from aeromag_env.compensation.compensate import compensate_vector, score
from aeromag_env.errors import AeromagError, AeromagWarning
from aeromag_env.flight.data import Flight, vector_names
from aeromag_env.flight.files import write_flight
from aeromag_env.flight.info import describe
from aeromag_env.flight.mount_choice import (
    APPLY_ANGLE_DEG,
    check_rotation,
    choose_mount,
    read_mount_file,
)
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
    assert (
        mount_residual_nt(
            Mount.identity(), box.vector("flux_a") @ true.rotation.T, box.vector("truth_earth")
        )
        > 10_000.0
    )


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
    with pytest.warns(AeromagWarning, match="pass mount="):  # never silent
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


# --- choosing the mount: --mount auto|identity|FILE, through the library and the CLI ---------


@pytest.fixture(scope="module")
def box_files(box: Flight, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The box written body-aligned, with flux_a remounted per MOUNTS, and with two fluxgates
    mounted differently (flux_a: axis swap, flux_b: 45°)."""
    folder = tmp_path_factory.mktemp("mounts")
    files = {"aligned": write_flight(box, folder / "aligned.h5")}
    for name, rotation in MOUNTS.items():
        files[name] = write_flight(_remounted(box, rotation), folder / f"{name}.h5")
    turned = _remounted(box, MOUNTS["45_deg"])
    two = dict(_remounted(box, AXIS_SWAP).fields)
    two.update({f"flux_b_{a}": turned[f"flux_a_{a}"] for a in "xyz"})
    files["two"] = write_flight(Flight(two, dict(box.attrs)), folder / "two.h5")
    return files


def _compensate(path: Path, out: Path, *extra: str) -> dict:
    assert main(["compensate", str(path), "--out", str(out), *extra]) == 0
    return json.loads((out / "report.json").read_text())


def test_auto_keeps_the_body_axes_of_a_body_aligned_fluxgate(box: Flight) -> None:
    """The estimate on a body-aligned flight is a fraction of a degree (the antisymmetric part
    of A): auto keeps the identity, so the compensation is the body-aligned one, bit for bit."""
    choice = choose_mount(box, "flux_a")
    assert choice.estimate is not None
    assert Mount.identity().angle_to_deg(choice.estimate) < APPLY_ANGLE_DEG
    assert choice.mount is None and not choice.applied and choice.warning is None
    assert "body axes kept" in choice.reason


@pytest.mark.parametrize("method", ["lsq", "kf"])
@pytest.mark.parametrize("name", MOUNTS)
def test_cli_default_mount_recovers_the_aligned_compensation(
    box_files: dict[str, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    name: str,
    method: str,
) -> None:
    """``aeromag compensate`` with the default (auto) mount on a remounted fluxgate: residual
    std, IR and FOM within 10 % of the body-aligned flight's, the mount within 1°, no warning."""
    aligned = _compensate(box_files["aligned"], tmp_path / "a", "--method", method)["metrics"]
    capsys.readouterr()
    report = _compensate(box_files[name], tmp_path / "m", "--method", method)
    assert "warning" not in capsys.readouterr().err
    for key in ("residual_std_nt", "improvement_ratio", "fom_nt"):
        assert report["metrics"][key] == pytest.approx(aligned[key], rel=0.10), key
    mount = report["mount"]
    assert mount["mode"] == "auto" and mount["applied"] and mount["source"] == "estimated"
    used = Mount(np.array(mount["rotation"]))
    assert used.angle_to_deg(Mount(MOUNTS[name])) < 1.0  # the bound [deg]
    assert report["settings"]["mount"]["rotation"] == mount["rotation"]


@pytest.mark.parametrize("name", MOUNTS)
def test_cli_identity_on_a_remounted_fluxgate_warns_with_the_angle(
    box_files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str
) -> None:
    report = _compensate(box_files[name], tmp_path, "--method", "lsq", "--mount", "identity")
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(
        "aeromag compensate: warning: flux_a: the assumed mount"
    )
    found = re.search(r"is ([\d.]+)° from the one the data indicate", err[0])
    assert found is not None  # the true mount's angle from the body axes, within 1° [deg]
    assert float(found.group(1)) == pytest.approx(
        Mount.identity().angle_to_deg(Mount(MOUNTS[name])), abs=1.0
    )
    assert report["mount"]["mode"] == "identity" and not report["mount"]["applied"]
    assert report["mount"]["warning"] in err[0]
    # the identity explains the readings far worse than the estimate [nT]
    assert report["mount"]["residual_nt"] > 100 * report["mount"]["estimate"]["residual_nt"]


def test_cli_mount_file_in_angles_or_matrix_is_applied(
    box_files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    true = Mount(MOUNTS["45_deg"])
    roll, pitch, yaw = true.angles_deg()
    specs = {
        "angles": {"flux_a": {"roll_deg": roll, "pitch_deg": pitch, "yaw_deg": yaw}},
        "matrix": {"mounts": {"flux_a": {"rotation": true.rotation.round(6).tolist()}}},
    }
    for kind, spec in specs.items():
        path = tmp_path / f"{kind}.json"
        path.write_text(json.dumps(spec))
        report = _compensate(
            box_files["45_deg"], tmp_path / kind, "--method", "lsq", "--mount", str(path)
        )
        assert "warning" not in capsys.readouterr().err  # the file's mount is the data's
        mount = report["mount"]
        assert mount["mode"] == "file" and mount["source"] == "file" and mount["applied"]
        assert Mount(np.array(mount["rotation"])).angle_to_deg(true) < 1e-3
        assert mount["estimate"]["angle_to_used_deg"] < 1.0


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ('{"flux_a": {"rotation": [[1, 0, 0], [0, 1, 0], [0, 0, -1]]}}', "det −1"),
        ('{"flux_a": {"rotation": [[1, 0.1, 0], [0, 1, 0], [0, 0, 1]]}}', "not orthonormal"),
        ('{"flux_a": {"rotation": [[1, 0, 0], [0, 1, 0]]}}', "must be 3×3"),
        ('{"flux_a": {"rotation": [[NaN, 0, 0], [0, 1, 0], [0, 0, 1]]}}', "non-finite"),
        ('{"flux_a": {"roll_deg": 1, "pitch_deg": 2}}', "give 'rotation'"),
        ('{"flux_b": {"roll_deg": 0, "pitch_deg": 0, "yaw_deg": 0}}', "no mount for flux_a"),
        ("[1, 2", "not a JSON file"),
        (None, "--mount takes auto, identity or a JSON mount file"),
    ],
)
def test_cli_bad_mount_files_are_one_line_errors(
    box_files: dict[str, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    content: str | None,
    message: str,
) -> None:
    path = tmp_path / "mount.json"
    if content is not None:
        path.write_text(content)
    args = ["compensate", str(box_files["aligned"]), "--method", "lsq", "--mount", str(path)]
    assert main([*args, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not (tmp_path / "o" / "report.json").exists()


def test_read_mount_file_accepts_a_report_block_and_checks_angles_against_matrix(
    tmp_path: Path,
) -> None:
    mount = Mount.from_angles_deg(10.0, -20.0, 45.0)
    path = tmp_path / "m.json"
    path.write_text(json.dumps({"flux_b": mount.to_dict()}))  # angles and matrix, as reported
    assert read_mount_file(path)["flux_b"].angle_to_deg(mount) < 1e-9
    bad = {**mount.to_dict(), "yaw_deg": 50.0}
    path.write_text(json.dumps({"flux_b": bad}))
    with pytest.raises(AeromagError, match=r"the rotation and the angles disagree by 5\.0"):
        read_mount_file(path)
    near = (mount.rotation + 1e-5).tolist()  # typed with 5 decimals: accepted, re-orthonormalised
    assert np.allclose(check_rotation(near, "x") @ check_rotation(near, "x").T, np.eye(3))


def test_info_shows_the_mount_of_each_fluxgate(box_files: dict[str, Path]) -> None:
    report = describe(box_files["two"])
    mounts = report.summary["mounts"]
    assert set(mounts) == {"flux_a", "flux_b"}
    for gate, name in (("flux_a", "axis_swap"), ("flux_b", "45_deg")):
        est = Mount(np.array(mounts[gate]["rotation"]))
        assert est.angle_to_deg(Mount(MOUNTS[name])) < 1.0
    text = "\n".join(report.lines)
    assert "fluxgate mounts (estimated from attitude and IGRF): 2" in text
    for gate, name in (("flux_a", "axis_swap"), ("flux_b", "45_deg")):
        line = re.search(rf"  {gate}: roll/pitch/yaw .*° \(([\d.]+)° from the body axes\)", text)
        assert line is not None, gate
        true_angle = Mount.identity().angle_to_deg(Mount(MOUNTS[name]))  # 120° and 51.5° [deg]
        assert float(line.group(1)) == pytest.approx(true_angle, abs=1.0)


@pytest.mark.slow
def test_discover_rotates_a_remounted_fluxgate_into_body_axes(
    box_files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "d"
    assert main(["discover", str(box_files["axis_swap"]), "--out", str(out), "--quiet"]) == 0
    report = json.loads((out / "report.json").read_text())
    assert report["mount"]["applied"] and report["mount"]["fluxgate"] == "flux_a"
    assert Mount(np.array(report["mount"]["rotation"])).angle_to_deg(Mount(AXIS_SWAP)) < 1.0
    assert report["channels"]["fluxgate"]["name"] == "flux_a"
    assert report["channels"]["scalar"] is None  # discover reads no scalar
    assert report["input_sha256"] and report["earth_model"]["name"] == "IGRF-14"
    # the rotation is not mistaken for a missing effect (the base model's gap stays small) [nT]
    assert report["gap"]["rms_before_nt"] < 5.0
