"""Every command of the documentation runs as written, walked as a new user walks it.

Each page of :data:`tests._docs_walk.PAGES` (getting started and every how-to page) is walked in
a fresh scratch folder: its ``bash``/``console``/``python`` blocks run in order, as a user copies
them into a terminal or an interpreter, with the package's ``aeromag`` and ``python`` first on
``PATH`` and the checkout on ``PYTHONPATH`` (so ``python -m experiments.…`` runs as from the
checkout's root, its outputs going to the scratch folder). Long commands run in the reduced mode
the pages document (``AEROMAG_QUICK=1``: every command at its ``--quick`` size), never skipped.

A page fails when a block exits with an error or prints a traceback, or when a command's
``--out`` is not there after its block; and no file of the checkout may change (no page writes
into it). Blocks a page marks ``% not walked: REASON`` (the installation the walk runs on, an
illustration for a cluster's machines) are listed, and few. The walk is its own CI step
(``pytest -m docs_walk``); the parsing is tested in the default run.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests._docs_walk import PROMPT, ROOT, Block, blocks, outputs, pages

#: The reduced mode the pages document (docs/getting-started.md, "Long commands").
REDUCED = {"AEROMAG_QUICK": "1"}
#: The most blocks all pages together may keep from the walk (installation, other machines).
MOST_NOT_WALKED = 4
#: A block's time limit [s]: the longest reduced one takes minutes on a loaded 2-core machine.
BLOCK_TIMEOUT_S = 3600.0
TRACEBACK = "Traceback (most recent call last)"


def walk_environment() -> dict[str, str]:
    """The user's environment: the package's interpreter and ``aeromag`` first on ``PATH``."""
    bin_dir = str(Path(sys.executable).parent)
    return {
        **os.environ,
        **REDUCED,
        "PATH": f"{bin_dir}{os.pathsep}{os.environ.get('PATH', '')}",
        "PYTHONPATH": str(ROOT),
        "MPLBACKEND": "Agg",
    }


def run_block(block: Block, folder: Path, env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    """One block, in ``folder``: a shell script under ``bash -eo pipefail``, python in a fresh
    interpreter."""
    if block.lang == "python":
        argv, stdin = [sys.executable, "-"], block.script
    else:
        argv, stdin = ["bash", "-eo", "pipefail", "-s"], block.script
    return subprocess.run(
        argv,
        input=stdin,
        cwd=folder,
        env=env,
        capture_output=True,
        text=True,
        timeout=BLOCK_TIMEOUT_S,
        check=False,
    )


#: Folders of the checkout a walk may write: Python's and numba's caches, the tools' caches.
CACHES = {
    ".git",
    ".venv",
    "__pycache__",
    ".pytest_cache",
    ".mypy_cache",
    ".ruff_cache",
    ".hypothesis",
}


def written_into_checkout(since: float) -> list[str]:
    """The files of the checkout (caches aside) modified at or after ``since`` [s, epoch]: a
    page's commands write into the scratch folder only."""
    found = []
    for folder, subfolders, files in os.walk(ROOT):
        subfolders[:] = [d for d in subfolders if d not in CACHES]
        for name in files:
            path = Path(folder, name)
            with contextlib.suppress(OSError):  # a file removed meanwhile
                if path.stat().st_mtime >= since:
                    found.append(str(path.relative_to(ROOT)))
    return sorted(found)


@pytest.mark.docs_walk
@pytest.mark.parametrize("page", pages(), ids=lambda p: str(p.relative_to(ROOT)))
def test_every_block_of_the_page_runs_as_written(page: Path, tmp_path: Path) -> None:
    env, started = walk_environment(), time.time()
    for block in blocks(page.read_text(encoding="utf-8")):
        if not block.runs:
            continue
        t0 = time.monotonic()
        done = run_block(block, tmp_path, env)
        took = time.monotonic() - t0
        print(f"{block.label(page)}: {took:.0f} s")
        said = f"{block.label(page)} ran {took:.0f} s:\n{block.script}\n{done.stderr[-4000:]}"
        assert done.returncode == 0, f"exit status {done.returncode}: {said}"
        assert TRACEBACK not in done.stderr + done.stdout, f"a traceback: {said}"
        for out in outputs(block.script):
            assert (tmp_path / out).exists(), f"{out} is not there after {block.label(page)}"
    assert not written_into_checkout(started), f"walking {page.name} wrote into the checkout"


def test_few_blocks_are_kept_from_the_walk_and_each_says_why() -> None:
    kept = [
        (block.label(page), block.skip)
        for page in pages()
        for block in blocks(page.read_text(encoding="utf-8"))
        if block.skip is not None
    ]
    assert len(kept) <= MOST_NOT_WALKED, kept
    assert all(len(reason.split()) >= 3 for _, reason in kept), kept


def test_the_walk_finds_every_page_and_runs_blocks_on_each() -> None:
    found = [p.relative_to(ROOT).as_posix() for p in pages()]
    assert found[0] == "docs/getting-started.md"
    assert {"docs/howto/own-flight-files.md", "docs/howto/train-and-evaluate.md"} <= set(found)
    assert all(p.startswith(("docs/getting-started", "docs/howto/")) for p in found)


def test_blocks_are_found_in_order_with_their_marks() -> None:
    text = (
        "Intro.\n\n```bash\naeromag demo --out d  # the demo\n```\n\n"
        "% not walked: runs on every node of a cluster\n```bash\nray start --head\n```\n\n"
        "```text\noutput only\n```\n\n"
        "```console\n$ aeromag info f.h5 \\\n    --json\n{\n$ echo done\n```\n\n"
        "* in a list:\n\n  ```python\n  print(1)\n  ```\n"
    )
    found = blocks(text)
    assert [(b.lang, b.line, b.runs) for b in found] == [
        ("bash", 3, True),
        ("bash", 8, False),
        ("text", 12, False),
        ("console", 16, True),
        ("python", 25, True),
    ]
    assert found[4].script == "print(1)\n"
    assert found[1].skip == "runs on every node of a cluster"
    assert found[3].script == "aeromag info f.h5 --json\necho done\n"
    assert PROMPT == "$ "


def test_the_outputs_of_a_script_are_its_out_arguments() -> None:
    script = (
        "aeromag simulate --seed 7 --out flight.h5\n"
        "aeromag compensate flight.h5 --method tl \\\n    --out results/tl   # a comment --out x\n"
        "aeromag bench --out=results/bench\n"
        'for s in 1 2; do aeromag simulate --seed "$s" --out "survey/f_$s.h5"; done\n'
        "aeromag example survey_raw.xyz\naeromag convert survey_raw.xyz flight.csv  # format\n"
        "aeromag stream --model cal/model.json < line.csv > line_c.csv\n"
    )
    assert outputs(script) == [
        "flight.h5",
        "results/tl",
        "results/bench",
        "survey_raw.xyz",
        "flight.csv",
        "line_c.csv",
    ]
