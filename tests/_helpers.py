"""Helpers the tests share: the one-line-error check, the shipped artefacts, the experiment
scripts (run as scripts, as their users run them: the tests never import ``experiments``), the
property tests' budget."""

from __future__ import annotations

import os
import re
import runpy
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pytest

#: the repository
ROOT = Path(__file__).resolve().parents[1]
#: the files the repository ships that tests read or copy
SHIPPED = {
    "policy": ROOT / "agents" / "policies" / "trained" / "ppo_nonstationary.npz",
    "hyperparams": ROOT / "agents" / "training" / "hyperparams" / "ppo.json",
}
EXPERIMENTS = ROOT / "experiments"
BENCHMARKS = ROOT / "benchmarks"

#: The environment variable naming the hypothesis profile of a run (``tests/conftest.py``
#: registers them): :data:`DETERMINISTIC` unless it says :data:`EXPLORE`.
PROFILE_VARIABLE = "HYPOTHESIS_PROFILE"
#: The default run's profile: every property test draws the same examples on every machine.
DETERMINISTIC = "deterministic"
#: The profile of CI's slow step: fresh random examples, :data:`EXPLORE_FACTOR` times as many.
EXPLORE = "explore"
EXPLORE_FACTOR = 4


def hypothesis_profile() -> str:
    """The hypothesis profile this run loads (:data:`PROFILE_VARIABLE`)."""
    return os.environ.get(PROFILE_VARIABLE, DETERMINISTIC)


def examples(n: int, explore: int | None = None) -> int:
    """A property test's ``max_examples``: ``n`` in the default run; under the explore profile
    ``explore``, by default :data:`EXPLORE_FACTOR` times ``n`` (a test's own setting outweighs
    its profile's). A test whose example takes seconds names a smaller ``explore``, so that
    CI's exploring step stays within a few minutes."""
    if hypothesis_profile() != EXPLORE:
        return n
    return EXPLORE_FACTOR * n if explore is None else explore


def assert_one_line_error(
    error: BaseException | pytest.ExceptionInfo[Any],
    *words: str,
    patterns: Sequence[str] = (),
) -> str:
    """The message of ``error`` (an exception or what ``pytest.raises`` caught), asserted to be
    one line holding every one of ``words`` (as text) and matching every one of ``patterns``
    (regular expressions, :func:`re.search`)."""
    message = str(error.value if isinstance(error, pytest.ExceptionInfo) else error)
    assert "\n" not in message, message
    for word in words:
        assert word in message, f"{word!r} not in {message!r}"
    for pattern in patterns:
        assert re.search(pattern, message), f"{pattern!r} does not match {message!r}"
    return message


def experiment(name: str) -> dict[str, Any]:
    """The names ``experiments/<name>.py`` defines, the script run under another name than
    ``__main__`` (so its ``main`` does not run): for tests of its functions."""
    return runpy.run_path(str(EXPERIMENTS / f"{name}.py"), run_name=f"experiment_{name}")


def run_experiment(name: str, *argv: str) -> int:
    """``python experiments/<name>.py ARGV`` in this process (pytest's capsys sees its output):
    its exit status."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(sys, "argv", [str(EXPERIMENTS / f"{name}.py"), *argv])
        try:
            runpy.run_path(str(EXPERIMENTS / f"{name}.py"), run_name="__main__")
        except SystemExit as e:
            return e.code if isinstance(e.code, int) else 0 if e.code is None else 1
    return 0


def run_script(name: str, *argv: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    """``python experiments/<name>.py ARGV`` in a fresh interpreter (in ``cwd``, default the
    checkout): for the scripts that start processes of their own, which a fork of the test
    process could deadlock (its threads' locks are copied held)."""
    return subprocess.run(
        [sys.executable, str(EXPERIMENTS / f"{name}.py"), *argv],
        cwd=cwd or ROOT,
        capture_output=True,
        text=True,
        timeout=1800,
        check=False,
    )


def run_cli(argv: list[str]) -> int:
    """``aeromag ARGV`` in this process: its exit status (argparse's errors exit through
    ``SystemExit``)."""
    from aeromag_env.cli.main import main

    try:
        return main(argv)
    except SystemExit as e:
        return int(e.code or 0)


#: The five observations the shipped policies read after the paper's two: the current Q and R
#: scales, the innovation whiteness, the flight's progress, the recent ROR.
SCALE_OBSERVATIONS = ("log_q_scale", "log_r_scale", "whiteness", "progress", "log_recent_ror")


def observations(*more: str) -> tuple[str, ...]:
    """An observation layout: the paper's two, :data:`SCALE_OBSERVATIONS`, then ``more``."""
    return ("log_ror", "log_qoq", *SCALE_OBSERVATIONS, *more)
