"""Handlers of the ``aeromag`` subcommands: each takes the parsed arguments, does the job
(importing what it needs lazily, ``agents`` included) and returns the exit status; bad input
raises :class:`~aeromag_env.errors.AeromagError`, which :func:`aeromag_env.cli.main.main` turns
into a one-line message and status 2. The parser is :mod:`aeromag_env.cli.parser`.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

from aeromag_env.cli import limits
from aeromag_env.errors import AeromagError


def cmd_simulate(args: argparse.Namespace) -> int:
    """``aeromag simulate``: simulate a flight (or replay one) and write it.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed arguments of the subcommand.

    Returns
    -------
    int
        Exit status (0); bad input raises :class:`~aeromag_env.errors.AeromagError`.
    """
    from aeromag_env.cli.simulate import run_simulate, simulation_summary

    flight, cfg = run_simulate(args)
    print(simulation_summary(flight, Path(args.out), cfg, args.seed))
    return 0


def cmd_discover(args: argparse.Namespace) -> int:
    """``aeromag discover``: find what the model is missing in a flight file (or in each of a
    folder or glob of them: :mod:`aeromag_env.jobs.fleet`).

    Parameters
    ----------
    args : argparse.Namespace
        Parsed arguments of the subcommand.

    Returns
    -------
    int
        Exit status (0; a fleet with a failed flight 2); bad input raises
        :class:`~aeromag_env.errors.AeromagError`.
    """
    limits.check_window("--calibration-window", args.calibration_window)
    from aeromag_env.cli.discover import summary_line
    from aeromag_env.cli.fleet import note_single_file, run_fleet
    from aeromag_env.cli.stderr import warnings_on_stderr
    from aeromag_env.jobs.discover import discover
    from aeromag_env.jobs.fleet import is_fleet

    out = Path(args.out)
    options = {
        "flux": args.flux,
        "calibration_window": tuple(args.calibration_window) if args.calibration_window else None,
        "mount": args.mount,
        "ground": args.ground,
        "html": not args.no_html,
        **selection_options(args),
    }

    def say(msg: str) -> None:
        if not args.quiet:
            print(f"discover: {msg}", file=sys.stderr, flush=True)

    if is_fleet(args.file):
        return run_fleet("discover", args.file, out, args.ray, args.quiet, options)
    note_single_file("discover", args.ray)
    with warnings_on_stderr():
        result = discover(args.file, out, say, **options)
    print(summary_line(result.report, out, html=not args.no_html))
    return 0


def selection_options(args: argparse.Namespace) -> dict[str, Any]:
    """``--line``, ``--segment`` and ``--calibration-line`` parsed (one-line errors), as keyword
    arguments of the requests: ``lines``, ``segment_s`` and ``calibration_line``."""
    from aeromag_env.flight.selection import parse_lines, parse_segment

    out: dict[str, Any] = {
        "lines": parse_lines(args.line) if args.line is not None else None,
        "segment_s": parse_segment(args.segment) if args.segment is not None else None,
    }
    line = getattr(args, "calibration_line", None)  # info has no --calibration-line
    if line is not None and line != "auto":
        try:
            value = float(line)
        except ValueError:
            value = float("nan")
        if not np.isfinite(value):
            raise AeromagError(
                f"--calibration-line takes one line id (or none: auto), got {line!r}"
            )
        line = f"{value:g}"
    out["calibration_line"] = line
    return out


def cmd_info(args: argparse.Namespace) -> int:
    """``aeromag info``: validate and summarise a flight file.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed arguments of the subcommand.

    Returns
    -------
    int
        Exit status (0); bad input raises :class:`~aeromag_env.errors.AeromagError`.
    """
    from aeromag_env.flight.info import main_info

    sel = selection_options(args)
    return main_info(args.file, args.json, sel["lines"], sel["segment_s"])


def cmd_convert(args: argparse.Namespace) -> int:
    """``aeromag convert``: read a flight file in any format and write it in another.

    Parameters
    ----------
    args : argparse.Namespace
        ``input`` and ``output`` paths.

    Returns
    -------
    int
        Exit status (0); the reader's warnings go to stderr, one line each; bad input raises
        :class:`~aeromag_env.errors.AeromagError`.
    """
    from aeromag_env.flight.files import convert_flight

    flight, problems = convert_flight(args.input, args.output)
    for problem in problems:
        print(f"aeromag convert: warning: {problem}", file=sys.stderr)
    print(f"wrote {args.output}: {flight.n} samples, {len(flight.names)} fields")
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    """``aeromag demo``: simulate, compensate and compare, and print the summary.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed arguments of the subcommand.

    Returns
    -------
    int
        Exit status (0); bad input raises :class:`~aeromag_env.errors.AeromagError`.
    """
    limits.check_seed("--seed", args.seed)
    from aeromag_env.cli.demo import run_demo

    out = Path(args.out)
    run_demo(out, args.seed)
    print((out / "summary.md").read_text(encoding="utf-8"), end="")
    files = "flight.h5, flight.png, compensation_*.png, tuners.png, summary.md, summary.json"
    print(f"results in {out}/: {files}")
    return 0


def tl_bandpass(values: list[str]) -> tuple[float, float] | None:
    """The ``--tl-bandpass`` values as (low, high) [Hz], or None for ``none``.

    Parameters
    ----------
    values : list of str
        LOW HIGH, or the single word ``none``.

    Returns
    -------
    tuple of float or None
    """
    if len(values) == 1 and values[0].lower() == "none":
        return None
    try:
        lo, hi = (float(v) for v in values)
    except ValueError:
        raise AeromagError(
            f"--tl-bandpass takes LOW HIGH [Hz] or 'none', got {' '.join(values)}"
        ) from None
    return lo, hi


def cmd_compensate(args: argparse.Namespace) -> int:
    """``aeromag compensate``: compensate a flight file with one method (or each of a folder or
    glob of them: :mod:`aeromag_env.jobs.fleet`).

    Parameters
    ----------
    args : argparse.Namespace
        Parsed arguments of the subcommand.

    Returns
    -------
    int
        Exit status (0; a fleet with a failed flight 2); bad input raises
        :class:`~aeromag_env.errors.AeromagError`.
    """
    limits.check_compensate(args)
    from aeromag_env.cli.compensate import summary_line
    from aeromag_env.cli.fleet import note_single_file, run_fleet
    from aeromag_env.cli.stderr import warnings_on_stderr
    from aeromag_env.jobs.compensate import compensate
    from aeromag_env.jobs.fleet import is_fleet

    out = Path(args.out)
    options = {
        "flux": args.flux,
        "scalar": args.scalar,
        "tl_bandpass_hz": tl_bandpass(args.tl_bandpass),
        "tl_trim": args.tl_trim,
        "tl_ridge": args.tl_ridge,
        "calibration_window_s": (
            tuple(args.calibration_window) if args.calibration_window else None
        ),
        "filter_preset": args.filter_preset,
        "r_std_nt": args.r_std_nt,
        "mount": args.mount,
        "html": not args.no_html,
        **selection_options(args),
    }
    if is_fleet(args.file):
        options["method"] = args.method
        return run_fleet("compensate", args.file, out, args.ray, False, options)
    note_single_file("compensate", args.ray)
    with warnings_on_stderr():
        result = compensate(args.file, args.method, out, **options)
    print(summary_line(result.report, out, html=not args.no_html))
    return 0


def cmd_reproduce(args: argparse.Namespace) -> int:
    """``aeromag reproduce-paper``: reproduce the paper's figures 3–5.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed arguments of the subcommand.

    Returns
    -------
    int
        Exit status (0); bad input raises :class:`~aeromag_env.errors.AeromagError`.
    """
    limits.check_seed("--seed", args.seed)
    from aeromag_env.compensation.paper import reproduce_paper

    reproduce_paper(Path(args.out), quick=args.quick, seed=args.seed)
    return 0


def cmd_evaluate(args: argparse.Namespace) -> int:
    """``aeromag evaluate``: compare tuning policies on the same flights.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed arguments of the subcommand.

    Returns
    -------
    int
        Exit status (0); bad input raises :class:`~aeromag_env.errors.AeromagError`.
    """
    limits.check_evaluate(args)
    from aeromag_env.cli.evaluate import run_evaluate

    policies = [p.strip() for p in args.policies.split(",") if p.strip()]
    run_evaluate(
        args.scenario,
        policies,
        args.episodes,
        args.seed_start,
        Path(args.out),
        args.quiet,
        ray=args.ray,
        html=not args.no_html,
    )
    return 0


def cmd_train(args: argparse.Namespace) -> int:
    """``aeromag train``: train a PPO tuner (imports ``agents`` lazily).

    Parameters
    ----------
    args : argparse.Namespace
        Parsed arguments of the subcommand.

    Returns
    -------
    int
        Exit status (0); bad input raises :class:`~aeromag_env.errors.AeromagError`.
    """
    limits.check_train(args)
    try:
        from agents import learners
        from agents.ppo import HYPERPARAMS, train_ppo
    except ImportError as e:
        raise AeromagError(
            f"training needs the rl extra (pip install 'aeromag-env[rl]'): {e}"
        ) from None
    scenario = args.scenario or ("nonstationary" if args.learner == "ppo" else "suite")
    if args.learner != "ppo" and scenario != "suite":
        raise AeromagError(
            f"--learner {args.learner} trains the general tuner on the suite; --scenario "
            f"{scenario} is for --learner ppo"
        )
    if args.seeds is not None:  # one run per seed, side by side (--ray) or one after another
        from aeromag_env.cli.train import parse_seeds, train_seeds

        hp = Path(args.hyperparams) if args.hyperparams else None
        train_seeds(
            scenario,
            args.timesteps,
            parse_seeds(args.seeds),
            Path(args.out),
            args.quick,
            hp,
            args.ray,
            args.quiet,
            html=not args.no_html,
            learner=args.learner,
        )
        print(f"policies: {args.out}/seed_<k>/policy.npz; summary: {args.out}/seeds.json")
        return 0
    if args.ray is not None:
        raise AeromagError("--ray runs several training seeds side by side: give --seeds")
    if args.learner == "ppo":
        summary = train_ppo(
            scenario,
            args.timesteps,
            args.seed,
            Path(args.out),
            args.quick,
            progress=not args.quiet,
            hyperparams=Path(args.hyperparams) if args.hyperparams else HYPERPARAMS,
        )
    else:
        summary = learners.train_learner(
            args.learner,
            args.seed,
            Path(args.out),
            args.timesteps,
            args.quick,
            hyperparams=Path(args.hyperparams) if args.hyperparams else learners.HYPERPARAMS,
        )
    if not args.no_html:  # the learning curve beside training.json
        from aeromag_env import reports
        from aeromag_env.atomic import write_text

        page = reports.train_page({"run": summary}, f"Training: {args.learner} on {scenario}")
        write_text(Path(args.out) / reports.PAGE, page)
    print(
        f"trained {summary['timesteps']} steps in {summary['train_seconds_this_run']:.0f} s; "
        f"best validation RMSE {summary['best_validation_rmse_nt']:.3g} nT; "
        f"policy: {args.out}/policy.npz"
    )
    return 0


def cmd_tune(args: argparse.Namespace) -> int:
    """``aeromag tune``: search a learner's hyperparameters with Ray Tune
    (:mod:`aeromag_env.cli.tune`).

    Parameters
    ----------
    args : argparse.Namespace
        Parsed arguments of the subcommand.

    Returns
    -------
    int
        Exit status (0); bad input raises :class:`~aeromag_env.errors.AeromagError`.
    """
    from aeromag_env.cli.tune import run_tune, tune_summary

    print(tune_summary(run_tune(args), args.out))
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    """``aeromag bench``: run the speed benchmarks.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed arguments of the subcommand.

    Returns
    -------
    int
        Exit status (0); bad input raises :class:`~aeromag_env.errors.AeromagError`.
    """
    from aeromag_env.cli.bench import run_benchmarks

    if args.only == "ray" and args.ray is None:
        raise AeromagError("--only ray measures evaluate on Ray: give --ray [ADDRESS] too")
    run_benchmarks(Path(args.out), quick=args.quick, ray=args.ray, only=args.only)
    return 0
