"""The ``aeromag`` argument parser: one ``_add_*`` per subcommand (its options and ``--help``
text), each bound to its handler in :mod:`aeromag_env.cli.commands`; the choices come from
:mod:`aeromag_env.jobs.choices`.
"""

from __future__ import annotations

import argparse
from typing import NoReturn

from aeromag_env.cli.commands import (
    cmd_bench,
    cmd_calibrate,
    cmd_compensate,
    cmd_convert,
    cmd_demo,
    cmd_discover,
    cmd_evaluate,
    cmd_example,
    cmd_info,
    cmd_reproduce,
    cmd_simulate,
    cmd_stream,
    cmd_train,
    cmd_tune,
)
from aeromag_env.jobs.choices import (
    BENCH_ONLY,
    FILTER_PRESETS,
    FIT_METHODS,
    GROUND_MODES,
    LEARNERS,
    METHODS,
    PATTERNS,
    POLICIES,
    PRESETS,
)

#: The exit statuses of every subcommand (``--help`` epilog; :func:`aeromag_env.cli.main.main`).
EXIT_STATUS = (
    "exit status: 0 done; 2 bad input (options, files, paths; one line on stderr); 1 internal "
    "error (a bug: one line on stderr, AEROMAG_DEBUG=1 shows the traceback); 130 interrupted"
)

#: ``file`` of compensate and discover: also a fleet (:mod:`aeromag_env.jobs.fleet`).
FLEET_HELP = (
    "or a folder or quoted glob of them (a fleet, e.g. 'flights/**/*.h5'): one output folder per "
    "flight, OUT/<file stem>/, and a summary OUT/fleet.csv and fleet.png; exit status 2 if a "
    "flight failed, the others complete"
)


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
    p.add_argument(
        "--out", required=True, help="output flight file (.h5, .hdf5, .csv, .xyz or .mat)"
    )
    p.add_argument(
        "--replay",
        metavar="FILE",
        help="fly this file's time, position, attitude and auxiliary channels instead of the "
        "configured trajectory (e.g. with a model_config.json from aeromag discover)",
    )
    p.add_argument(
        "--aircraft",
        type=int,
        metavar="N",
        help="the aircraft's seed, ≥ 0: it draws the interference coefficients, so flights with "
        "one --aircraft and different --seed are flights of one aircraft (calibrate on one, "
        "apply to the others); default: --seed draws them",
    )
    p.add_argument(
        "--permanent-shift-nt",
        nargs=3,
        type=float,
        metavar=("X", "Y", "Z"),
        help="maintenance: shift the aircraft's permanent field at the fluxgate by X Y Z [nT] "
        "(with --aircraft)",
    )
    p.add_argument(
        "--scalar-permanent-shift-nt",
        nargs=3,
        type=float,
        metavar=("X", "Y", "Z"),
        help="maintenance: shift the aircraft's permanent field at the scalar magnetometer by "
        "X Y Z [nT] (with --aircraft)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_simulate)


def _add_discover(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "discover",
        help="find what the model is missing in a measured flight",
        description="Fit the base model (paper eq. 5) on a calibration part, report where the "
        "simulated and measured fluxgate disagree, name the missing physical effects from the "
        "effects library (GLS F-tests, Holm-corrected), add them and show the gap on held-out "
        "data. Writes report.json, report.md, model_config.json, residual.png, diagnostics.png.",
    )
    p.add_argument(
        "file",
        help=f"flight file (HDF5, CSV, Geosoft XYZ or MATLAB .mat), real or "
        f"simulated; {FLEET_HELP}",
    )
    p.add_argument("--out", required=True, help="output folder")
    _add_ray_option(p)
    p.add_argument(
        "--flux",
        default="auto",
        help="vector magnetometer id, or auto: the first fluxgate with clean data (default auto)",
    )
    _add_mount_option(p)
    p.add_argument(
        "--calibration-window",
        nargs=2,
        type=float,
        metavar=("T0", "T1"),
        help="fit on this time window [s] and score the rest (default: interleaved 60-s "
        "blocks, every third held out)",
    )
    p.add_argument(
        "--ground",
        choices=GROUND_MODES,
        default="ignore",
        help="separate: fit, test "
        "and score only what magnetic ground cannot explain (survey lines; the "
        "report lists effects it cannot tell from ground) (default ignore)",
    )
    _add_selection_options(p)
    p.add_argument("--quiet", action="store_true", help="no progress messages")
    _add_html_option(p)
    p.set_defaults(func=cmd_discover)


def _add_selection_options(p: argparse.ArgumentParser, calibration: bool = True) -> None:
    """``--line``, ``--segment`` and (``calibration``) ``--calibration-line`` (info, compensate,
    discover): :func:`aeromag_env.flight.selection.select`."""
    p.add_argument(
        "--line",
        metavar="N[,M…]",
        help="use only these flight lines (ids of the 'line' field, comma-separated)",
    )
    p.add_argument("--segment", metavar="T0:T1", help="use only the samples with T0 ≤ tt ≤ T1 [s]")
    if calibration:
        p.add_argument(
            "--calibration-line",
            nargs="?",
            const="auto",
            metavar="N",
            help="fit on the calibration line and judge on the rest, as the industry does: "
            "line N, or without N the line that holds the labelled manoeuvres or, unlabelled, "
            "the one flown with roll/pitch swings on several headings (the calibration box)",
        )


def _add_ray_option(p: argparse.ArgumentParser) -> None:
    """``--ray [ADDRESS]`` (evaluate, train, tune, compensate, discover, bench)."""
    p.add_argument(
        "--ray",
        nargs="?",
        const="local",
        metavar="ADDRESS",
        help="run the tasks on Ray (extra ray): without ADDRESS Ray starts on this machine with "
        "its cores; with one (host:port of `ray start --head`, or ray://host:10001) it joins "
        "that cluster (default: this process, no Ray)",
    )


def _add_html_option(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--no-html",
        action="store_true",
        help="do not write report.html (the interactive page; the PNG figures are written "
        "either way)",
    )


def _add_mount_option(p: argparse.ArgumentParser) -> None:
    """``--mount auto|identity|FILE`` (compensate, discover)."""
    p.add_argument(
        "--mount",
        default="auto",
        metavar="auto|identity|FILE",
        help="fluxgate mount (sensor → body rotation): auto estimates it from the data (IGRF, "
        "attitude) and applies it when over 1° from the body axes; identity takes the sensor "
        'axes for body axes; FILE is JSON, e.g. {"flux_a": {"roll_deg": 0, "pitch_deg": 0, '
        '"yaw_deg": 90}} or {"flux_a": {"rotation": [[…], […], […]]}} (default auto)',
    )


def _add_info(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "info",
        help="validate and summarise a flight file",
        description="Validate a flight file and summarise it; exits 2 if it is unusable.",
    )
    p.add_argument("file", help="flight file (HDF5, CSV, Geosoft XYZ or MATLAB .mat)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    _add_selection_options(p, calibration=False)
    p.set_defaults(func=cmd_info)


def _add_demo(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "demo",
        help="the main job: simulate, compensate, compare",
        description="Simulate a 30-minute nominal calibration flight, compensate it with kf, "
        "fakf, lsq and tl, and write figures and a summary table to --out.",
    )
    p.add_argument("--out", default="results/demo", help="output folder (default results/demo)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.set_defaults(func=cmd_demo)


def _add_compensate(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "compensate",
        help="compensate a flight file with one method, or with a calibrated model",
        description="Estimate and remove the aircraft's interference; write "
        "compensated.h5, report.json and compensation.png to --out. With --model, apply a "
        "model calibrated on another flight (aeromag calibrate) instead of fitting: a filter "
        "continues from its calibrated state; a warning says when the model no longer fits.",
    )
    p.add_argument(
        "file", help=f"flight file (HDF5, CSV, Geosoft XYZ or MATLAB .mat); {FLEET_HELP}"
    )
    p.add_argument(
        "--method",
        choices=METHODS,
        help="compensation method (required without --model; with it, the model's)",
    )
    p.add_argument(
        "--model",
        metavar="MODEL.json",
        help="apply this calibrated model (aeromag calibrate's model.json): nothing is fitted",
    )
    p.add_argument("--out", required=True, help="output folder")
    _add_html_option(p)
    _add_ray_option(p)
    _add_fit_options(p)
    _add_selection_options(p)
    p.set_defaults(func=cmd_compensate)


def _add_fit_options(p: argparse.ArgumentParser) -> None:
    """The channel, mount, Tolles–Lawson, calibration-window and filter options (compensate,
    calibrate)."""
    p.add_argument(
        "--flux",
        default="auto",
        help="vector magnetometer id, or auto: the first fluxgate with clean data (default auto)",
    )
    p.add_argument(
        "--scalar",
        default="auto",
        help="scalar magnetometer (tl, and the comparison with the vendor's compensated field), "
        "or auto: the first mag_N_uc with clean data (default auto)",
    )
    _add_mount_option(p)
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
        choices=FILTER_PRESETS,
        default="default",
        help="filter settings: package defaults or the paper's §4 Q(0), R(0), x(0)",
    )
    p.add_argument("--r-std-nt", type=float, help="filter measurement-noise std [nT] (default 1.5)")


def _add_calibrate(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "calibrate",
        help="fit a compensation model on a calibration flight, to apply to other flights",
        description="Fit a model on a calibration flight (the whole file, its calibration "
        "line or a time window) and write --out/model.json (for aeromag compensate --model and "
        "aeromag stream --model), report.json and report.html (the figure of merit box by "
        "box).",
    )
    p.add_argument("file", help="the calibration flight's file (HDF5, CSV, Geosoft XYZ, .mat)")
    p.add_argument(
        "--method",
        required=True,
        choices=FIT_METHODS,
        help="tl (Tolles–Lawson coefficients) or a recursive filter (its state at the end)",
    )
    p.add_argument("--out", required=True, help="output folder")
    _add_html_option(p)
    _add_fit_options(p)
    p.add_argument(
        "--calibration-line",
        nargs="?",
        const="auto",
        metavar="N",
        help="fit on flight line N only, or without N the calibration box's line (the one "
        "with the labelled manoeuvres or, unlabelled, the one flown with roll/pitch swings on "
        "several headings)",
    )
    p.set_defaults(func=cmd_calibrate)


def _add_stream(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "stream",
        help="compensate samples as they arrive (CSV lines on stdin → stdout)",
        description="Read a header line of channel names and then one CSV line per sample on "
        "standard input (aeromag convert's CSV is valid input: its # lines are skipped, its "
        "#@ date read); write a header and one line per sample on standard output (the time "
        "and the compensated field, named as compensate names it), flushed as each is "
        "answered: the same values as aeromag compensate --model on the same flight. A bad "
        "line is reported on stderr and skipped.",
    )
    p.add_argument(
        "--model", required=True, metavar="MODEL.json", help="the calibrated model to apply"
    )
    p.add_argument(
        "--date",
        metavar="YYYY-MM-DD",
        help="the flight's date, for a filter's model (default: the input's #@ date, else "
        "its first sample's year and doy)",
    )
    p.set_defaults(func=cmd_stream)


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
    p.set_defaults(func=cmd_reproduce)


def _add_evaluate(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "evaluate",
        help="compare tuning policies on the same flights",
        description="Run every policy on the same seeds of a scenario; write "
        "results.json (paired differences vs fis with 95 %% intervals) and a figure.",
    )
    p.add_argument(
        "--scenario",
        default="nominal",
        help="scenario, or several comma-separated: one output set each in --out/<scenario>/ "
        "(default nominal)",
    )
    p.add_argument(
        "--policies",
        default="constant,fis,sage_husa,ding,tuned_constant,oracle",
        help=f"comma-separated policy names of: {', '.join(POLICIES)}, or ppo:PATH.npz",
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
    _add_html_option(p)
    _add_ray_option(p)
    p.set_defaults(func=cmd_evaluate)


def _add_train(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "train",
        help="train a tuner: PPO, or another learner (needs the rl extra)",
        description="Train stable-baselines3 PPO on a scenario (hyperparameters in "
        "agents/training/hyperparams/ppo.json), or with --learner another learner on the suite "
        "(agents/training/hyperparams/learners.json); keeps the best validated policy as "
        "--out/policy.npz. Run the same command again to finish an interrupted run: PPO resumes "
        "from --out's checkpoint and trains up to --timesteps in all, another learner starts "
        "again; a run that already reached --timesteps says so and trains nothing.",
    )
    p.add_argument(
        "--learner",
        default="ppo",
        choices=LEARNERS,
        help="ppo (default), recurrent_ppo, sac, tqc (sb3-contrib) or cmaes (CMA-ES over a "
        "linear rule); all but ppo train the general tuner on the suite",
    )
    p.add_argument(
        "--scenario",
        help="scenario (default nonstationary; the other learners train on suite only)",
    )
    p.add_argument(
        "--timesteps",
        type=int,
        help="environment steps in all, a resumed run's included (3e6; --quick: 2048)",
    )
    seeds = p.add_mutually_exclusive_group()
    seeds.add_argument("--seed", type=int, default=0, help="training seed (default 0)")
    seeds.add_argument(
        "--seeds",
        metavar="0-4",
        help="one training run per seed (e.g. 0-4 or 0,2,5), each in --out/seed_<k>/ with its "
        "own checkpoint (a rerun finishes the unfinished ones); side by side with --ray; writes "
        "--out/seeds.json",
    )
    p.add_argument("--out", default="results/ppo", help="output folder (default results/ppo)")
    p.add_argument("--quick", action="store_true", help="about a minute (agents/training/quick.py)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument(
        "--hyperparams", help="hyperparameter file (default agents/training/hyperparams/ppo.json)"
    )
    _add_html_option(p)
    _add_ray_option(p)
    p.set_defaults(func=cmd_train)


def _add_tune(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "tune",
        help="search a learner's hyperparameters with Ray Tune (needs the rl and ray extras)",
        description="Random search over a learner's hyperparameters (the --space file) with Ray "
        "Tune and ASHA early stopping: each trial trains the learner, validates on the "
        "validation seeds [50000, 100000) only, and ASHA stops the trials that validate badly. "
        "PPO (the default) trains on --scenario and writes --out/ppo.json (the hyperparameter "
        "file with the best trial's values, for aeromag train --hyperparams); --learner sac, "
        "tqc or recurrent_ppo trains on the suite and writes --out/learners.json (for aeromag "
        "train --learner L --hyperparams). Both write --out/tune.json (every trial). Always "
        "runs on Ray: on this machine's cores, or on a cluster with --ray ADDRESS. Run the "
        "same command again to finish an interrupted search (it starts again from its first "
        "trial); a search already run to its end with the same request says so and runs "
        "nothing.",
    )
    p.add_argument(
        "--learner",
        default="ppo",
        choices=LEARNERS,
        help="ppo (default), recurrent_ppo, sac or tqc (cmaes is not searched); all but ppo "
        "train the general tuner on the suite",
    )
    p.add_argument(
        "--scenario", help="scenario (default nonstationary; the other learners: suite only)"
    )
    p.add_argument(
        "--space",
        help="search space file (default agents/search/spaces/tune_space.json; other learners: "
        "tune_space_learners.json)",
    )
    p.add_argument("--samples", type=int, help="trials (configurations; 16, --quick: 2)")
    p.add_argument(
        "--timesteps",
        type=int,
        help="environment steps per trial (5e5, other learners: their learners.json timesteps; "
        "--quick: 1024, other learners 2048)",
    )
    p.add_argument("--seed", type=int, default=0, help="sampling and training seed (default 0)")
    p.add_argument("--out", default="results/tune", help="output folder (default results/tune)")
    p.add_argument("--quick", action="store_true", help="about a minute (agents/training/quick.py)")
    p.add_argument(
        "--hyperparams",
        help="base hyperparameter file (default agents/training/hyperparams/ppo.json; other "
        "learners: "
        "learners.json)",
    )
    _add_ray_option(p)
    p.set_defaults(func=cmd_tune)


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
    p.add_argument("--quick", action="store_true", help="about a minute (agents/training/quick.py)")
    p.add_argument(
        "--only",
        choices=BENCH_ONLY,
        help="ray: only the Ray figures (needs --ray [ADDRESS]); discover: only the discrepancy "
        "workflow's seconds per flight-hour; ppo: only PPO's figures at 8 and 64 environments "
        "(the speed targets; 5 repeats of a third of a full run's steps each); stream: only "
        "aeromag stream's latency per sample and memory over a 10-hour stream",
    )
    _add_ray_option(p)
    p.set_defaults(func=cmd_bench)


def _add_convert(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "convert",
        help="convert a flight file between HDF5, CSV, Geosoft XYZ and MATLAB .mat",
        description="Read a flight file (format found from its content: HDF5, CSV, Geosoft "
        "XYZ, MAT v5 or v7.3), rename the fields that have an alias to the SGL 2020 names and "
        "write it in the format of the output's suffix (.h5/.hdf5, .csv, .xyz, .mat = MAT v5). "
        "The input is never overwritten; the output is written atomically.",
    )
    p.add_argument("input", help="flight file to read")
    p.add_argument("output", help="file to write (.h5, .hdf5, .csv, .xyz or .mat)")
    p.set_defaults(func=cmd_convert)


def _add_example(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "example",
        help="write a sample survey file, as a contractor delivers it",
        description="Write the sample survey file the guides use: a simulated calibration box "
        "and six survey lines (nominal preset, seed 11) with Geosoft column names, the fluxgate "
        "mounted as an axis swap, a 30 s logger gap, one 1e6 nT spike in the scalar, three "
        "missing pitch samples and the vendor's compensated channel COMPMAG1 (no real survey "
        "file may be shipped). The output's suffix picks the format; written atomically.",
    )
    p.add_argument("output", help="file to write (.xyz as delivered, or .h5, .csv, .mat)")
    p.set_defaults(func=cmd_example)


def build_parser() -> argparse.ArgumentParser:
    """The full ``aeromag`` parser.

    Returns
    -------
    argparse.ArgumentParser
        Subcommands in ``--help`` order; each sets ``func`` (its handler) and ``command``; bad
        arguments exit with status 2 and a one-line message.
    """
    parser = _Parser(
        prog="aeromag",
        description="Aircraft aeromagnetic compensation toolkit.",
        epilog=EXIT_STATUS,
    )
    sub = parser.add_subparsers(
        dest="command", required=True, metavar="COMMAND", parser_class=_Parser
    )
    adders = (
        _add_simulate,
        _add_info,
        _add_calibrate,
        _add_compensate,
        _add_stream,
        _add_reproduce,
        _add_evaluate,
        _add_train,
        _add_tune,
        _add_discover,
        _add_demo,
        _add_convert,
        _add_example,
        _add_bench,
    )
    for add in adders:
        add(sub)
    for command in sub.choices.values():
        command.epilog = EXIT_STATUS
    return parser
