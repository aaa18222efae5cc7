"""``aeromag simulate``: the configuration from the arguments, the replayed flight checked, the
flight simulated and written atomically (the output is never an input)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from aeromag_env.atomic import check_output_file
from aeromag_env.cli import limits
from aeromag_env.configs import from_json
from aeromag_env.errors import AeromagError, ConfigError, FlightFileError
from aeromag_env.flight.data import Flight
from aeromag_env.simulation.config import SimulationConfig, preset, with_overrides

FLIGHT_SUFFIXES = (".h5", ".hdf5", ".csv", ".xyz", ".mat")


def simulation_config(args: argparse.Namespace) -> SimulationConfig:
    """The simulator configuration of ``aeromag simulate``'s arguments.

    Parameters
    ----------
    args : argparse.Namespace
        ``config`` (a JSON file, else ``preset``), ``pattern`` and ``duration_s`` overrides.

    Returns
    -------
    SimulationConfig
    """
    if args.config:
        try:
            text = Path(args.config).read_text(encoding="utf-8")
        except OSError as e:
            raise ConfigError(f"cannot read configuration {args.config}: {e.strerror}") from None
        except UnicodeDecodeError:
            raise ConfigError(f"configuration {args.config} is not UTF-8 text (JSON)") from None
        cfg = from_json(SimulationConfig, text)
    else:
        cfg = preset(args.preset)
    overrides: dict[str, object] = {}
    if args.pattern:
        overrides["trajectory.pattern"] = args.pattern
    if args.duration_s is not None:
        overrides["trajectory.duration_s"] = args.duration_s
    return with_overrides(cfg, overrides) if overrides else cfg


def load_replay(path: str | Path) -> Flight:
    """The flight to replay: its reader's warnings on stderr (one line each); refused when the
    time, position or attitude it would fly has a non-finite sample (the simulator cannot fly
    through a hole; ``aeromag info`` shows where they are)."""
    from aeromag_env.flight.files import load_flight

    replay, problems = load_flight(path, needs=("tt", "position", "attitude", "date"))
    for problem in [*problems, *replay_warnings(replay)]:
        print(f"aeromag simulate: warning: {problem}", file=sys.stderr)
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


def run_simulate(args: argparse.Namespace) -> tuple[Flight, SimulationConfig]:
    """Do the work of ``aeromag simulate``: check, simulate (or replay), write; return the
    flight and its configuration."""
    from tqdm import tqdm

    from aeromag_env.flight.files import write_flight
    from aeromag_env.simulation.simulate import STAGES, simulate_flight

    out = Path(args.out)
    if out.suffix.lower() not in FLIGHT_SUFFIXES:
        raise AeromagError(f"--out must end in {', '.join(FLIGHT_SUFFIXES)}, got {out.name!r}")
    limits.check_seed("--seed", args.seed)
    cfg = simulation_config(args)
    limits.check_simulation(cfg, replay=bool(args.replay))
    inputs = [p for p in (args.config, args.replay) if p]
    check_output_file(out, inputs)
    replay = load_replay(args.replay) if args.replay else None
    with tqdm(
        total=len(STAGES) + 1,
        desc="simulate",
        unit="stage",
        disable=args.quiet or None,
        leave=False,
    ) as bar:

        def progress(stage: str) -> None:
            bar.set_description(stage)
            bar.update(1)

        flight = simulate_flight(cfg, args.seed, progress=progress, replay=replay)
        progress("write")
        write_flight(flight, out, inputs=inputs)
    return flight, cfg


def simulation_summary(flight: Flight, out: Path, cfg: SimulationConfig, seed: int) -> str:
    """One line: what was written.

    Parameters
    ----------
    flight : Flight
        The simulated flight.
    out : pathlib.Path
        Where it was written.
    cfg : SimulationConfig
        Its configuration.
    seed : int
        Its seed.

    Returns
    -------
    str
    """
    interf = flight.vector("truth_interf")
    rms = float(np.sqrt(np.mean(np.sum(interf**2, axis=1))))
    return (
        f"wrote {out}: {cfg.trajectory.pattern}, preset {cfg.preset}, seed {seed}; "
        f"{flight.n} samples ({flight.duration_s:.1f} s at {flight.sample_rate_hz:g} Hz), "
        f"{len(flight.maneuver_windows())} maneuver windows, "
        f"fluxgate interference {rms:.0f} nT RMS"
    )
