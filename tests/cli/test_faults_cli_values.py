"""Fault injection, part of issue 20: command-line values, CSV cells and hyperparameter sizes
that crashed, ran away or were silently lost now give one line and a documented exit status.

The convention (:func:`aeromag_env.cli.main.main`): 0 done, 2 bad input with one line
``aeromag CMD: error: ...`` on stderr, 1 an internal error with one line ``aeromag CMD: internal
error: ...`` (``AEROMAG_DEBUG=1`` raises it). Every case runs ``main`` in-process on small
simulated flights.
"""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path

import numpy as np
import pytest

from aeromag_env.cli.main import main
from aeromag_env.compensation.compensate import FILTER_METHODS, MIN_VECTOR_SAMPLES
from aeromag_env.errors import FlightFileError, HyperparameterError
from aeromag_env.flight.files import load_flight, write_flight
from aeromag_env.jobs import limits
from aeromag_env.jobs import simulate as simulate_job
from aeromag_env.simulation.config import preset, with_overrides
from agents.training.ppo import HYPERPARAMS, load_hyperparams
from tests._flights import simulated
from tests._helpers import assert_one_line_error

DEBUG_HINT = "(a bug: please report it with the command line; AEROMAG_DEBUG=1 shows the traceback)"


@pytest.fixture(scope="module")
def flight_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 120-s nominal flight (1200 samples at 10 Hz) with a fluxgate and a scalar."""
    folder = tmp_path_factory.mktemp("flight")
    return write_flight(simulated(trajectory__duration_s=120.0), folder / "f.h5")


def _run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    try:
        code = main(argv)
    except SystemExit as e:  # argparse's own errors
        code = int(e.code or 0)
    out, err = capsys.readouterr()
    return code, out, err


def _refused(argv: list[str], capsys: pytest.CaptureFixture[str], *words: str) -> str:
    """Exit 2 with one line ``aeromag CMD: error: ...`` holding every one of ``words`` (after
    the warnings, if any, one line each)."""
    code, _, err = _run(argv, capsys)
    *warnings, error = err.splitlines()
    assert code == 2 and "Traceback" not in err, err
    assert error.startswith(f"aeromag {argv[0]}: error: "), err
    assert all(": warning: " in line for line in warnings), err
    assert all(word in error for word in words), err
    return error


# 1. one exit-status convention


@pytest.mark.parametrize(
    ("exc", "shown"),
    [
        (ZeroDivisionError("float division by zero"), "ZeroDivisionError: float division by zero"),
        (ValueError("first line\nsecond line"), "ValueError: first line"),
        (RuntimeError(), "RuntimeError"),
    ],
)
def test_an_internal_error_is_one_line_and_exit_1(flight_file, capsys, monkeypatch, exc, shown):
    def broken(*args: object, **kwargs: object) -> int:
        raise exc

    monkeypatch.setattr("aeromag_env.jobs.info.describe", broken)
    monkeypatch.delenv("AEROMAG_DEBUG", raising=False)
    code, out, err = _run(["info", str(flight_file)], capsys)
    assert code == 1 and out == ""
    assert err == f"aeromag info: internal error: {shown} {DEBUG_HINT}\n"
    monkeypatch.setenv("AEROMAG_DEBUG", "1")
    with pytest.raises(type(exc)):
        main(["info", str(flight_file)])


@pytest.mark.parametrize("argv", [["--help"], ["compensate", "--help"], ["train", "--help"]])
def test_help_states_the_exit_statuses(capsys, argv):
    code, out, _ = _run(argv, capsys)
    text = " ".join(out.split())  # argparse wraps the epilog
    assert code == 0
    assert "exit status: 0 done; 2 bad input" in text and "1 internal error" in text
    assert "AEROMAG_DEBUG=1" in text and "130 interrupted" in text


# 2. aeromag info: errors on stderr, reports on stdout


def test_info_errors_go_to_stderr(tmp_path, capsys):
    missing = tmp_path / "missing.h5"
    code, out, err = _run(["info", str(missing)], capsys)
    assert (code, out, err) == (2, "", f"aeromag info: error: {missing}: file not found\n")
    code, out, err = _run(["info", str(missing), "--json"], capsys)
    assert code == 2 and json.loads(out)["usable"] is False  # the JSON stays on stdout
    assert err == f"aeromag info: error: {missing}: file not found\n"


# 3. values that crashed or ran away


@pytest.mark.parametrize("value", ["0.05", "0.1", "0", "-5", "nan", "inf", "-inf", "1e9", "1e300"])
def test_simulate_duration_out_of_range(tmp_path, capsys, value):
    out = tmp_path / "x.h5"
    _refused(
        ["simulate", f"--duration-s={value}", "--out", str(out), "--quiet"],
        capsys,
        "--duration-s must be > 0",
        "0.2 to 1e+07 s at 10 Hz",
    )
    assert not out.exists()


def test_simulate_shortest_duration_gives_two_samples(tmp_path, capsys):
    out = tmp_path / "x.h5"
    code, _, err = _run(["simulate", "--duration-s", "0.2", "--out", str(out), "--quiet"], capsys)
    assert code == 0, err
    assert load_flight(out)[0].n == 2


def test_simulate_refuses_a_flight_larger_than_the_memory(tmp_path, capsys, monkeypatch):
    available = 10**6  # [bytes]
    monkeypatch.setattr(simulate_job, "available_memory_bytes", lambda: available)
    per_sample = limits.BYTES_PER_VALUE * len(simulated(trajectory__duration_s=1.0).names)
    largest = available // per_sample / 10.0  # [s] at 10 Hz
    out = tmp_path / "x.h5"
    argv = ["simulate", "--duration-s", "120", "--out", str(out), "--quiet"]
    words = ("--duration-s 120 s needs about", f"the largest duration here is {largest:.0f} s")
    _refused(argv, capsys, *words)
    assert not out.exists()
    fits = with_overrides(preset("nominal"), {"trajectory.duration_s": math.floor(largest)})
    simulate_job.check_memory(fits, replay=False)  # what the message offers is accepted


@pytest.mark.parametrize("value", ["1e-300", "0", "-1", "nan", "inf", "-inf", "1e300", "2e5"])
def test_compensate_r_std_out_of_range(flight_file, tmp_path, capsys, value):
    argv = [
        "compensate",
        str(flight_file),
        "--method",
        "kf",
        "--out",
        str(tmp_path / "o"),
        f"--r-std-nt={value}",
    ]
    _refused(argv, capsys, "--r-std-nt must be in [0.001, 100000] nT")
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("value", ["1e-3", "1e5"])
def test_compensate_r_std_at_the_bounds_runs(flight_file, tmp_path, capsys, value):
    argv = [
        "compensate",
        str(flight_file),
        "--method",
        "kf",
        "--out",
        str(tmp_path / "o"),
        "--r-std-nt",
        value,
    ]
    assert _run(argv, capsys)[0] == 0


@pytest.mark.parametrize(
    ("extra", "words"),
    [
        (["--method", "kf", "--flux", "flux_z"], ("--flux flux_z", "fluxgates present: flux_a")),
        (["--method", "tl", "--scalar", "mag_9_uc"], ("--scalar mag_9_uc", "present: mag_1_uc")),
        (["--method", "tl", "--tl-bandpass", "0.1", "7"], ("--tl-bandpass", "≤ 5 Hz", "Nyquist")),
        (["--method", "tl", "--tl-bandpass", "0", "7"], ("--tl-bandpass", "≤ 5 Hz", "Nyquist")),
        (["--method", "tl", "--tl-bandpass", "6", "7"], ("--tl-bandpass", "≤ 5 Hz", "Nyquist")),
        (["--method", "tl", "--tl-trim", "100000"], ("trim 100000", "--tl-trim ≤ 590 would fit")),
        (["--method", "tl", "--tl-ridge", "nan"], ("--tl-ridge must be ≥ 0 and finite",)),
        (["--method", "tl", "--tl-ridge", "inf"], ("--tl-ridge must be ≥ 0 and finite",)),
        (["--method", "kf", "--calibration-window", "nan", "50"], ("finite times T0 < T1 [s]",)),
        (["--method", "kf", "--calibration-window", "0", "inf"], ("finite times T0 < T1 [s]",)),
    ],
)
def test_compensate_bad_values(flight_file, tmp_path, capsys, extra, words):
    _refused(["compensate", str(flight_file), "--out", str(tmp_path / "o"), *extra], capsys, *words)
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("extra", [["--tl-bandpass", "0.1", "5"], ["--tl-trim", "590"]])
def test_compensate_tl_at_the_limits_runs(flight_file, tmp_path, capsys, extra):
    """HIGH = fs/2 is MagNav's high-pass; the trim the message offers fits."""
    argv = ["compensate", str(flight_file), "--method", "tl", "--out", str(tmp_path / "o"), *extra]
    code, _, err = _run(argv, capsys)
    assert code == 0, err


def test_discover_calibration_window_nan(flight_file, tmp_path, capsys):
    argv = [
        "discover",
        str(flight_file),
        "--out",
        str(tmp_path / "d"),
        "--quiet",
        "--calibration-window",
        "nan",
        "60",
    ]
    _refused(argv, capsys, "--calibration-window needs finite times T0 < T1 [s]")


@pytest.mark.parametrize("method", [*FILTER_METHODS, "lsq", "tl"])
def test_a_flight_too_short_for_the_method_is_refused(tmp_path, capsys, method):
    path = write_flight(simulated(trajectory__duration_s=0.5), tmp_path / "five.h5")
    need = "at least 59 samples" if method == "tl" else f"at least {MIN_VECTOR_SAMPLES} samples"
    _refused(
        ["compensate", str(path), "--method", method, "--out", str(tmp_path / "o")],
        capsys,
        need,
        "this one has 5",
    )


def test_the_shortest_flight_a_filter_accepts_runs(tmp_path, capsys):
    path = write_flight(simulated(trajectory__duration_s=2.8), tmp_path / "short.h5")
    code, _, err = _run(
        ["compensate", str(path), "--method", "kf", "--out", str(tmp_path / "o")], capsys
    )
    assert code == 0, err


@pytest.mark.parametrize(
    "argv",
    [
        ["simulate", "--out", "x.h5", "--quiet", "--seed", "-5"],
        ["simulate", "--out", "x.h5", "--quiet", "--seed", str(2**32)],
        ["demo", "--out", "out", "--seed", "-5"],
        ["reproduce-paper", "--out", "out", "--quick", "--seed", "-5"],
        ["train", "--out", "out", "--quick", "--quiet", "--seed", "-5"],
        ["train", "--out", "out", "--quick", "--quiet", "--seed", str(2**32)],
    ],
)
def test_seeds_out_of_range(tmp_path, capsys, monkeypatch, argv):
    monkeypatch.chdir(tmp_path)
    _refused(argv, capsys, "--seed must be ≥ 0 and ≤ 4294967295")
    assert list(tmp_path.iterdir()) == []


EPISODES = "--episodes must be in [1, 10000] flights"
SEED_START = "--seed-start must be in [100000, 4294967276]"  # with the default 20 episodes


@pytest.mark.parametrize(
    ("option", "value", "words"),
    [
        ("--episodes", "0", EPISODES),
        ("--episodes", "-3", EPISODES),
        ("--episodes", "10001", EPISODES),
        ("--episodes", str(10**12), EPISODES),
        ("--seed-start", "-5", SEED_START),
        ("--seed-start", "5", SEED_START),
        ("--seed-start", str(2**32), SEED_START),
    ],
)
def test_evaluate_episodes_and_seeds_out_of_range(tmp_path, capsys, option, value, words):
    argv = ["evaluate", "--out", str(tmp_path / "e"), "--quiet", f"{option}={value}"]
    _refused(argv, capsys, words)
    assert not (tmp_path / "e").exists()


@pytest.mark.parametrize("value", ["0", "-1", str(10**9 + 1), str(10**11)])
def test_train_timesteps_out_of_range(tmp_path, capsys, value):
    out = tmp_path / "t"
    _refused(
        ["train", "--out", str(out), "--quick", "--quiet", "--timesteps", value],
        capsys,
        "--timesteps must be in [1, 1e+09] environment steps",
        "days of CPU time",
    )
    assert not out.exists()


# 4. CSV cells that are not numbers


def _csv_with(tmp_path: Path, name: str, column: str, cells: dict[int, str]) -> tuple[Path, int]:
    """A 60-sample CSV flight with ``cells`` (row index → text) written into ``column``; the
    path and the file line number of data row 0."""
    path = write_flight(simulated(trajectory__duration_s=6.0), tmp_path / name)
    lines = path.read_text(encoding="utf-8").splitlines()
    first = int(lines[0].startswith("#@"))  # index of the header line
    j = lines[first].split(",").index(column)
    for row, text in cells.items():
        values = lines[first + 1 + row].split(",")
        values[j] = text
        lines[first + 1 + row] = ",".join(values)
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path, first + 2


def test_csv_one_unreadable_cell_is_missing_with_a_warning(tmp_path, capsys):
    path, line0 = _csv_with(tmp_path, "one.csv", "mag_1_uc", {7: "abc"})
    flight, problems = load_flight(path)
    truth = simulated(trajectory__duration_s=6.0)["mag_1_uc"]
    assert np.isnan(flight["mag_1_uc"][7])
    np.testing.assert_array_equal(np.delete(flight["mag_1_uc"], 7), np.delete(truth, 7))
    note = f"column mag_1_uc: 1 cell is not a number, read as missing (NaN): line {line0 + 7} 'abc'"
    assert note in problems
    code, out, _ = _run(["info", str(path)], capsys)
    assert code == 0 and note in out


def test_csv_many_unreadable_cells_are_counted(tmp_path):
    path, line0 = _csv_with(tmp_path, "many.csv", "flux_a_x", {i: f"x{i}" for i in range(2, 22)})
    flight, problems = load_flight(path)
    assert np.isnan(flight["flux_a_x"][2:22]).all() and np.isfinite(flight["flux_a_x"][22:]).all()
    [note] = [p for p in problems if p.startswith("column flux_a_x")]
    assert note.startswith("column flux_a_x: 20 cells are not numbers, read as missing (NaN): ")
    assert f"line {line0 + 2} 'x2'" in note and note.endswith("(first 3 shown)")


def test_csv_column_mostly_text_is_refused(tmp_path):
    path, _ = _csv_with(tmp_path, "most.csv", "mag_1_uc", {i: "n/a" for i in range(3, 60)})
    with pytest.raises(FlightFileError, match="column mag_1_uc is not numeric: 57 of its 60"):
        load_flight(path)


def test_csv_text_only_column_is_still_skipped(tmp_path):
    path, _ = _csv_with(tmp_path, "label.csv", "line", {i: "box" for i in range(60)})
    flight, problems = load_flight(path)
    assert "line" not in flight and "skipped column(s): line" in problems


# 5. hyperparameter files of absurd sizes


def _hp_file(tmp_path: Path, change: dict[str, object], pretrain: bool = False) -> Path:
    doc = json.loads(HYPERPARAMS.read_text(encoding="utf-8"))
    hp = doc["scenarios"]["nonstationary"]
    (hp["pretrain"] if pretrain else hp).update(copy.deepcopy(change))
    path = tmp_path / "hp.json"
    path.write_text(json.dumps(doc), encoding="utf-8")
    return path


@pytest.mark.parametrize(
    ("change", "pretrain", "words"),
    [
        ({"n_envs": 100_000}, False, "n_envs must be an integer ≥ 1 and ≤ 256"),
        ({"n_steps": 10**9}, False, "n_steps must be an integer ≥ 1 and ≤ 16384"),
        ({"batch_size": 10**7}, False, "batch_size must be an integer ≥ 2 and ≤ 65536"),
        ({"n_epochs": 10**6}, False, "n_epochs must be an integer ≥ 1 and ≤ 100"),
        ({"net_arch": [10**6]}, False, "net_arch.0 must be an integer ≥ 1 and ≤ 1024"),
        ({"net_arch": [64] * 100}, False, "net_arch must be a list of at most 8 integers"),
        ({"eval_every": 10**12}, False, "eval_every must be an integer ≥ 1 and ≤ 1000000000"),
        ({"eval_episodes": 10**9}, False, "eval_episodes must be an integer ≥ 1 and ≤ 10000"),
        ({"steps": 10**12}, True, "pretrain.steps must be an integer ≥ 1 and ≤ 10000000"),
        ({"epochs": 10**6}, True, "pretrain.epochs must be an integer ≥ 1 and ≤ 100"),
    ],
)
def test_hyperparameters_of_absurd_size_are_refused(tmp_path, change, pretrain, words):
    path = _hp_file(tmp_path, change, pretrain)
    with pytest.raises(HyperparameterError) as info:
        load_hyperparams("nonstationary", path)
    assert_one_line_error(info, str(path), words)


def test_hyperparameters_at_the_upper_bounds_are_accepted(tmp_path):
    change = {
        "n_envs": 256,
        "n_steps": 16384,
        "batch_size": 65536,
        "n_epochs": 100,
        "net_arch": [1024] * 8,
        "eval_every": 10**9,
        "eval_episodes": 10_000,
    }
    hp = load_hyperparams("nonstationary", _hp_file(tmp_path, change))
    assert {k: hp.to_entry()[k] for k in change} == change


# 6. found by the fault-injection suite (experiments/fault_suite.py)


def test_replay_prints_the_readers_warnings_and_refuses_non_finite_positions(
    flight_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``simulate --replay`` dropped the reader's warnings and crashed on a NaN latitude."""
    flight, _ = load_flight(flight_file)
    noisy = {**flight.fields, "flux_a_x": flight["flux_a_x"].copy()}
    noisy["flux_a_x"][100:150] = np.nan
    path = write_flight(type(flight)(noisy, dict(flight.attrs)), tmp_path / "nan_flux.h5")
    code, _, err = _run(
        ["simulate", "--replay", str(path), "--quiet", "--out", str(tmp_path / "sim.h5")], capsys
    )
    assert code == 0 and "aeromag simulate: warning:" in err and "flux_a_x" in err, err
    holed = {**flight.fields, "lat": flight["lat"].copy()}
    holed["lat"][10:20] = np.nan
    path = write_flight(type(flight)(holed, dict(flight.attrs)), tmp_path / "nan_lat.h5")
    _refused(
        ["simulate", "--replay", str(path), "--out", str(tmp_path / "sim2.h5")],
        capsys,
        "cannot replay",
        "lat has 10 non-finite",
    )
    assert not (tmp_path / "sim2.h5").exists()


def test_a_configuration_that_is_not_text_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = tmp_path / "config.json"
    config.write_bytes(np.random.default_rng(0).bytes(256))
    _refused(
        ["simulate", "--config", str(config), "--out", str(tmp_path / "s.h5")], capsys, "not UTF-8"
    )


@pytest.mark.parametrize(
    "command",
    [
        ["compensate", "FILE", "--method", "lsq"],
        ["demo"],
        ["evaluate"],
        ["bench"],
        ["reproduce-paper"],
    ],
)
def test_an_empty_out_is_refused_not_the_current_folder(
    command: list[str],
    flight_file: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.chdir(tmp_path)
    argv = [str(flight_file) if a == "FILE" else a for a in command]
    _refused([*argv, "--out", ""], capsys, "--out is empty")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_one_episode_gives_strict_json_and_says_why_there_is_no_interval(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, _ = _run(
        [
            "evaluate",
            "--episodes",
            "1",
            "--policies",
            "constant,fis",
            "--quiet",
            "--out",
            str(tmp_path),
        ],
        capsys,
    )
    assert code == 0 and "[n/a]" in out and "nan" not in out.lower()
    text = (tmp_path / "results.json").read_text()
    json.loads(text, parse_constant=lambda c: pytest.fail(f"{c} in results.json"))


def test_info_on_a_segment_holding_the_whole_flight(
    flight_file: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, err = _run(["info", str(flight_file), "--segment=0:1e300"], capsys)
    assert code == 0 and "every sample" in out, err


def test_a_band_edge_too_low_to_design_is_refused(
    flight_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _refused(
        [
            "compensate",
            str(flight_file),
            "--method",
            "tl",
            "--tl-bandpass",
            "1e-300",
            "0.9",
            "--out",
            str(tmp_path),
        ],
        capsys,
        "band edge 1e-300 Hz",
    )
