"""Flight trajectories: the calibration box, survey lines, and the two in sequence.

A trajectory is built from segments (straight legs, attitude oscillations, coordinated turns,
climbs), each giving per-sample commands: turn rate, bank, flight-path angle and attitude
perturbations. The course is the integral of the turn rate; the position follows the course at
constant true airspeed (no wind); the attitude is the commanded one plus FOGM turbulence.

Maneuver windows: within one box, heading ``h`` (0-based) carries windows ``3h + 1`` (roll),
``3h + 2`` (pitch) and ``3h + 3`` (yaw); a repeated box continues the count (13–24, …).
Line ids: 1 for the calibration box, 0 for transits and survey turns, 1001, 1002, … for survey
lines.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from aeromag_env.geo.frames import earth_radii_m
from aeromag_env.noise import fogm
from aeromag_env.simulation.config import CalibrationConfig, SurveyConfig, TrajectoryConfig
from aeromag_env.units import GRAVITY_M_S2

#: Time for the bank angle to roll in or out of a turn [s].
_ROLL_IN_S = 3.0
#: Maneuver kinds in the order flown at each heading.
MANEUVER_KINDS = ("roll", "pitch", "yaw")
CALIBRATION_LINE = 1
FIRST_SURVEY_LINE = 1001


@dataclass(frozen=True)
class Trajectory:
    """Sampled trajectory; all arrays shape (n,).

    Attributes
    ----------
    tt : time [s]; lat, lon : [rad]; alt : [m]
    roll, pitch, yaw : attitude [rad] (yaw wrapped to (-π, π])
    maneuver : 0 outside, k ≥ 1 inside maneuver window k
    line : flight line id
    """

    tt: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    alt: np.ndarray
    roll: np.ndarray
    pitch: np.ndarray
    yaw: np.ndarray
    maneuver: np.ndarray
    line: np.ndarray


class _Segments:
    """Accumulates per-sample commands of consecutive segments."""

    def __init__(self, fs: float, speed: float) -> None:
        self.fs, self.speed = fs, speed
        self.parts: dict[str, list[np.ndarray]] = {
            k: [] for k in ("rate", "bank", "gamma", "droll", "dpitch", "dyaw", "maneuver", "line")
        }

    @property
    def n(self) -> int:
        return int(sum(a.size for a in self.parts["rate"]))

    def add(self, n: int, line: int, maneuver: int = 0, **cmd: np.ndarray) -> None:
        for key, parts in self.parts.items():
            if key == "maneuver":
                parts.append(np.full(n, maneuver, dtype=np.int64))
            elif key == "line":
                parts.append(np.full(n, line, dtype=np.int64))
            else:
                parts.append(np.broadcast_to(cmd.get(key, 0.0), (n,)).astype(float))

    def straight(self, duration_s: float, line: int) -> None:
        self.add(round(duration_s * self.fs), line)

    def oscillation(
        self, kind: str, amp: float, period: float, cycles: int, wid: int, line: int
    ) -> None:
        """``cycles`` periods of ``amp sin(2π t / period)`` with smooth half-period tapers."""
        n = round(cycles * period * self.fs)
        t = np.arange(n) / self.fs
        wave = amp * np.sin(2 * np.pi * t / period) * _taper(t, period / 2, n / self.fs)
        cmd = {"d" + kind: wave}
        if kind == "pitch":
            cmd["gamma"] = wave  # the aircraft climbs and dives with the nose
        self.add(n, line, wid, **cmd)

    def turn(self, angle: float, bank: float, line: int) -> None:
        """Coordinated turn through ``angle`` [rad] (sign = direction) at up to ``bank`` [rad]."""
        rate_max = GRAVITY_M_S2 * np.tan(bank) / self.speed
        n_ramp = max(1, round(_ROLL_IN_S * self.fs))
        ramp = _smoothstep(np.arange(n_ramp) / n_ramp)
        ramp_turn = np.sum(np.tan(bank * ramp)) / np.tan(bank) / self.fs  # [s at full rate]
        n_hold = max(0, round((abs(angle) / rate_max - 2 * ramp_turn) * self.fs))
        profile = np.r_[
            np.tan(bank * ramp), np.full(n_hold, np.tan(bank)), np.tan(bank * ramp[::-1])
        ]
        rate = profile * GRAVITY_M_S2 / self.speed
        rate *= abs(angle) / (rate.sum() / self.fs)  # land exactly on the new heading
        self.add(
            rate.size,
            line,
            rate=np.sign(angle) * rate,
            bank=np.sign(angle) * np.arctan(rate * self.speed / GRAVITY_M_S2),
        )

    def climb(self, delta_alt_m: float, rate_m_s: float, line: int) -> None:
        """Climb (or descend) by ``delta_alt_m`` at up to ``rate_m_s``, smooth start and end."""
        if abs(delta_alt_m) < 1e-9:
            return
        n_ramp = round(5.0 * self.fs)
        ramp = _smoothstep(np.arange(n_ramp) / n_ramp)
        n_hold = max(0, round((abs(delta_alt_m) / rate_m_s - n_ramp / self.fs) * self.fs))
        vz = np.r_[ramp, np.ones(n_hold), ramp[::-1]]
        vz *= abs(delta_alt_m) / (vz.sum() / self.fs)
        self.add(
            vz.size, line, gamma=np.sign(delta_alt_m) * np.arcsin(np.clip(vz / self.speed, 0, 0.5))
        )

    def arrays(self) -> dict[str, np.ndarray]:
        return {k: np.concatenate(v) if v else np.zeros(0) for k, v in self.parts.items()}


def _smoothstep(r: np.ndarray) -> np.ndarray:
    r = np.clip(r, 0.0, 1.0)
    return r * r * (3.0 - 2.0 * r)


def _taper(t: np.ndarray, width: float, total: float) -> np.ndarray:
    return _smoothstep(t / width) * _smoothstep((total - t) / width)


def _wrap_angle(a: np.ndarray) -> np.ndarray:
    """Wrap to (-π, π]."""
    return np.pi - np.mod(np.pi - a, 2.0 * np.pi)


def _calibration_box(seg: _Segments, cal: CalibrationConfig, first_window: int) -> None:
    """One compensation box: at each heading three maneuvers, then a turn to the next heading."""
    headings = np.deg2rad(np.asarray(cal.headings_deg))
    amps = np.deg2rad([cal.roll_amplitude_deg, cal.pitch_amplitude_deg, cal.yaw_amplitude_deg])
    periods = (cal.roll_period_s, cal.pitch_period_s, cal.yaw_period_s)
    wid = first_window
    for h in range(headings.size):
        seg.straight(cal.leg_s, CALIBRATION_LINE)
        for kind, amp, period in zip(MANEUVER_KINDS, amps, periods, strict=True):
            seg.oscillation(kind, amp, period, cal.cycles, wid, CALIBRATION_LINE)
            wid += 1
            seg.straight(cal.gap_s, CALIBRATION_LINE)
        seg.straight(cal.leg_s, CALIBRATION_LINE)
        delta = float(_wrap_angle(headings[(h + 1) % headings.size] - headings[h]))
        if abs(delta) > 1e-9:
            seg.turn(delta, np.deg2rad(cal.bank_deg), CALIBRATION_LINE)


def _survey_lines(seg: _Segments, sur: SurveyConfig, until_n: int, speed: float) -> None:
    """Alternating lines and 180° turns (right, left, …) until ``until_n`` samples exist."""
    line, direction = FIRST_SURVEY_LINE, 1.0
    while seg.n < until_n:
        seg.straight(sur.line_length_m / speed, line)
        seg.turn(direction * np.pi, np.deg2rad(sur.bank_deg), 0)
        line, direction = line + 1, -direction


def _commands(cfg: TrajectoryConfig) -> tuple[dict[str, np.ndarray], float, float]:
    """Per-sample commands for the pattern, plus the start heading [rad] and altitude [m].

    Without ``duration_s``: one box (calibration), 1800 s of lines (survey), or one box then
    1200 s of lines. With it, boxes repeat (calibration) or lines continue until it is reached.
    """
    fs, cal, sur = cfg.sample_rate_hz, cfg.calibration, cfg.survey
    seg = _Segments(fs, cfg.speed_m_s)
    target = None if cfg.duration_s is None else round(cfg.duration_s * fs)
    if cfg.pattern == "survey":
        _survey_lines(seg, sur, target or round(1800 * fs), cfg.speed_m_s)
        return seg.arrays(), float(np.deg2rad(sur.line_heading_deg)), sur.altitude_m
    windows_per_box = len(MANEUVER_KINDS) * len(cal.headings_deg)
    box = 0
    while box == 0 or (cfg.pattern == "calibration" and target is not None and seg.n < target):
        _calibration_box(seg, cal, windows_per_box * box + 1)
        box += 1
    if cfg.pattern == "calibration+survey":
        to_lines = float(_wrap_angle(np.deg2rad(sur.line_heading_deg - cal.headings_deg[0])))
        if abs(to_lines) > 1e-9:
            seg.turn(to_lines, np.deg2rad(sur.bank_deg), 0)
        seg.climb(sur.altitude_m - cal.altitude_m, sur.climb_rate_m_s, 0)
        _survey_lines(seg, sur, target or seg.n + round(1200 * fs), cfg.speed_m_s)
    return seg.arrays(), float(np.deg2rad(cal.headings_deg[0])), cal.altitude_m


def generate_trajectory(cfg: TrajectoryConfig, rng: np.random.Generator) -> Trajectory:
    """Sample the configured pattern.

    Parameters
    ----------
    cfg : TrajectoryConfig
    rng : numpy.random.Generator
        Source of the attitude turbulence.

    Returns
    -------
    Trajectory
        ``round(duration_s * sample_rate_hz)`` samples when ``duration_s`` is set (the pattern is
        cut there), else the pattern's natural length.
    """
    track = _track(cfg)
    jitter = fogm(track["tt"].size, 1.0 / cfg.sample_rate_hz, 1.0, cfg.jitter_tau_s, rng, dims=3)
    sig = np.deg2rad([cfg.jitter_roll_deg, cfg.jitter_pitch_deg, cfg.jitter_yaw_deg])
    return Trajectory(
        tt=track["tt"].copy(),
        lat=track["lat"].copy(),
        lon=track["lon"].copy(),
        alt=track["alt"].copy(),
        roll=track["bank"] + track["droll"] + sig[0] * jitter[:, 0],
        pitch=track["dpitch"] + sig[1] * jitter[:, 1],
        yaw=_wrap_angle(track["course"] + track["dyaw"] + sig[2] * jitter[:, 2]),
        maneuver=track["maneuver"].copy(),
        line=track["line"].copy(),
    )


@functools.lru_cache(maxsize=8)
def _track(cfg: TrajectoryConfig) -> dict[str, np.ndarray]:
    """The deterministic part of :func:`generate_trajectory` (everything but the turbulence):
    the commands, course and position, read-only. Remembered per configuration: a training run
    flies the same pattern for every episode, and building it costs milliseconds of Python."""
    cmd, heading0, alt0 = _commands(cfg)
    n = cmd["rate"].size if cfg.duration_s is None else round(cfg.duration_s * cfg.sample_rate_hz)
    cmd = {k: v[:n] for k, v in cmd.items()}
    fs, v = cfg.sample_rate_hz, cfg.speed_m_s
    dt = 1.0 / fs
    course = heading0 + dt * np.r_[0.0, np.cumsum(cmd["rate"])[:-1]]
    gamma = cmd["gamma"]
    alt = alt0 + dt * np.r_[0.0, np.cumsum(v * np.sin(gamma))[:-1]]
    lat0, lon0 = np.deg2rad(cfg.start_lat_deg), np.deg2rad(cfg.start_lon_deg)
    r_m, _ = earth_radii_m(np.array(lat0))
    v_h = v * np.cos(gamma)
    lat = lat0 + dt * np.r_[0.0, np.cumsum(v_h * np.cos(course) / (r_m + alt))[:-1]]
    _, r_n = earth_radii_m(lat)
    lon = lon0 + dt * np.r_[0.0, np.cumsum(v_h * np.sin(course) / ((r_n + alt) * np.cos(lat)))[:-1]]
    track = {**cmd, "tt": np.arange(n) * dt, "course": course, "lat": lat, "lon": lon, "alt": alt}
    for a in track.values():
        a.flags.writeable = False
    return track
