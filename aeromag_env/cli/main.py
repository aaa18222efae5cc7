"""The ``aeromag`` command line: one entry point, one subcommand per job.

Every subcommand has ``--help``, writes its results atomically, and on bad input exits with
status 2 and a one-line message on stderr (no traceback).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import NoReturn

import numpy as np

from aeromag_env.configs import from_json
from aeromag_env.errors import AeromagError, ConfigError
from aeromag_env.flight.data import Flight
from aeromag_env.simulation.config import (
    PATTERNS,
    PRESETS,
    SimulationConfig,
    preset,
    with_overrides,
)

FLIGHT_SUFFIXES = (".h5", ".hdf5", ".csv")


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line error message (no usage dump)."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _add_simulate(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "simulate",
        help="simulate a flight and write it as a flight file",
        description="Simulate a flight (trajectory, IGRF-14 Earth field, aircraft "
        "interference, sensor noise) and write it in the MagNav/SGL layout.",
    )
    p.add_argument(
        "--pattern", choices=PATTERNS, help="flight pattern (default: the preset's, calibration)"
    )
    p.add_argument(
        "--preset",
        default="nominal",
        choices=list(PRESETS),
        help="physics preset (default nominal)",
    )
    p.add_argument("--config", help="JSON simulator configuration (instead of --preset)")
    p.add_argument("--seed", type=int, default=0, help="random seed, ≥ 0 (default 0)")
    p.add_argument(
        "--duration-s", type=float, help="flight duration [s] (default: the pattern's own)"
    )
    p.add_argument("--out", required=True, help="output flight file (.h5 or .csv)")
    p.add_argument(
        "--replay",
        metavar="FILE",
        help="fly this file's time, position, attitude and auxiliary channels instead of the "
        "configured trajectory (e.g. with a model_config.json from aeromag discover)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_simulate)


def _add_discover(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "discover",
        help="find what the model is missing in a measured flight",
        description="Fit the base model (paper eq. 5) on a calibration part, report where the "
        "simulated and measured fluxgate disagree, name the missing physical effects from the "
        "effects library (GLS F-tests, Holm-corrected), add them and show the gap on held-out "
        "data. Writes report.json, report.md, model_config.json, residual.png, diagnostics.png.",
    )
    p.add_argument("file", help="flight file (.h5 or .csv), real or simulated")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--flux", default="flux_a", help="vector magnetometer (default flux_a)")
    p.add_argument(
        "--calibration-window",
        nargs=2,
        type=float,
        metavar=("T0", "T1"),
        help="fit on this time window [s] and score the rest (default: interleaved 60-s "
        "blocks, every third held out)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress messages")
    p.set_defaults(func=_cmd_discover)


def _add_info(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "info",
        help="validate and summarise a flight file",
        description="Validate a flight file and summarise it; exits 2 if it is unusable.",
    )
    p.add_argument("file", help="flight file (.h5 or .csv)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(func=_cmd_info)


def _add_demo(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "demo",
        help="the main job: simulate, compensate, compare",
        description="Simulate a 30-minute nominal calibration flight, compensate it with kf, "
        "fakf, lsq and tl, and write figures and a summary table to --out.",
    )
    p.add_argument("--out", default="results/demo", help="output folder (default results/demo)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.set_defaults(func=_cmd_demo)


def _add_compensate(sub: argparse._SubParsersAction) -> None:
    from aeromag_env.compensation.compensate import METHODS

    p = sub.add_parser(
        "compensate",
        help="compensate a flight file with one method",
        description="Estimate and remove the aircraft's interference; write "
        "compensated.h5, report.json and compensation.png to --out.",
    )
    p.add_argument("file", help="flight file (.h5 or .csv)")
    p.add_argument("--method", required=True, choices=METHODS, help="compensation method")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--flux", default="flux_a", help="vector magnetometer id (default flux_a)")
    p.add_argument(
        "--scalar", default="mag_1_uc", help="scalar magnetometer for tl (default mag_1_uc)"
    )
    p.add_argument(
        "--tl-bandpass",
        nargs="+",
        default=["0.1", "0.9"],
        metavar="HZ",
        help="tl band-pass LOW HIGH [Hz] or 'none' (default 0.1 0.9)",
    )
    p.add_argument("--tl-trim", type=int, default=20, help="tl: samples trimmed at each end (20)")
    p.add_argument("--tl-ridge", type=float, default=0.0, help="tl: ridge parameter λ (0)")
    p.add_argument(
        "--calibration-window",
        nargs=2,
        type=float,
        metavar=("T0", "T1"),
        help="fit on T0 ≤ tt ≤ T1 [s] only, apply everywhere",
    )
    p.add_argument(
        "--filter-preset",
        choices=("default", "paper"),
        default="default",
        help="filter settings: package defaults or the paper's §4 Q(0), R(0), x(0)",
    )
    p.add_argument("--r-std-nt", type=float, help="filter measurement-noise std [nT] (default 1.5)")
    p.set_defaults(func=_cmd_compensate)


def _add_reproduce(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "reproduce-paper",
        help="reproduce Zhang, Zhao & Chang (2014) figs. 3–5",
        description="Run the paper's setting on a simulated flight and compare "
        "with its claims; writes report.json and fig3/4/5 PNGs to --out.",
    )
    p.add_argument("--out", default="results/paper", help="output folder (default results/paper)")
    p.add_argument("--quick", action="store_true", help="one calibration box instead of 30 min")
    p.add_argument("--seed", type=int, default=2014, help="random seed (default 2014)")
    p.set_defaults(func=_cmd_reproduce)


def _add_evaluate(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "evaluate",
        help="compare tuning policies on the same flights",
        description="Run every policy on the same seeds of a scenario; write "
        "results.json (paired differences vs fis with 95 %% intervals) and a figure.",
    )
    p.add_argument("--scenario", default="nominal", help="scenario (default nominal)")
    p.add_argument(
        "--policies",
        default="constant,fis,sage_husa,ding,tuned_constant,oracle",
        help="comma-separated policy names",
    )
    p.add_argument("--episodes", type=int, default=20, help="episodes (seeds) per policy (20)")
    p.add_argument(
        "--seed-start",
        type=int,
        default=100_000,
        help="first evaluation seed, ≥ 100000 (training uses the seeds below)",
    )
    p.add_argument("--out", default="results/evaluate", help="output folder")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_evaluate)


def _add_train(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "train",
        help="train a PPO tuner (needs the rl extra)",
        description="Train stable-baselines3 PPO on a scenario (hyperparameters in "
        "agents/hyperparams/ppo.json); resumes from --out's checkpoint; keeps the "
        "best validated policy as --out/policy.npz.",
    )
    p.add_argument("--scenario", default="nonstationary", help="scenario (default nonstationary)")
    p.add_argument("--timesteps", type=int, default=3_000_000, help="environment steps (3e6)")
    p.add_argument("--seed", type=int, default=0, help="training seed (default 0)")
    p.add_argument("--out", default="results/ppo", help="output folder (default results/ppo)")
    p.add_argument("--quick", action="store_true", help="tiny settings (tests)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument(
        "--hyperparams", help="hyperparameter file (default agents/hyperparams/ppo.json)"
    )
    p.set_defaults(func=_cmd_train)


def _add_bench(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "bench",
        help="speed benchmarks, measured side by side in one run",
        description="Run the speed benchmarks (simulation, filters, environments, PPO "
        "training, discovery, memory), each against a reference measured in the same run; "
        "print a table and write bench.json (medians of repeated runs). A full run takes "
        "a few minutes.",
    )
    p.add_argument("--out", default="results/bench", help="output folder (default results/bench)")
    p.add_argument("--quick", action="store_true", help="fewer repeats and shorter runs")
    p.set_defaults(func=_cmd_bench)


def build_parser() -> argparse.ArgumentParser:
    """The full ``aeromag`` parser."""
    parser = _Parser(prog="aeromag", description="Aircraft aeromagnetic compensation toolkit.")
    sub = parser.add_subparsers(
        dest="command", required=True, metavar="COMMAND", parser_class=_Parser
    )
    adders = (_add_simulate, _add_info, _add_compensate, _add_reproduce, _add_evaluate, _add_train,
              _add_discover, _add_demo,
              _add_bench)  # fmt: skip
    for add in adders:
        add(sub)
    return parser


def _simulation_config(args: argparse.Namespace) -> SimulationConfig:
    if args.config:
        try:
            text = Path(args.config).read_text(encoding="utf-8")
        except OSError as e:
            raise ConfigError(f"cannot read configuration {args.config}: {e.strerror}") from None
        cfg = from_json(SimulationConfig, text)
    else:
        cfg = preset(args.preset)
    overrides: dict[str, object] = {}
    if args.pattern:
        overrides["trajectory.pattern"] = args.pattern
    if args.duration_s is not None:
        overrides["trajectory.duration_s"] = args.duration_s
    return with_overrides(cfg, overrides) if overrides else cfg


def _cmd_simulate(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from aeromag_env.flight.files import write_flight
    from aeromag_env.simulation.simulate import STAGES, simulate_flight

    out = Path(args.out)
    if out.suffix.lower() not in FLIGHT_SUFFIXES:
        raise AeromagError(f"--out must end in {', '.join(FLIGHT_SUFFIXES)}, got {out.name!r}")
    if args.seed < 0:
        raise AeromagError(f"--seed must be ≥ 0, got {args.seed}")
    cfg = _simulation_config(args)
    replay = None
    if args.replay:
        from aeromag_env.flight.files import load_flight

        if Path(args.replay).resolve() == out.resolve():
            raise AeromagError("--out must not be the --replay file (inputs are never overwritten)")
        replay, _ = load_flight(args.replay, needs=("tt", "position", "attitude", "date"))
        replay.attrs["path"] = str(args.replay)
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
        inputs = [p for p in (args.config, args.replay) if p]
        write_flight(flight, out, inputs=inputs)
    print(simulation_summary(flight, out, cfg, args.seed))
    return 0


def simulation_summary(flight: Flight, out: Path, cfg: SimulationConfig, seed: int) -> str:
    """One line: what was written."""
    interf = flight.vector("truth_interf")
    rms = float(np.sqrt(np.mean(np.sum(interf**2, axis=1))))
    return (
        f"wrote {out}: {cfg.trajectory.pattern}, preset {cfg.preset}, seed {seed}; "
        f"{flight.n} samples ({flight.duration_s:.1f} s at {flight.sample_rate_hz:g} Hz), "
        f"{len(flight.maneuver_windows())} maneuver windows, "
        f"fluxgate interference {rms:.0f} nT RMS"
    )


def _cmd_discover(args: argparse.Namespace) -> int:
    from aeromag_env.cli.discover import run_discover

    out = Path(args.out)
    window = tuple(args.calibration_window) if args.calibration_window else None

    def say(msg: str) -> None:
        if not args.quiet:
            print(f"discover: {msg}", file=sys.stderr, flush=True)

    report = run_discover(Path(args.file), out, args.flux, window, say)
    gap = report["gap"]
    print(
        f"{report['verdict']}; held-out gap {gap['rms_before_nt']:.3g} → "
        f"{gap['rms_after_nt']:.3g} nT ({gap['shrink']:.2f}×); wrote {out}/report.json, "
        "report.md, model_config.json, residual.png, diagnostics.png"
    )
    return 0


def _cmd_info(args: argparse.Namespace) -> int:
    from aeromag_env.flight.info import main_info

    return main_info(args.file, as_json=args.json)


def _cmd_demo(args: argparse.Namespace) -> int:
    from aeromag_env.cli.demo import run_demo

    out = Path(args.out)
    run_demo(out, args.seed)
    print((out / "summary.md").read_text(encoding="utf-8"), end="")
    files = "flight.h5, flight.png, compensation_*.png, tuners.png, summary.md, summary.json"
    print(f"results in {out}/: {files}")
    return 0


def _tl_bandpass(values: list[str]) -> tuple[float, float] | None:
    if len(values) == 1 and values[0].lower() == "none":
        return None
    try:
        lo, hi = (float(v) for v in values)
    except ValueError:
        raise AeromagError(
            f"--tl-bandpass takes LOW HIGH [Hz] or 'none', got {' '.join(values)}"
        ) from None
    return lo, hi


def _cmd_compensate(args: argparse.Namespace) -> int:
    from aeromag_env.cli.compensate import CompensateRequest, run_compensate, summary_line

    req = CompensateRequest(
        path=Path(args.file), out=Path(args.out), method=args.method, flux=args.flux,
        scalar=args.scalar, tl_bandpass_hz=_tl_bandpass(args.tl_bandpass), tl_trim=args.tl_trim,
        tl_ridge=args.tl_ridge, calibration_window_s=tuple(args.calibration_window) if
        args.calibration_window else None, filter_preset=args.filter_preset, r_std_nt=args.r_std_nt,
    )  # fmt: skip
    report = run_compensate(req)
    print(summary_line(report, req.out))
    return 0


def _cmd_reproduce(args: argparse.Namespace) -> int:
    from aeromag_env.compensation.paper import reproduce_paper

    reproduce_paper(Path(args.out), quick=args.quick, seed=args.seed)
    return 0


def _cmd_evaluate(args: argparse.Namespace) -> int:
    from aeromag_env.cli.evaluate import run_evaluate

    policies = [p.strip() for p in args.policies.split(",") if p.strip()]
    run_evaluate(
        args.scenario, policies, args.episodes, args.seed_start, Path(args.out), args.quiet
    )
    return 0


def _cmd_train(args: argparse.Namespace) -> int:
    try:
        from agents.ppo import train_ppo
    except ImportError as e:
        raise AeromagError(
            f"training needs the rl extra (pip install 'aeromag-env[rl]'): {e}"
        ) from None
    if args.timesteps < 1 or args.seed < 0:
        raise AeromagError("--timesteps must be ≥ 1 and --seed ≥ 0")
    extra = {"hyperparams": Path(args.hyperparams)} if args.hyperparams else {}
    summary = train_ppo(args.scenario, args.timesteps, args.seed, Path(args.out), args.quick,
                        progress=not args.quiet, **extra)  # fmt: skip
    print(
        f"trained {summary['timesteps']} steps in {summary['train_seconds_this_run']:.0f} s; "
        f"best validation RMSE {summary['best_validation_rmse_nt']:.3g} nT; "
        f"policy: {args.out}/policy.npz"
    )
    return 0


def _cmd_bench(args: argparse.Namespace) -> int:
    from aeromag_env.cli.bench import run_benchmarks

    run_benchmarks(Path(args.out), quick=args.quick)
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``aeromag``; returns the exit status."""
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except AeromagError as e:
        print(f"aeromag {args.command}: error: {e}", file=sys.stderr)
        return 2
    except OSError as e:
        print(
            f"aeromag {args.command}: error: {e.strerror or e}: {e.filename or ''}", file=sys.stderr
        )
        return 2
    except KeyboardInterrupt:
        print(
            f"aeromag {args.command}: interrupted; no output was left half-written", file=sys.stderr
        )
        return 130


if __name__ == "__main__":
    sys.exit(main())
