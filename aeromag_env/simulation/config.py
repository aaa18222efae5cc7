"""Simulator configuration: frozen keyword-only dataclasses composed into ``SimulationConfig``.

Fields carry their unit as a suffix (``_s``, ``_m``, ``_deg``, ``_nt``…). Every dataclass
validates itself in ``__post_init__`` with a message naming the field and its unit, and
round-trips through JSON (:func:`to_dict` / :func:`from_dict`), so a configuration stored in a
flight file or passed through ``gym.make`` as a dict comes back identical.

Presets (:data:`PRESETS`, :func:`preset`):

* ``nominal`` — realistic cabin installation: fluxgate interference of a few hundred nT RMS
  (permanent ~200 nT, induced ~1.5e-3, eddy ~2e-4 s → a few nT during maneuvers), fluxgate noise
  1 nT white + 1 nT FOGM (600 s), a tail-stinger cesium magnetometer (0.01 nT white) with
  Tolles–Lawson interference, quiet-day diurnal variation (20 nT daily cycle + 2 nT smooth
  irregular part).
* ``paper`` — the setting of Zhang, Zhao & Chang (2014), §4: 20 nT white noise per fluxgate
  axis, nothing else (no coloured noise, no drift, no external variation, no scalar sensor).
  The paper gives no true interference, so the realistic ``nominal`` coefficients are used.
* ``noise_free`` — ``nominal`` without any sensor noise or external variation (for recovery
  tests); attitude turbulence stays, it is motion, not noise.
"""

from __future__ import annotations

import math
import typing
from dataclasses import dataclass, field
from typing import Any

from aeromag_env.configs import (
    check,
    from_dict,
    require_nonnegative,
    require_positive,
    to_dict,
)
from aeromag_env.errors import ConfigError

PATTERNS = ("calibration", "survey", "calibration+survey")
#: Samples a set ``duration_s`` may give, at its sample rate: at least two (a flight needs a
#: sample rate, and every pattern is cut to this length), at most 10⁸ (116 days at 10 Hz; the
#: 23 fields of a nominal flight alone then hold 18 GB, and ``aeromag simulate`` further checks
#: what the memory available allows).
DURATION_SAMPLES = (2, 10**8)


@dataclass(frozen=True, kw_only=True)
class CalibrationConfig:
    """The compensation box (figure-of-merit flight).

    At each heading: a straight leg, then roll, pitch and yaw oscillations (``cycles`` periods
    each, separated by ``gap_s`` of straight flight), a straight leg, and a turn of ``bank_deg``
    to the next heading. Four headings × three maneuvers = the 12 windows of the FOM.
    Amplitudes are the half peak-to-peak swing [deg].
    """

    headings_deg: tuple[float, ...] = (0.0, 90.0, 180.0, 270.0)
    roll_amplitude_deg: float = 10.0
    pitch_amplitude_deg: float = 5.0
    yaw_amplitude_deg: float = 5.0
    roll_period_s: float = 5.0
    pitch_period_s: float = 5.0
    yaw_period_s: float = 5.0
    cycles: int = 3
    leg_s: float = 20.0
    gap_s: float = 5.0
    bank_deg: float = 20.0
    altitude_m: float = 3000.0

    def __post_init__(self) -> None:
        check(len(self.headings_deg) >= 1, "CalibrationConfig.headings_deg needs ≥ 1 heading")
        require_positive(self, "roll_period_s", "pitch_period_s", "yaw_period_s", "bank_deg")
        require_nonnegative(self, "roll_amplitude_deg", "pitch_amplitude_deg", "yaw_amplitude_deg")
        require_nonnegative(self, "leg_s", "gap_s", "altitude_m")
        for nm in ("roll_amplitude_deg", "pitch_amplitude_deg", "yaw_amplitude_deg", "bank_deg"):
            check(getattr(self, nm) <= 45, f"CalibrationConfig.{nm} must be ≤ 45 deg")
        check(self.cycles >= 1, f"CalibrationConfig.cycles must be ≥ 1, got {self.cycles}")


@dataclass(frozen=True, kw_only=True)
class SurveyConfig:
    """Parallel survey lines joined by 180° turns of ``bank_deg`` (line spacing = turn diameter)."""

    line_length_m: float = 10_000.0
    line_heading_deg: float = 0.0
    bank_deg: float = 25.0
    altitude_m: float = 400.0
    climb_rate_m_s: float = 7.5

    def __post_init__(self) -> None:
        require_positive(self, "line_length_m", "bank_deg", "climb_rate_m_s")
        require_nonnegative(self, "altitude_m")
        check(self.bank_deg <= 45, "SurveyConfig.bank_deg must be ≤ 45 deg")


@dataclass(frozen=True, kw_only=True)
class TrajectoryConfig:
    """Flight pattern, timing, start point and attitude turbulence (FOGM per Euler angle).

    ``duration_s`` [s] cuts the pattern (or repeats calibration boxes) to that length, which
    must give :data:`DURATION_SAMPLES` samples at ``sample_rate_hz`` (0.2 s to 10⁷ s at
    10 Hz); None flies the pattern's own length.
    """

    pattern: str = "calibration"
    duration_s: float | None = None
    sample_rate_hz: float = 10.0
    start_lat_deg: float = 45.3
    start_lon_deg: float = -76.0
    speed_m_s: float = 65.0
    date: str = "2026-06-01T14:00:00"
    jitter_roll_deg: float = 0.3
    jitter_pitch_deg: float = 0.15
    jitter_yaw_deg: float = 0.15
    jitter_tau_s: float = 2.0
    calibration: CalibrationConfig = field(default_factory=CalibrationConfig)
    survey: SurveyConfig = field(default_factory=SurveyConfig)

    def __post_init__(self) -> None:
        check(
            self.pattern in PATTERNS,
            f"pattern must be one of {', '.join(PATTERNS)}; got {self.pattern!r}",
        )
        require_positive(self, "sample_rate_hz", "speed_m_s", "jitter_tau_s")
        if self.duration_s is not None:
            self._check_duration()
        require_nonnegative(self, "jitter_roll_deg", "jitter_pitch_deg", "jitter_yaw_deg")
        check(
            -90 < self.start_lat_deg < 90,
            f"start_lat_deg must be in (-90, 90), got {self.start_lat_deg}",
        )
        check(
            -360 <= self.start_lon_deg <= 360, f"start_lon_deg out of range: {self.start_lon_deg}"
        )
        from aeromag_env.geo.earth import parse_date

        try:
            parse_date(self.date)
        except ValueError as e:
            raise ConfigError(f"TrajectoryConfig.date: {e}") from None

    def _check_duration(self) -> None:
        """``duration_s`` [s] finite and giving :data:`DURATION_SAMPLES` samples."""
        d, fs = self.duration_s, self.sample_rate_hz
        lo, hi = DURATION_SAMPLES
        ok = isinstance(d, (int, float)) and math.isfinite(d) and lo <= d * fs <= hi
        check(
            ok,
            f"TrajectoryConfig.duration_s must be > 0 and give {lo} to {hi:.0e} samples: "
            f"{lo / fs:g} to {hi / fs:g} s at {fs:g} Hz, got {d}",
        )


@dataclass(frozen=True, kw_only=True)
class EarthConfig:
    """Earth field: IGRF-14 grid spacing and the external (diurnal) variation.

    The external variation is a daily cycle plus a smooth irregular part (FOGM of
    ``external_fogm_std_nt`` and ``external_fogm_tau_s`` through a ``external_smoothing_s`` lag),
    referenced to the start of the flight: a quiet day, as compensation flights are flown.
    """

    igrf_grid_spacing_s: float = 10.0
    daily_amplitude_nt: float = 20.0
    external_fogm_std_nt: float = 2.0
    external_fogm_tau_s: float = 600.0
    external_smoothing_s: float = 60.0

    def __post_init__(self) -> None:
        require_positive(self, "igrf_grid_spacing_s", "external_fogm_tau_s", "external_smoothing_s")
        require_nonnegative(self, "daily_amplitude_nt", "external_fogm_std_nt")


@dataclass(frozen=True, kw_only=True)
class InterferenceConfig:
    """Aircraft field at a magnetometer: ``T_p + A T + B Ṫ`` (paper eq. 5).

    Coefficients are drawn per flight, ``N(0, std²)`` each, unless given explicitly
    (``permanent_nt``: 3 values [nT]; ``induced``: 9 values of ``A`` row-major [-];
    ``eddy_s``: 9 values of ``B`` row-major [s]).
    """

    permanent_std_nt: float = 200.0
    induced_std: float = 1.5e-3
    eddy_std_s: float = 2e-4
    permanent_nt: tuple[float, ...] | None = None
    induced: tuple[float, ...] | None = None
    eddy_s: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        require_nonnegative(self, "permanent_std_nt", "induced_std", "eddy_std_s")
        for nm, size in (("permanent_nt", 3), ("induced", 9), ("eddy_s", 9)):
            v = getattr(self, nm)
            check(v is None or len(v) == size, f"InterferenceConfig.{nm} needs {size} values")


@dataclass(frozen=True, kw_only=True)
class SensorNoiseConfig:
    """Sensor noise per axis: white + FOGM + linear drift (rate drawn ``N(0, drift_std²)``)."""

    white_std_nt: float = 1.0
    fogm_std_nt: float = 1.0
    fogm_tau_s: float = 600.0
    drift_std_nt_per_h: float = 0.0

    def __post_init__(self) -> None:
        require_positive(self, "fogm_tau_s")
        require_nonnegative(self, "white_std_nt", "fogm_std_nt", "drift_std_nt_per_h")


@dataclass(frozen=True, kw_only=True)
class ScalarConfig:
    """Optional scalar (total-field) magnetometer, e.g. a tail stinger.

    It reads ``|T + ΔT_s|`` exactly, with ``ΔT_s = T_p + A T + B Ṫ`` of its own (small at a
    stinger); the Tolles–Lawson model is the linearisation ``T̂ · ΔT_s`` of that, and the
    equivalent 18 TL coefficients are stored with the flight's truth.
    """

    enabled: bool = True
    name: str = "mag_1_uc"
    interference: InterferenceConfig = field(
        default_factory=lambda: InterferenceConfig(
            permanent_std_nt=50.0, induced_std=5e-4, eddy_std_s=5e-5
        )
    )
    noise: SensorNoiseConfig = field(
        default_factory=lambda: SensorNoiseConfig(white_std_nt=0.01, fogm_std_nt=0.0)
    )

    def __post_init__(self) -> None:
        check(
            self.name.startswith("mag_") and self.name.endswith("_uc"),
            f"ScalarConfig.name must look like mag_N_uc, got {self.name!r}",
        )


@dataclass(frozen=True, kw_only=True)
class GeologyConfig:
    """Crustal magnetic anomaly (:mod:`aeromag_env.geo.crust`): a random potential field of
    sources ``depth_to_source_m`` [m] to ``depth_to_source_m + source_thickness_m`` [m] below a
    flat ground at altitude 0, spectrum ``∝ |k|^(−fractal_exponent)``, scaled to a total-field
    anomaly of ``rms_nt`` [nT] RMS at ``reference_altitude_m`` [m]. Every sensor sees it; the
    compensation's base model (IGRF + diurnal) does not. ``seed`` fixes one ground over a square
    area (:mod:`aeromag_env.geo.crust_area`; side ``area_size_km``, centred on the area_center
    [deg], None: the trajectory's start; flown ≥ ``min_altitude_m`` [m]), the same for every
    flight over it; None draws it from the flight's seed on a grid around the track.
    """

    rms_nt: float = 50.0
    reference_altitude_m: float = 400.0
    depth_to_source_m: float = 200.0
    source_thickness_m: float = 3000.0
    fractal_exponent: float = 2.0
    seed: int | None = None
    area_center_lat_deg: float | None = None
    area_center_lon_deg: float | None = None
    area_size_km: float = 100.0
    min_altitude_m: float = 300.0

    def __post_init__(self) -> None:
        from aeromag_env.geo.crust_area import check_area

        require_nonnegative(self, "rms_nt", "reference_altitude_m")
        require_positive(self, "depth_to_source_m", "source_thickness_m")
        beta = self.fractal_exponent
        check(0 <= beta < 4, f"GeologyConfig.fractal_exponent must be in [0, 4), got {beta}")
        check(self.seed is None or self.seed >= 0, f"GeologyConfig.seed must be ≥ 0: {self.seed}")
        check_area(self)


AUX_KINDS = ("switching", "strobe", "temperature", "random_walk")


@dataclass(frozen=True, kw_only=True)
class AuxChannelConfig:
    """One simulated auxiliary channel (``cur_*`` [A], ``vol_*`` [V], ``temp_*`` [°C]).

    Kinds (:mod:`aeromag_env.simulation.auxiliary`): ``switching`` — a load switched on and off
    (fan, pump, radio keying) with random dwell times around ``period_s``; ``strobe`` — pulses of
    0.2 s at ``60 / period_s`` flashes per minute; ``temperature`` — a warm-up towards ``level``
    plus thermostat cycling of period ``period_s``; ``random_walk`` — a slowly wandering reading.
    ``level`` is the on-current, pulse height, temperature rise or walk scale. A channel carries
    no field by itself: an effect (e.g. ``onboard_current``) couples it to the magnetometer, and a
    channel no effect names is a decoy.
    """

    name: str
    kind: str = "switching"
    level: float = 1.0
    period_s: float = 60.0
    offset: float = 0.0

    def __post_init__(self) -> None:
        check(
            self.name.startswith(("cur_", "vol_", "temp_")),
            f"AuxChannelConfig.name must start with cur_, vol_ or temp_, got {self.name!r}",
        )
        check(self.kind in AUX_KINDS, f"AuxChannelConfig.kind must be one of {AUX_KINDS}")
        require_positive(self, "period_s")
        check(math.isfinite(self.level), "AuxChannelConfig.level must be finite")
        check(math.isfinite(self.offset), "AuxChannelConfig.offset must be finite")


@dataclass(frozen=True, kw_only=True)
class EffectConfig:
    """One extra physical effect added to the fluxgate signal
    (:mod:`aeromag_env.simulation.effects`).

    ``name`` is a canonical effect name, ``channel`` the auxiliary channel it follows (if any),
    ``parameters`` its parameters by name (lists of numbers); each effect validates its own.
    """

    name: str
    channel: str | None = None
    parameters: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        from aeromag_env.simulation.effects import check_effect_config

        check_effect_config(self)


@dataclass(frozen=True, kw_only=True)
class AircraftConfig:
    """One aircraft of a fleet: its interference drawn from its own seed, not the flight's.

    Without it (``SimulationConfig.aircraft = None``) every flight's coefficients come from the
    flight's seed, so two flights are two aircraft. With it, the fluxgate's and the scalar
    magnetometer's coefficients (:class:`InterferenceConfig` draws, or their explicit values)
    come from ``seed``, and the flight's seed draws only the trajectory, the Earth field's
    variation and the sensor noise: flights with one ``seed`` and different flight seeds are
    flights of one aircraft (calibrate on one, apply to the others, with a known truth).

    Maintenance (a part replaced, a magnetised tool left aboard) shifts the permanent field:
    ``permanent_shift_nt`` [nT] is added to the fluxgate's ``T_p`` and
    ``scalar_permanent_shift_nt`` [nT] to the scalar magnetometer's, after the draw.
    """

    seed: int
    permanent_shift_nt: tuple[float, ...] = (0.0, 0.0, 0.0)
    scalar_permanent_shift_nt: tuple[float, ...] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        check(
            isinstance(self.seed, int) and not isinstance(self.seed, bool) and self.seed >= 0,
            f"AircraftConfig.seed must be an integer ≥ 0, got {self.seed!r}",
        )
        for nm in ("permanent_shift_nt", "scalar_permanent_shift_nt"):
            v = getattr(self, nm)
            check(
                len(v) == 3 and all(math.isfinite(float(x)) for x in v),
                f"AircraftConfig.{nm} needs 3 finite values [nT], got {v!r}",
            )

    @property
    def maintained(self) -> bool:
        """Whether a maintenance shift is set (any component non-zero)."""
        return any(self.permanent_shift_nt) or any(self.scalar_permanent_shift_nt)


@dataclass(frozen=True, kw_only=True)
class SimulationConfig:
    """Root configuration of one simulated flight.

    ``aux_channels`` are simulated auxiliary channels and ``effects`` the extra physical effects
    (effects library, :mod:`aeromag_env.simulation.effects`) added to the fluxgate on top of paper
    eq. 5; ``geology`` the crustal anomaly (None: none, as in every preset); ``aircraft`` the
    aircraft whose interference the flight carries (None: drawn from the flight's seed).
    """

    preset: str = "nominal"
    fluxgate: str = "flux_a"
    trajectory: TrajectoryConfig = field(default_factory=TrajectoryConfig)
    earth: EarthConfig = field(default_factory=EarthConfig)
    interference: InterferenceConfig = field(default_factory=InterferenceConfig)
    fluxgate_noise: SensorNoiseConfig = field(default_factory=SensorNoiseConfig)
    scalar: ScalarConfig = field(default_factory=ScalarConfig)
    aux_channels: tuple[AuxChannelConfig, ...] = ()
    effects: tuple[EffectConfig, ...] = ()
    geology: GeologyConfig | None = None
    aircraft: AircraftConfig | None = None

    def __post_init__(self) -> None:
        check(
            len(self.fluxgate) == 6 and self.fluxgate.startswith("flux_"),
            f"fluxgate must look like flux_a, got {self.fluxgate!r}",
        )
        names = [a.name for a in self.aux_channels]
        check(len(set(names)) == len(names), "aux_channels: duplicate channel names")


def _paper() -> SimulationConfig:
    return SimulationConfig(
        preset="paper",
        earth=EarthConfig(daily_amplitude_nt=0.0, external_fogm_std_nt=0.0),
        fluxgate_noise=SensorNoiseConfig(white_std_nt=20.0, fogm_std_nt=0.0),
        scalar=ScalarConfig(enabled=False),
    )


def _noise_free() -> SimulationConfig:
    quiet = SensorNoiseConfig(white_std_nt=0.0, fogm_std_nt=0.0)
    return SimulationConfig(
        preset="noise_free",
        earth=EarthConfig(daily_amplitude_nt=0.0, external_fogm_std_nt=0.0),
        fluxgate_noise=quiet,
        scalar=ScalarConfig(noise=quiet),
    )


PRESETS: dict[str, typing.Callable[[], SimulationConfig]] = {
    "nominal": SimulationConfig,
    "paper": _paper,
    "noise_free": _noise_free,
}


def preset(name: str) -> SimulationConfig:
    """The named preset; unknown names give a one-line error listing the valid ones."""
    if name not in PRESETS:
        raise ConfigError(f"unknown preset {name!r}; valid presets: {', '.join(PRESETS)}")
    return PRESETS[name]()


def with_overrides(cfg: SimulationConfig, overrides: dict[str, Any]) -> SimulationConfig:
    """Copy of ``cfg`` with dotted-path overrides, e.g. ``{"trajectory.duration_s": 600}``."""
    d = to_dict(cfg)
    for path, value in overrides.items():
        node = d
        *parents, leaf = path.split(".")
        for p in parents:
            if not isinstance(node.get(p), dict):
                raise ConfigError(f"unknown configuration field {path!r}")
            node = node[p]
        if leaf not in node:
            raise ConfigError(f"unknown configuration field {path!r}")
        node[leaf] = value
    return from_dict(SimulationConfig, d)
