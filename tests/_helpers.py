"""Helpers the tests share: the one-line-error check, the shipped artefacts, the experiment
scripts (run as scripts: the tests never import ``experiments``)."""

from __future__ import annotations

import re
import runpy
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


def run_cli(argv: list[str]) -> int:
    """``aeromag ARGV`` in this process: its exit status (argparse's errors exit through
    ``SystemExit``)."""
    from aeromag_env.cli.main import main

    try:
        return main(argv)
    except SystemExit as e:
        return int(e.code or 0)
