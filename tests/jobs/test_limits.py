"""Every numeric option of every command has its range in the library: a value outside it is an
:class:`~aeromag_env.errors.ArgumentError` from the job's function, naming the argument as the
library spells it, and exit 2 with one line naming the option on the command line."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from aeromag_env.cli.main import main
from aeromag_env.cli.parser import build_parser
from aeromag_env.errors import ArgumentError
from aeromag_env.jobs.calibrate import calibrate
from aeromag_env.jobs.compensate import compensate
from aeromag_env.jobs.demo import demo
from aeromag_env.jobs.discover import discover
from aeromag_env.jobs.evaluate import evaluate
from aeromag_env.jobs.info import info
from aeromag_env.jobs.reproduce import reproduce
from aeromag_env.jobs.simulate import simulate
from aeromag_env.jobs.train import train
from aeromag_env.jobs.tune import tune

#: Options whose text carries numbers although argparse reads it as text.
NUMBERS_AS_TEXT = {"--line", "--segment", "--seeds", "--calibration-line", "--tl-bandpass"}
FILE = "flight.h5"  # never read: every range is checked before the file
NAN = math.nan

#: (command, option) → (the values on the command line, the library argument it gives, the job
#: called with that argument out of its range, in a scratch folder).
Case = tuple[list[str], str, Callable[[Path], Any]]
CASES: dict[tuple[str, str], Case] = {
    ("simulate", "--seed"): (["-1"], "seed", lambda d: simulate(d / "x.h5", seed=-1)),
    ("simulate", "--duration-s"): (
        ["0"],
        "duration_s",
        lambda d: simulate(d / "x.h5", duration_s=0.0),
    ),
    ("simulate", "--aircraft"): (["-1"], "aircraft", lambda d: simulate(d / "x.h5", aircraft=-1)),
    ("simulate", "--permanent-shift-nt"): (
        ["nan", "0", "0"],
        "permanent_shift_nt",
        lambda d: simulate(d / "x.h5", aircraft=1, permanent_shift_nt=(NAN, 0.0, 0.0)),
    ),
    ("simulate", "--scalar-permanent-shift-nt"): (
        ["0", "1e6", "0"],
        "scalar_permanent_shift_nt",
        lambda d: simulate(d / "x.h5", aircraft=1, scalar_permanent_shift_nt=(0.0, 1e6, 0.0)),
    ),
    ("info", "--line"): (["nan"], "lines", lambda d: info(FILE, lines=(NAN,))),
    ("info", "--segment"): (["9:3"], "segment_s", lambda d: info(FILE, segment_s=(9.0, 3.0))),
    ("compensate", "--tl-bandpass"): (
        ["0.9", "0.1"],
        "tl_bandpass_hz",
        lambda d: compensate(FILE, "tl", tl_bandpass_hz=(0.9, 0.1)),
    ),
    ("compensate", "--tl-trim"): (["-1"], "tl_trim", lambda d: compensate(FILE, "tl", tl_trim=-1)),
    ("compensate", "--tl-ridge"): (
        ["-1"],
        "tl_ridge",
        lambda d: compensate(FILE, "tl", tl_ridge=-1.0),
    ),
    ("compensate", "--calibration-window"): (
        ["5", "1"],
        "calibration_window_s",
        lambda d: compensate(FILE, "kf", calibration_window_s=(5.0, 1.0)),
    ),
    ("compensate", "--line"): (["nan"], "lines", lambda d: compensate(FILE, "kf", lines=(NAN,))),
    ("compensate", "--segment"): (
        ["0:inf"],
        "segment_s",
        lambda d: compensate(FILE, "kf", segment_s=(0.0, math.inf)),
    ),
    ("compensate", "--calibration-line"): (
        ["nan"],
        "calibration_line",
        lambda d: compensate(FILE, "kf", calibration_line="nan"),
    ),
    ("compensate", "--r-std-nt"): (
        ["1e-300"],
        "r_std_nt",
        lambda d: compensate(FILE, "kf", r_std_nt=1e-300),
    ),
    ("calibrate", "--tl-bandpass"): (
        ["0.9", "0.1"],
        "tl_bandpass_hz",
        lambda d: calibrate(FILE, "tl", tl_bandpass_hz=(0.9, 0.1)),
    ),
    ("calibrate", "--tl-trim"): (["-1"], "tl_trim", lambda d: calibrate(FILE, "tl", tl_trim=-1)),
    ("calibrate", "--tl-ridge"): (
        ["-1"],
        "tl_ridge",
        lambda d: calibrate(FILE, "tl", tl_ridge=-1.0),
    ),
    ("calibrate", "--calibration-window"): (
        ["5", "1"],
        "calibration_window_s",
        lambda d: calibrate(FILE, "kf", calibration_window_s=(5.0, 1.0)),
    ),
    ("calibrate", "--calibration-line"): (
        ["nan"],
        "calibration_line",
        lambda d: calibrate(FILE, "kf", calibration_line="nan"),
    ),
    ("calibrate", "--r-std-nt"): (
        ["1e6"],
        "r_std_nt",
        lambda d: calibrate(FILE, "kf", r_std_nt=1e6),
    ),
    ("reproduce-paper", "--seed"): (["-1"], "seed", lambda d: reproduce(d / "p", seed=-1)),
    ("evaluate", "--episodes"): (
        ["0"],
        "episodes",
        lambda d: evaluate("nominal", ["fis"], episodes=0),
    ),
    ("evaluate", "--seed-start"): (
        ["5"],
        "seed_start",
        lambda d: evaluate("nominal", ["fis"], seed_start=5),
    ),
    ("train", "--timesteps"): (["0"], "timesteps", lambda d: train(d / "t", timesteps=0)),
    ("train", "--seed"): (["-1"], "seed", lambda d: train(d / "t", seed=-1)),
    ("train", "--seeds"): (["4294967296"], "seeds", lambda d: train(d / "t", seeds=[2**32])),
    ("tune", "--samples"): (["0"], "samples", lambda d: tune(d / "t", samples=0)),
    ("tune", "--timesteps"): (["0"], "timesteps", lambda d: tune(d / "t", timesteps=0)),
    ("tune", "--seed"): (["-1"], "seed", lambda d: tune(d / "t", seed=-1)),
    ("discover", "--calibration-window"): (
        ["nan", "50"],
        "calibration_window_s",
        lambda d: discover(FILE, calibration_window_s=(NAN, 50.0)),
    ),
    ("discover", "--line"): (["nan"], "lines", lambda d: discover(FILE, lines=(NAN,))),
    ("discover", "--segment"): (
        ["9:3"],
        "segment_s",
        lambda d: discover(FILE, segment_s=(9.0, 3.0)),
    ),
    ("discover", "--calibration-line"): (
        ["inf"],
        "calibration_line",
        lambda d: discover(FILE, calibration_line="inf"),
    ),
    ("demo", "--seed"): (["-1"], "seed", lambda d: demo(d / "demo", seed=-1)),
}


def _numeric_options() -> set[tuple[str, str]]:
    """Every (command, option) of the parser that takes numbers."""
    commands = build_parser()._subparsers._group_actions[0].choices  # type: ignore[union-attr]
    found = set()
    for command, parser in commands.items():
        for action in parser._actions:
            for option in action.option_strings:
                if action.type in (int, float) or option in NUMBERS_AS_TEXT:
                    found.add((command, option))
    return found


def test_every_numeric_option_has_a_range_case() -> None:
    assert set(CASES) == _numeric_options()


@pytest.mark.parametrize("key", sorted(CASES), ids=lambda k: " ".join(k))
def test_a_value_out_of_range_is_refused_by_the_library_and_the_command_line(
    key: tuple[str, str], tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch
) -> None:
    command, option = key
    values, argument, call = CASES[key]
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ArgumentError) as raised:
        call(tmp_path)
    assert raised.value.argument == argument
    assert str(raised.value).startswith(f"{argument} ") and "--" not in str(raised.value)
    argv = [
        command,
        *([FILE] if command in ("info", "compensate", "calibrate", "discover") else []),
    ]
    argv += ["--out", str(tmp_path / "cli")] if command != "info" else []
    argv += ["--method", "kf"] if command in ("compensate", "calibrate") else []
    argv += ["--quiet"] if command in ("simulate", "train", "evaluate", "discover") else []
    argv += [f"{option}={values[0]}"] if len(values) == 1 else [option, *values]
    if command == "simulate":
        argv[argv.index("--out") + 1] = str(tmp_path / "cli.h5")
    assert main(argv) == 2
    _out, err = capsys.readouterr()
    assert err.count("\n") == 1 and err.startswith(f"aeromag {command}: error: {option} "), err
    assert not (tmp_path / "cli").exists() and not (tmp_path / "cli.h5").exists()
