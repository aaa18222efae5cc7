import numpy as np
import pytest

from aeromag_env.errors import ConfigError
from aeromag_env.simulation.config import CalibrationConfig, TrajectoryConfig
from aeromag_env.simulation.trajectory import (
    CALIBRATION_LINE,
    FIRST_SURVEY_LINE,
    generate_trajectory,
)


def _fit_amplitude(t: np.ndarray, x: np.ndarray, period: float) -> float:
    """Least-squares amplitude of the sinusoid at ``period`` (robust to turbulence jitter)."""
    w = 2 * np.pi / period
    design = np.column_stack([np.sin(w * t), np.cos(w * t), np.ones_like(t)])
    coef, *_ = np.linalg.lstsq(design, x, rcond=None)
    return float(np.hypot(coef[0], coef[1]))


def _unwrap_deg(yaw):
    return np.rad2deg(np.unwrap(yaw))


@pytest.mark.parametrize(
    "cal",
    [
        CalibrationConfig(),
        CalibrationConfig(
            roll_amplitude_deg=8,
            pitch_amplitude_deg=3,
            yaw_amplitude_deg=4,
            roll_period_s=4,
            pitch_period_s=6,
            yaw_period_s=5,
            cycles=4,
        ),
    ],
    ids=["default", "custom"],
)
def test_calibration_box_headings_windows_amplitudes(cal):
    traj = generate_trajectory(TrajectoryConfig(calibration=cal), np.random.default_rng(7))
    ids = np.unique(traj.maneuver[traj.maneuver > 0])
    np.testing.assert_array_equal(ids, np.arange(1, 13))  # 12 maneuver windows
    assert np.all(traj.line == CALIBRATION_LINE)
    amps = {
        "roll": cal.roll_amplitude_deg,
        "pitch": cal.pitch_amplitude_deg,
        "yaw": cal.yaw_amplitude_deg,
    }
    periods = {"roll": cal.roll_period_s, "pitch": cal.pitch_period_s, "yaw": cal.yaw_period_s}
    headings = []
    for wid in ids:
        k = traj.maneuver == wid
        kind = ("roll", "pitch", "yaw")[(wid - 1) % 3]
        t = traj.tt[k] - traj.tt[k][0]
        assert t[-1] + 0.1 == pytest.approx(cal.cycles * periods[kind], abs=0.11)
        yaw_deg = _unwrap_deg(traj.yaw[k])
        signals = {
            "roll": np.rad2deg(traj.roll[k]),
            "pitch": np.rad2deg(traj.pitch[k]),
            "yaw": yaw_deg,
        }
        # the tapered sinusoid has a fitted amplitude a little below the configured peak; the
        # peak itself sits within ±1° of it (turbulence jitter: σ ≤ 0.3°, so ±1° is > 3σ)
        fitted = _fit_amplitude(t, signals[kind], periods[kind])
        assert 0.75 * amps[kind] < fitted <= 1.02 * amps[kind]
        peak = np.max(np.abs(signals[kind] - np.median(signals[kind])))
        assert peak == pytest.approx(amps[kind], abs=1.0)
        for other in set(signals) - {kind}:  # the other two axes only carry turbulence
            assert np.std(signals[other]) < 0.5
        headings.append(np.median(yaw_deg) % 360)
    expected = np.repeat([0.0, 90.0, 180.0, 270.0], 3)
    off = (np.asarray(headings) - expected + 180.0) % 360.0 - 180.0  # circular difference [deg]
    assert np.max(np.abs(off)) < 1.5


def test_box_closes_and_repeats():
    traj = generate_trajectory(
        TrajectoryConfig(jitter_roll_deg=0, jitter_pitch_deg=0, jitter_yaw_deg=0),
        np.random.default_rng(0),
    )
    # four 90° turns bring the aircraft back to its first heading
    assert abs((np.rad2deg(traj.yaw[-1]) + 180.0) % 360.0 - 180.0) < 1e-6
    # the box is ~6–9 min long (industry: 6–8 min)
    assert 300 < traj.tt[-1] < 600
    long = generate_trajectory(TrajectoryConfig(duration_s=1200.0), np.random.default_rng(0))
    assert long.tt.size == 12_000
    assert long.maneuver.max() > 12  # the box repeats, windows keep counting


def test_turns_are_coordinated():
    cfg = TrajectoryConfig(
        pattern="survey", duration_s=900, jitter_roll_deg=0, jitter_pitch_deg=0, jitter_yaw_deg=0
    )
    traj = generate_trajectory(cfg, np.random.default_rng(0))
    rate = np.gradient(np.unwrap(traj.yaw), traj.tt)
    # coordinated turn: yaw rate = g tan(roll) / v
    np.testing.assert_allclose(
        rate[5:-5], 9.80665 * np.tan(traj.roll[5:-5]) / cfg.speed_m_s, atol=2e-3
    )
    assert np.rad2deg(np.max(np.abs(traj.roll))) == pytest.approx(25.0, abs=0.5)


def test_survey_lines_parallel_and_spaced():
    cfg = TrajectoryConfig(
        pattern="survey", duration_s=1800, jitter_roll_deg=0, jitter_pitch_deg=0, jitter_yaw_deg=0
    )
    traj = generate_trajectory(cfg, np.random.default_rng(0))
    lines = np.unique(traj.line[traj.line >= FIRST_SURVEY_LINE])
    assert lines.size >= 3
    east = []
    for ln in lines[:3]:
        k = traj.line == ln
        yaw = np.rad2deg(traj.yaw[k]) % 360
        assert np.ptp(np.minimum(yaw, 360 - yaw) if ln % 2 else np.abs(yaw - 180)) < 1e-6
        east.append(np.mean(traj.lon[k]))
    spacing = np.diff(east) * 6_378_137 * np.cos(traj.lat[0])
    radius = cfg.speed_m_s**2 / (9.80665 * np.tan(np.deg2rad(25.0)))
    np.testing.assert_allclose(spacing, 2 * radius, rtol=0.02)  # lines one turn diameter apart
    assert np.all(np.abs(traj.alt - 400.0) < 1e-6)


def test_composite_descends_to_survey_altitude():
    traj = generate_trajectory(
        TrajectoryConfig(pattern="calibration+survey"), np.random.default_rng(0)
    )
    assert traj.maneuver.max() == 12
    cal = traj.line == CALIBRATION_LINE
    sur = traj.line >= FIRST_SURVEY_LINE
    assert np.all(np.abs(traj.alt[cal] - 3000) < 10) and np.all(np.abs(traj.alt[sur] - 400) < 1e-3)
    assert traj.tt[cal].max() < traj.tt[sur].min()


def test_duration_and_sample_rate():
    traj = generate_trajectory(
        TrajectoryConfig(pattern="survey", duration_s=100, sample_rate_hz=20),
        np.random.default_rng(0),
    )
    assert traj.tt.size == 2000
    np.testing.assert_allclose(np.diff(traj.tt), 0.05)


def test_bad_configs_name_the_field():
    with pytest.raises(ConfigError, match="pattern must be one of"):
        TrajectoryConfig(pattern="spiral")
    with pytest.raises(ConfigError, match="roll_period_s"):
        CalibrationConfig(roll_period_s=0)
    with pytest.raises(ConfigError, match="duration_s"):
        TrajectoryConfig(duration_s=-5)
