"""Simulate a flight (or replay one) and write it: :func:`simulate`, the job of ``aeromag
simulate``.

The configuration is a preset or a JSON file, with the pattern and duration overridden; a
replayed flight file gives the time, track, attitude and auxiliary channels to fly, and is
checked first (non-finite samples refused; altitude channels that disagree, an implausible
ground speed or a magnetometer far from IGRF warned of, as ``compensate`` would). The flight is
written atomically and never over an input.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from aeromag_env.atomic import check_output_file
from aeromag_env.configs import from_json
from aeromag_env.errors import ArgumentError, ConfigError, FlightFileError
from aeromag_env.flight.data import Flight
from aeromag_env.jobs.limits import (
    BYTES_PER_VALUE,
    MAX_PERMANENT_SHIFT_NT,
    available_memory_bytes,
    check_seed,
    check_vector,
)
from aeromag_env.jobs.provenance import JobWarnings
from aeromag_env.simulation.config import (
    DURATION_SAMPLES,
    PATTERNS,
    PRESETS,
    AircraftConfig,
    SimulationConfig,
    preset,
    with_overrides,
)
from aeromag_env.simulation.simulate import STAGES, simulate_flight

#: The suffixes of the flight files ``simulate`` writes (the format follows the suffix).
FLIGHT_SUFFIXES = (".h5", ".hdf5", ".csv", ".xyz", ".mat")
#: The stages a simulation reports to ``progress`` (then ``write``).
__all__ = ["FLIGHT_SUFFIXES", "STAGES", "SimulateRequest", "SimulationResult", "simulate"]
#: The fields a replayed file must have.
REPLAY_NEEDS = ("tt", "position", "attitude", "date")


@dataclass(frozen=True, kw_only=True)
class SimulateRequest:
    """What a simulation is asked for (validated by :meth:`check`).

    Attributes
    ----------
    out : Path
        The flight file to write (its suffix, one of :data:`FLIGHT_SUFFIXES`, picks the format).
    seed : int
        The seed of the trajectory's draws, the aircraft and the noise, in ``[0, 2³² − 1]``.
    preset : str
        A physics preset of :data:`~aeromag_env.simulation.config.PRESETS` (unless ``config``).
    config : Path or None
        A JSON simulator configuration, instead of the preset.
    pattern : str or None
        The flight pattern (:data:`~aeromag_env.simulation.config.PATTERNS`; None: the
        configuration's).
    duration_s : float or None
        The flight's duration [s] (None: the pattern's own).
    replay : Path or None
        A flight file whose time, position, attitude and auxiliary channels are flown.
    aircraft : int or None
        The aircraft's seed, in ``[0, 2³² − 1]``: it draws the interference coefficients, so
        flights with one ``aircraft`` and different ``seed`` are flights of one aircraft
        (:class:`~aeromag_env.simulation.config.AircraftConfig`); None: the flight's seed draws
        them.
    permanent_shift_nt, scalar_permanent_shift_nt : (float, float, float) or None
        Maintenance: the aircraft's permanent field shifted at the fluxgate and at the scalar
        magnetometer [nT] (with ``aircraft``).
    """

    out: Path
    seed: int = 0
    preset: str = "nominal"
    config: Path | None = None
    pattern: str | None = None
    duration_s: float | None = None
    replay: Path | None = None
    aircraft: int | None = None
    permanent_shift_nt: tuple[float, float, float] | None = None
    scalar_permanent_shift_nt: tuple[float, float, float] | None = None

    def check(self) -> None:
        """One-line errors for unusable arguments (before any file is read)."""
        if self.out.suffix.lower() not in FLIGHT_SUFFIXES:
            raise ArgumentError("out", f"must end in {', '.join(FLIGHT_SUFFIXES)}", self.out.name)
        check_seed("seed", self.seed)
        if self.preset not in PRESETS:
            raise ArgumentError("preset", f"must be one of {', '.join(PRESETS)}", self.preset)
        if self.pattern is not None and self.pattern not in PATTERNS:
            raise ArgumentError("pattern", f"must be one of {', '.join(PATTERNS)}", self.pattern)
        self._check_aircraft()
        self.simulation_config()  # the configuration file and the duration against its rate

    def _check_aircraft(self) -> None:
        """The aircraft's seed, and the maintenance shifts only with an aircraft."""
        if self.aircraft is not None:
            check_seed("aircraft", self.aircraft)
        for name in ("permanent_shift_nt", "scalar_permanent_shift_nt"):
            shift = getattr(self, name)
            if shift is None:
                continue
            if self.aircraft is None:
                raise ArgumentError(name, "shifts an aircraft's field: it needs aircraft")
            lo, hi = -MAX_PERMANENT_SHIFT_NT, MAX_PERMANENT_SHIFT_NT
            check_vector(name, shift, lo, hi, "nT", "above the Earth's whole field")

    def inputs(self) -> list[Path]:
        """The files the run reads (never overwritten)."""
        return [p for p in (self.config, self.replay) if p is not None]

    def simulation_config(self) -> SimulationConfig:
        """The simulator configuration: the JSON file or the preset, with the overrides."""
        if self.config is not None:
            try:
                text = self.config.read_text(encoding="utf-8")
            except OSError as e:
                raise ConfigError(
                    f"cannot read configuration {self.config}: {e.strerror}"
                ) from None
            except UnicodeDecodeError:
                raise ConfigError(f"configuration {self.config} is not UTF-8 text (JSON)") from None
            cfg = from_json(SimulationConfig, text)
        else:
            cfg = preset(self.preset)
        overrides: dict[str, object] = {}
        if self.pattern:
            overrides["trajectory.pattern"] = self.pattern
        if self.duration_s is not None:
            _check_duration(self.duration_s, cfg.trajectory.sample_rate_hz)
            overrides["trajectory.duration_s"] = float(self.duration_s)
        cfg = with_overrides(cfg, overrides) if overrides else cfg
        return cfg if self.aircraft is None else dataclasses.replace(cfg, aircraft=self.plane())

    def plane(self) -> AircraftConfig:
        """The aircraft (``aircraft`` given), with its maintenance shifts."""
        assert self.aircraft is not None
        zero = (0.0, 0.0, 0.0)
        return AircraftConfig(
            seed=self.aircraft,
            permanent_shift_nt=self.permanent_shift_nt or zero,
            scalar_permanent_shift_nt=self.scalar_permanent_shift_nt or zero,
        )


def _check_duration(duration_s: float, rate_hz: float) -> None:
    """``duration_s`` [s] finite and giving :data:`~aeromag_env.simulation.config.
    DURATION_SAMPLES` samples at ``rate_hz``."""
    lo, hi = DURATION_SAMPLES
    d = duration_s
    if not (isinstance(d, int | float) and math.isfinite(d) and lo <= d * rate_hz <= hi):
        raise ArgumentError(
            "duration_s",
            f"must be > 0 and give {lo} to {hi:.0e} samples: {lo / rate_hz:g} to "
            f"{hi / rate_hz:g} s at {rate_hz:g} Hz",
            d,
        )


@dataclass(frozen=True)
class SimulationResult:
    """What :func:`simulate` produced.

    Attributes
    ----------
    flight : Flight
        The simulated flight (with its ``truth_*`` fields).
    config : SimulationConfig
        Its configuration.
    seed : int
        Its seed.
    path : Path
        The file written.
    warnings : tuple of str
        What the replayed file's reader and checks said, one line each.
    """

    flight: Flight
    config: SimulationConfig
    seed: int
    path: Path
    warnings: tuple[str, ...]

    def summary(self) -> str:
        """One line: what was written."""
        flight, cfg = self.flight, self.config
        interf = flight.vector("truth_interf")
        rms = float(np.sqrt(np.mean(np.sum(interf**2, axis=1))))
        return (
            f"wrote {self.path}: {cfg.trajectory.pattern}, preset {cfg.preset}, seed {self.seed}; "
            f"{flight.n} samples ({flight.duration_s:.1f} s at {flight.sample_rate_hz:g} Hz), "
            f"{len(flight.maneuver_windows())} maneuver windows, "
            f"fluxgate interference {rms:.0f} nT RMS"
        )


def simulate(
    out: str | Path,
    *,
    seed: int = 0,
    preset: str = "nominal",
    config: str | Path | None = None,
    pattern: str | None = None,
    duration_s: float | None = None,
    replay: str | Path | None = None,
    aircraft: int | None = None,
    permanent_shift_nt: tuple[float, float, float] | None = None,
    scalar_permanent_shift_nt: tuple[float, float, float] | None = None,
    progress: Callable[[str], Any] | None = None,
) -> SimulationResult:
    """Simulate a flight (or replay one) and write it, as ``aeromag simulate`` does.

    Parameters
    ----------
    out : str or Path
        The flight file to write (.h5, .hdf5, .csv, .xyz or .mat).
    seed, preset, config, pattern, duration_s, replay, aircraft, permanent_shift_nt, \
    scalar_permanent_shift_nt
        See :class:`SimulateRequest`.
    progress : callable or None
        Called with the name of each stage as it starts
        (:data:`~aeromag_env.simulation.simulate.STAGES`, then ``write``).

    Returns
    -------
    SimulationResult

    Warns
    -----
    AeromagWarning
        What the replayed file's reader and checks found (also in the result's ``warnings``).

    Raises
    ------
    AeromagError
        Bad arguments, an unreadable configuration or replay, a flight too long for the memory
        available, or an output that is an input (one line), before anything is written.
    """
    request = SimulateRequest(
        out=Path(out),
        seed=seed,
        preset=preset,
        config=None if config is None else Path(config),
        pattern=pattern,
        duration_s=duration_s,
        replay=None if replay is None else Path(replay),
        aircraft=aircraft,
        permanent_shift_nt=permanent_shift_nt,
        scalar_permanent_shift_nt=scalar_permanent_shift_nt,
    )
    request.check()
    return run_simulate(request, JobWarnings(), progress)


def run_simulate(
    req: SimulateRequest, warn: JobWarnings, progress: Callable[[str], Any] | None = None
) -> SimulationResult:
    """Do the work of :func:`simulate` for a checked request; its warnings go to ``warn``."""
    from aeromag_env.flight.files import write_flight

    cfg = req.simulation_config()
    check_memory(cfg, replay=req.replay is not None)
    check_output_file(req.out, req.inputs())
    replay = load_replay(req.replay, warn) if req.replay is not None else None
    flight = simulate_flight(cfg, req.seed, progress=progress, replay=replay)
    if progress is not None:
        progress("write")
    write_flight(flight, req.out, inputs=req.inputs())
    return SimulationResult(flight, cfg, req.seed, req.out, tuple(warn.lines))


def check_memory(cfg: SimulationConfig, replay: bool) -> None:
    """Refuse a simulated flight that would not fit in the memory available now.

    The peak is :data:`~aeromag_env.jobs.limits.BYTES_PER_VALUE` per field and sample; the
    field count comes from a two-sample simulation of the same configuration. A replayed
    flight has the replayed file's length (already read), and a pattern without
    ``duration_s`` its own (minutes).
    """
    traj = cfg.trajectory
    if replay or traj.duration_s is None:
        return
    available = available_memory_bytes()
    if available is None:
        return
    probe = with_overrides(cfg, {"trajectory.duration_s": 2.0 / traj.sample_rate_hz})
    per_sample = BYTES_PER_VALUE * len(simulate_flight(probe, 0).names)
    samples = round(traj.duration_s * traj.sample_rate_hz)
    if samples * per_sample > available:
        largest = available // per_sample / traj.sample_rate_hz
        raise ArgumentError(
            "duration_s",
            f"{traj.duration_s:g} s needs about {samples * per_sample / 1e9:.3g} GB ({samples} "
            f"samples × {per_sample} bytes) but {available / 1e9:.3g} GB of memory is available: "
            f"the largest duration here is {largest:.0f} s",
        )


def load_replay(path: Path, warn: Callable[[str], None]) -> Flight:
    """The flight to replay, its reader's and checks' warnings said to ``warn``; refused when
    the time, position or attitude it would fly has a non-finite sample (the simulator cannot
    fly through a hole; ``aeromag info`` shows where they are)."""
    from aeromag_env.flight.files import load_flight

    replay, problems = load_flight(path, needs=REPLAY_NEEDS)
    for problem in [*problems, *replay_warnings(replay)]:
        warn(problem)
    flown = {
        "tt": replay.tt,
        **dict(zip(("lat", "lon", "alt"), replay.position_rad(), strict=True)),
        **dict(zip(("roll", "pitch", "yaw"), replay.attitude_rad(), strict=True)),
    }
    for name, values in flown.items():
        bad = int(np.count_nonzero(~np.isfinite(np.asarray(values, float))))
        if bad:
            raise FlightFileError(
                f"{path}: cannot replay: {name} has {bad} non-finite "
                "sample(s) (a replay flies every sample; cut them out first, "
                "e.g. with aeromag convert of a selected part)"
            )
    replay.attrs["path"] = str(path)
    return replay


def replay_warnings(replay: Flight) -> list[str]:
    """What makes a replay fly the wrong track, as ``compensate`` would warn of it: altitude
    channels that disagree (feet beside metres), a median ground speed no aircraft flies (time
    in ms, lat/lon in radians) and a magnetometer far from IGRF-14 at the file's position and
    date (lat/lon in radians, a wrong date)."""
    from aeromag_env.flight.channels import altitude_disagreements, choose_channels
    from aeromag_env.flight.earth_model import model_mismatch
    from aeromag_env.flight.quality import ground_speed_problem

    altitude = replay.altitude_name()
    chosen = choose_channels(replay, kinds=("scalar", "fluxgate"))
    scalar, flux = (c.name if c else None for c in (chosen.scalar, chosen.fluxgate))
    found = [ground_speed_problem(replay), model_mismatch(replay, scalar, flux)]
    disagree = altitude_disagreements(replay, altitude) if altitude else []
    return [*disagree, *(message for message in found if message)]
