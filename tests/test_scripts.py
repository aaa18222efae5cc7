"""Every script of ``experiments/`` and ``benchmarks/``, as a user runs it from another folder:
``--help`` prints its usage and exits 0, writing nothing; it runs this checkout's packages (not
an installed copy); its default output folders are git-ignored ones under ``results/``, never
committed files.

The scripts run with ``--help`` in one fresh interpreter started in an empty folder, without
``PYTHONPATH`` (so only a script's own way to its checkout finds the packages), each by its path
as ``python PATH --help`` runs it; every argument parser a script builds is recorded on the way
(its options' defaults)."""

from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from tests._helpers import BENCHMARKS, EXPERIMENTS, ROOT

SCRIPTS = sorted(
    p
    for folder in (EXPERIMENTS, BENCHMARKS)
    for p in folder.glob("*.py")
    if p.name != "__init__.py"
)
#: The options that name where a script writes.
OUTPUT_OPTIONS = ("out", "data", "to", "runs")
#: The packages a script finds through its checkout.
CHECKOUT_PACKAGES = ("aeromag_env", "agents", "tests", "experiments")

#: Runs each script given on its command line with ``--help``, recording each parser's option
#: defaults (subcommands' too) as parsing starts; prints, as JSON, per script its exit status and
#: output, and where ``aeromag_env`` and ``agents`` were imported from.
DRIVER = r"""
import argparse, contextlib, io, json, runpy, sys

parse = argparse.ArgumentParser.parse_known_args
seen = {}


def defaults(parser):
    out = {}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                out[name] = defaults(sub)
        elif action.dest != "help":
            value = action.default
            plain = isinstance(value, (str, int, float, type(None)))
            out[action.dest] = value if plain else str(value)
    return out


def recording(self, args=None, namespace=None):
    seen.setdefault("parser", defaults(self))
    return parse(self, args, namespace)


argparse.ArgumentParser.parse_known_args = recording
report = {}
for path in sys.argv[1:]:
    seen.clear()
    sys.argv = [path, "--help"]
    text = io.StringIO()
    try:
        with contextlib.redirect_stdout(text):
            runpy.run_path(path, run_name="__main__")
        status = "returned without exiting"
    except SystemExit as e:
        status = e.code
    report[path] = {"exit": status, "stdout": text.getvalue(), "defaults": seen.get("parser")}
modules = {name: sys.modules[name].__file__ for name in ("aeromag_env", "agents")}
print(json.dumps({"scripts": report, "modules": modules}))
"""


@pytest.fixture(scope="module")
def helps(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """The driver's report, and the folder it ran in (which must stay empty)."""
    cwd = tmp_path_factory.mktemp("elsewhere")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    run = subprocess.run(
        [sys.executable, "-c", DRIVER, *map(str, SCRIPTS)],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert run.returncode == 0, run.stderr[-3000:]
    return {**json.loads(run.stdout.splitlines()[-1]), "cwd": cwd}


def _name(path: Path) -> str:
    return f"{path.parent.name}/{path.name}"


@pytest.mark.parametrize("script", SCRIPTS, ids=_name)
def test_help_prints_the_usage_and_exits_0(helps: dict[str, Any], script: Path) -> None:
    done = helps["scripts"][str(script)]
    assert done["exit"] in (0, None), done
    assert done["stdout"].startswith(f"usage: {script.name}"), done["stdout"][:200]


def test_help_from_another_folder_runs_this_checkout_and_writes_nothing(
    helps: dict[str, Any],
) -> None:
    for name, file in helps["modules"].items():
        assert ROOT in Path(file).parents, f"{name} came from {file}, not from {ROOT}"
    assert not any(helps["cwd"].iterdir())


def _outputs(defaults: dict[str, Any], where: str) -> list[tuple[str, str]]:
    """``(option, default)`` of every output option with a default, subcommands' included."""
    found = []
    for dest, value in defaults.items():
        if isinstance(value, dict):
            found += _outputs(value, f"{where} {dest}")
        elif dest in OUTPUT_OPTIONS and value is not None:
            found.append((f"{where} --{dest}", str(value)))
    return found


def test_no_default_output_is_committed(helps: dict[str, Any]) -> None:
    """Every default output folder or file is under ``results/``, which git ignores."""
    outputs = [
        item
        for path, done in helps["scripts"].items()
        for item in _outputs(done["defaults"] or {}, _name(Path(path)))
    ]
    assert len(outputs) >= 10, outputs  # the scripts that write do say where
    assert [o for o in outputs if Path(o[1]).parts[0] != "results"] == []
    ignored = subprocess.run(
        ["git", "check-ignore", "--no-index", *(value for _, value in outputs)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=False,
    )
    assert sorted(ignored.stdout.split()) == sorted(value for _, value in outputs)


def _checkout_first(tree: ast.Module) -> str | None:
    """What is wrong with a script's way to its checkout: a top-level import of the checkout's
    packages before the block that, run by its path, puts the checkout first on ``sys.path``."""
    for node in tree.body:
        if isinstance(node, ast.If) and "__package__" in ast.unparse(node.test):
            if "sys.path.insert(0" not in ast.unparse(node):
                return "the __package__ block does not put the checkout first"
            return None
        names = [a.name for a in node.names] if isinstance(node, ast.Import) else []
        if isinstance(node, ast.ImportFrom) and node.module:
            names = [node.module]
        if any(n.split(".")[0] in CHECKOUT_PACKAGES for n in names):
            return f"line {node.lineno} imports the checkout's packages before the block"
    return None


@pytest.mark.parametrize("script", SCRIPTS, ids=_name)
def test_a_script_run_by_its_path_puts_its_checkout_first(script: Path) -> None:
    """Without it a script run from another folder imports an installed copy of the packages
    (silently another version) or fails on ``experiments`` and ``tests``."""
    assert _checkout_first(ast.parse(script.read_text(encoding="utf-8"))) is None


def test_as_a_module_from_the_checkout() -> None:
    """``python -m experiments.NAME`` from the checkout's root, as the results files record."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    run = subprocess.run(
        [sys.executable, "-m", "experiments.same_verdicts", "--help"],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        check=False,
    )
    assert run.returncode == 0 and "usage:" in run.stdout and "old new" in run.stdout, run
