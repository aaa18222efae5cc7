"""Handlers of the ``aeromag`` subcommands: each reads its parsed arguments into one job's
arguments (:mod:`aeromag_env.jobs`, imported when the command runs), calls the job with its
warnings shown on stderr, prints what it did and returns the exit status. Bad input raises
:class:`~aeromag_env.errors.AeromagError`, which :func:`aeromag_env.cli.main.main` turns into one
line and status 2. The parser is :mod:`aeromag_env.cli.parser`.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from aeromag_env.cli import options
from aeromag_env.cli.stderr import warn_stderr, warnings_on_stderr


def _progress_bar(args: argparse.Namespace, total: int, desc: str, unit: str) -> Any:
    """A tqdm bar on stderr (none with ``--quiet`` or when stderr is not a terminal)."""
    from tqdm import tqdm

    quiet = getattr(args, "quiet", False)
    return tqdm(total=total, desc=desc, unit=unit, disable=quiet or None, leave=False)


def cmd_simulate(args: argparse.Namespace) -> int:
    """``aeromag simulate``: simulate a flight (or replay one) and write it."""
    from aeromag_env.jobs.simulate import STAGES, simulate

    with _progress_bar(args, len(STAGES) + 1, "simulate", "stage") as bar:

        def progress(stage: str) -> None:
            bar.set_description(stage)
            bar.update(1)

        with warnings_on_stderr("simulate"):
            result = simulate(
                args.out,
                seed=args.seed,
                preset=args.preset,
                config=args.config,
                pattern=args.pattern,
                duration_s=args.duration_s,
                replay=args.replay,
                aircraft=args.aircraft,
                permanent_shift_nt=options.triple(args.permanent_shift_nt),
                scalar_permanent_shift_nt=options.triple(args.scalar_permanent_shift_nt),
                progress=progress,
            )
    print(result.summary())
    return 0


def cmd_info(args: argparse.Namespace) -> int:
    """``aeromag info``: validate and summarise a flight file; 2 when it is unusable."""
    import json

    from aeromag_env.jobs.info import info

    sel = options.selection(args)
    report = info(args.file, lines=sel["lines"], segment_s=sel["segment_s"])
    if args.json:
        print(json.dumps(report.to_dict(), indent=2, ensure_ascii=False, allow_nan=False))
    elif report.summary.keys() - {"path", "format"}:  # a summary, not just the failed read
        print("\n".join(report.lines))
    if report.usable:
        return 0
    print(f"aeromag info: error: {report.problems[0].removeprefix('unusable: ')}", file=sys.stderr)
    return 2


def cmd_convert(args: argparse.Namespace) -> int:
    """``aeromag convert``: read a flight file in any format and write it in another."""
    from aeromag_env.jobs.convert import convert

    result = convert(args.input, args.output)
    for problem in result.warnings:
        print(f"aeromag convert: warning: {problem}", file=sys.stderr)
    print(f"wrote {args.output}: {result.flight.n} samples, {len(result.flight.names)} fields")
    return 0


def cmd_example(args: argparse.Namespace) -> int:
    """``aeromag example``: write the sample survey file of the guides."""
    from aeromag_env.jobs.example import example

    print(example(args.output).summary())
    return 0


def _fit_options(args: argparse.Namespace) -> dict[str, Any]:
    """The channel, mount, Tolles–Lawson and filter options as the jobs' keyword arguments."""
    return {
        "flux": args.flux,
        "scalar": args.scalar,
        "tl_bandpass_hz": options.parse_bandpass(args.tl_bandpass),
        "tl_trim": args.tl_trim,
        "tl_ridge": args.tl_ridge,
        "calibration_window_s": options.window(args.calibration_window),
        "filter_preset": args.filter_preset,
        "r_std_nt": args.r_std_nt,
        "mount": args.mount,
        "html": not args.no_html,
    }


def cmd_compensate(args: argparse.Namespace) -> int:
    """``aeromag compensate``: compensate a flight file with one method or a calibrated model
    (or each of a folder or glob of them: :mod:`aeromag_env.jobs.fleet`); 2 when a flight of a
    fleet failed."""
    from aeromag_env.cli.fleet import note_single_file, run_fleet
    from aeromag_env.cli.summaries import compensate_line
    from aeromag_env.jobs import ArgumentError
    from aeromag_env.jobs.compensate import compensate
    from aeromag_env.jobs.fleet import is_fleet

    if args.method is None and args.model is None:
        raise ArgumentError("method", "is needed (or model, a calibrated model to apply)")
    out = Path(args.out)
    kwargs = {**_fit_options(args), **options.selection(args), "model": args.model}
    if is_fleet(args.file):
        return run_fleet(
            "compensate", args.file, out, args.ray, False, {"method": args.method, **kwargs}
        )
    note_single_file("compensate", args.ray)
    with warnings_on_stderr("compensate"):
        result = compensate(args.file, args.method, out, **kwargs)
    for problem in result.input_problems:
        warn_stderr("compensate", problem)
    print(compensate_line(result.report, out, html=not args.no_html))
    return 0


def cmd_calibrate(args: argparse.Namespace) -> int:
    """``aeromag calibrate``: fit a model on a calibration flight; print its figures."""
    from aeromag_env.cli.summaries import calibrate_line
    from aeromag_env.jobs.calibrate import calibrate

    out = Path(args.out)
    kwargs = {
        **_fit_options(args),
        "calibration_line": options.parse_calibration_line(args.calibration_line),
    }
    with warnings_on_stderr("calibrate"):
        result = calibrate(args.file, args.method, out, **kwargs)
    for problem in result.report["input_problems"]:
        warn_stderr("calibrate", problem)
    print(calibrate_line(result.report, out, html=not args.no_html))
    return 0


def cmd_stream(args: argparse.Namespace) -> int:
    """``aeromag stream``: compensate CSV samples on stdin, one flushed line each on stdout;
    bad lines are warnings on stderr, skipped."""
    from aeromag_env.jobs.stream import stream

    with warnings_on_stderr("stream"):
        stream(args.model, sys.stdin, sys.stdout, date=args.date)
    return 0


def cmd_discover(args: argparse.Namespace) -> int:
    """``aeromag discover``: find what the model is missing in a flight file (or in each of a
    folder or glob of them); 2 when a flight of a fleet failed."""
    from aeromag_env.cli.fleet import note_single_file, run_fleet
    from aeromag_env.cli.summaries import discover_line
    from aeromag_env.jobs.discover import discover
    from aeromag_env.jobs.fleet import is_fleet

    out = Path(args.out)
    kwargs = {
        "flux": args.flux,
        "calibration_window_s": options.window(args.calibration_window),
        "mount": args.mount,
        "ground": args.ground,
        "html": not args.no_html,
        **options.selection(args),
    }
    if is_fleet(args.file):
        return run_fleet("discover", args.file, out, args.ray, args.quiet, kwargs)
    note_single_file("discover", args.ray)

    def say(msg: str) -> None:
        if not args.quiet:
            print(f"discover: {msg}", file=sys.stderr, flush=True)

    with warnings_on_stderr("discover"):
        result = discover(args.file, out, say, **kwargs)
    for problem in result.report["input_problems"]:
        warn_stderr("discover", problem)
    print(discover_line(result.report, out, html=not args.no_html))
    return 0


def cmd_reproduce(args: argparse.Namespace) -> int:
    """``aeromag reproduce-paper``: reproduce the paper's figures 3–5."""
    from aeromag_env.jobs.reproduce import reproduce

    reproduce(args.out, quick=args.quick, seed=args.seed)
    return 0


def cmd_evaluate(args: argparse.Namespace) -> int:
    """``aeromag evaluate``: compare tuning policies on the same flights; print a table per
    scenario."""
    from aeromag_env.jobs.evaluate import evaluate, scenario_names

    policies = [p.strip() for p in args.policies.split(",") if p.strip()]
    scenarios = scenario_names(args.scenario)
    total = args.episodes * len(policies) * len(scenarios)
    with _progress_bar(args, total, args.scenario, "episode") as bar:
        result = evaluate(
            scenarios,
            policies,
            episodes=args.episodes,
            seed_start=args.seed_start,
            out=args.out,
            ray=args.ray,
            html=not args.no_html,
            progress=bar.update,
        )
    if result.note:
        print(f"aeromag evaluate: {result.note}", file=sys.stderr)
    out = Path(args.out)
    for name, table in result.tables().items():
        folder = out if len(result.results) == 1 else out / name
        print(table)
        print(f"wrote {folder}/results.json, evaluation.png")
    return 0


def cmd_train(args: argparse.Namespace) -> int:
    """``aeromag train``: train a tuner (one run, or one per seed with ``--seeds``)."""
    from aeromag_env.cli.summaries import seed_table
    from aeromag_env.jobs import AeromagError
    from aeromag_env.jobs.train import train

    seeds = None if args.seeds is None else options.parse_seeds(args.seeds)
    with _progress_bar(args, len(seeds or ()), "training seeds", "seed") as bar:
        result = train(
            args.out,
            learner=args.learner,
            scenario=args.scenario,
            timesteps=args.timesteps,
            seed=args.seed,
            seeds=seeds,
            quick=args.quick,
            hyperparams=args.hyperparams,
            ray=args.ray,
            html=not args.no_html,
            show_progress=seeds is None and not args.quiet,
            on_seed=lambda outcome: bar.update(1),
        )
    if seeds is None:
        s = result.summary
        if result.finished:
            print(
                f"already trained: {s['timesteps']} steps in {args.out} (the request's total); "
                f"nothing to do; best validation RMSE {s['best_validation_rmse_nt']:.3g} nT; "
                f"policy: {args.out}/policy.npz"
            )
            return 0
        print(
            f"trained {s['timesteps']} steps in {s['train_seconds_this_run']:.0f} s; "
            f"best validation RMSE {s['best_validation_rmse_nt']:.3g} nT; "
            f"policy: {args.out}/policy.npz"
        )
        return 0
    if result.finished:
        done = ", ".join(map(str, result.finished))
        print(f"already trained to the request's total: seed(s) {done}; not trained again")
    print(seed_table(result.summary))
    if result.failed:
        first = result.failed[0]
        raise AeromagError(
            f"{len(result.failed)} of {len(seeds)} training run(s) failed; first: "
            f"{first.label}: {first.error}"
        )
    print(f"policies: {args.out}/seed_<k>/policy.npz; summary: {args.out}/seeds.json")
    return 0


def cmd_tune(args: argparse.Namespace) -> int:
    """``aeromag tune``: search a learner's hyperparameters with Ray Tune."""
    from aeromag_env.cli.summaries import tune_summary
    from aeromag_env.jobs.tune import tune

    result = tune(
        args.out,
        learner=args.learner,
        scenario=args.scenario,
        space=args.space,
        samples=args.samples,
        timesteps=args.timesteps,
        seed=args.seed,
        quick=args.quick,
        ray=args.ray,
        hyperparams=args.hyperparams,
    )
    if result.finished:
        print(f"already searched: {args.out}/tune.json records this request; nothing to do")
    print(tune_summary(result.summary, args.out))
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    """``aeromag demo``: simulate, compensate and compare, and print the summary."""
    from aeromag_env.jobs.demo import demo

    result = demo(args.out, seed=args.seed)
    print(result.text, end="")
    files = "flight.h5, flight.png, compensation_*.png, tuners.png, summary.md, summary.json"
    files += ", report.html"
    print(f"results in {args.out}/: {files}")
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    """``aeromag bench``: run the speed benchmarks; print the table."""
    from aeromag_env.jobs.bench import bench

    result = bench(args.out, quick=args.quick, ray=args.ray, only=args.only)
    print(result.table)
    print(f"wrote {result.path}")
    return 0
