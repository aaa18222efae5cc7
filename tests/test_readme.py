"""The code a user copies from the README and the documentation runs.

Every ```python block of ``README.md`` and ``docs/getting-started.md`` runs, in document order,
in one temporary folder (a block may use a file an earlier block wrote), each in a fresh
namespace of one interpreter per document with the checkout on ``PYTHONPATH``, after a prelude
that makes the files a document's examples take as given (block 0). Every ``aeromag``
command in a ```bash block (and every ``$ aeromag`` line of a ```text transcript) of the README
and the pages under ``docs/`` (the lab notebook excepted: it records commands as they were run)
is parsed by the real argument parser, so a subcommand or option that does not exist fails here.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

import aeromag_env
from aeromag_env.cli.parser import build_parser

ROOT = Path(__file__).resolve().parents[1]
#: The documents whose python blocks run, each with what its blocks expect to find: the README's
#: examples compensate "your" flight file, a simulated calibration flight here.
RUN_PYTHON = {
    "README.md": (
        "import aeromag_env\n"
        "flight = aeromag_env.simulate_flight(aeromag_env.preset('nominal'), 7)\n"
        "aeromag_env.write_flight(flight, 'flight.xyz')\n"
    ),
    "docs/getting-started.md": "",
}
#: Pages whose commands are parsed; the lab notebook keeps commands of past versions verbatim.
PARSED = ("README.md", "docs/getting-started.md", "docs/howto", "docs/background", "docs/results")
FENCE = re.compile(r"^```(?P<lang>[\w-]*)[^\n]*\n(?P<body>.*?)^```\s*$", re.M | re.S)
#: Words that end one shell command on a line and start the next (or redirect its output).
SEPARATORS = {"&&", "||", ";", "|", ">", ">>", "2>", "&"}
#: The library door that the one-door work adds; blocks calling it wait for it.
PENDING = {"aeromag_env.compensate(": hasattr(aeromag_env, "compensate")}


def blocks(path: Path, lang: str) -> list[str]:
    """The bodies of the fenced code blocks of one language in a Markdown file, in order."""
    return [m["body"] for m in FENCE.finditer(path.read_text()) if m["lang"] == lang]


def pages() -> list[Path]:
    """The Markdown files whose ``aeromag`` commands are parsed."""
    out: list[Path] = []
    for name in PARSED:
        path = ROOT / name
        out.extend(sorted(path.rglob("*.md")) if path.is_dir() else [path])
    return [p for p in out if p.exists()]


def commands(text: str, prompt: str = "") -> list[list[str]]:
    """The argument lists of the ``aeromag`` commands in a shell block.

    Lines ending in a backslash are joined; comments dropped; a line may hold several commands
    separated by ``&&``, ``;`` or ``|``. With ``prompt`` only lines starting with it count (a
    transcript), and the prompt is removed.
    """
    joined = re.sub(r"\\\n", " ", text)
    out = []
    for line in joined.splitlines():
        line = line.strip()
        if prompt:
            if not line.startswith(prompt):
                continue
            line = line[len(prompt) :]
        words = shlex.split(line, comments=True)
        command: list[str] = []
        for word in [*words, ";"]:
            if word in SEPARATORS:
                if command and Path(command[0]).name == "aeromag":
                    out.append(command[1:])
                command = []
            else:
                command.append(word)
    return out


def test_the_command_extractor_finds_every_command_and_drops_comments() -> None:
    text = (
        "bash scripts/bootstrap && .venv/bin/aeromag demo   # set up\n"
        "aeromag train --scenario suite \\\n    --timesteps 10 --out r  # long\n"
        "ray stop\n"
    )
    train = ["train", "--scenario", "suite", "--timesteps", "10", "--out", "r"]
    assert commands(text) == [["demo"], train]
    assert commands("$ aeromag info f.xyz\nfile: f.xyz\n", prompt="$ ") == [["info", "f.xyz"]]


def test_the_parser_refuses_an_option_that_does_not_exist() -> None:
    with pytest.raises(SystemExit) as stop:
        build_parser().parse_args(["compensate", "f.h5", "--method", "tl", "--out", "o", "--nope"])
    assert stop.value.code == 2


@pytest.mark.parametrize("page", pages(), ids=lambda p: str(p.relative_to(ROOT)))
def test_every_aeromag_command_on_a_page_parses(page: Path) -> None:
    found = [args for body in blocks(page, "bash") for args in commands(body)]
    found += [args for body in blocks(page, "text") for args in commands(body, prompt="$ ")]
    parser = build_parser()
    for args in found:
        try:
            parser.parse_args(args)
        except SystemExit as stop:
            if stop.code != 0:  # --help exits 0
                pytest.fail(f"{page.name}: `aeromag {shlex.join(args)}` does not parse")


def test_the_readme_has_the_two_commands_and_stays_short() -> None:
    text = (ROOT / "README.md").read_text()
    assert "bash scripts/bootstrap && .venv/bin/aeromag demo" in text
    assert ".venv/bin/python -m pytest" in text
    assert len(text.splitlines()) <= 200


def test_the_readme_links_point_to_files_that_exist() -> None:
    text = (ROOT / "README.md").read_text()
    for target in re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", text):
        if "://" not in target:
            assert (ROOT / target).exists(), f"README links to {target}, which is missing"


#: Runs the blocks given as a JSON list on stdin, each in a fresh namespace of one interpreter
#: (imports are paid once), and names the block that failed.
RUNNER = """
import json, sys, traceback
for i, code in json.load(sys.stdin):
    try:
        exec(compile(code, f"<python block {i + 1}>", "exec"), {"__name__": "__main__"})
    except BaseException:
        sys.exit(f"python block {i + 1} failed:\\n{code}\\n{traceback.format_exc()}")
"""


@pytest.mark.parametrize(
    "name",
    # the tutorial (15 s) runs in the slow step; the README's blocks in the default run
    [pytest.param(n, marks=pytest.mark.slow) if n != "README.md" else n for n in RUN_PYTHON],
)
def test_every_python_block_runs(name: str, tmp_path: Path) -> None:
    runnable: list[tuple[int, str]] = [(-1, RUN_PYTHON[name])]
    waiting: list[tuple[int, str]] = []
    for i, code in enumerate(blocks(ROOT / name, "python")):
        pending = any(call in code and not present for call, present in PENDING.items())
        (waiting if pending else runnable).append((i, code))
    run = subprocess.run(
        [sys.executable, "-c", RUNNER],
        input=json.dumps(runnable),
        cwd=tmp_path,
        env={**os.environ, "PYTHONPATH": str(ROOT), "MPLBACKEND": "Agg"},
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert run.returncode == 0, f"{name}: {run.stderr[-4000:]}"
    if waiting:
        numbers = [i + 1 for i, _ in waiting]
        pytest.skip(f"{name}: python block(s) {numbers} call aeromag_env.compensate, not built yet")
