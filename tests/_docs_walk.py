"""The documentation walked as a new user walks it: the pages' code blocks, in order, in a fresh
folder (:mod:`tests.test_docs_walk` runs them).

A page's fenced blocks are its steps. ``bash``, ``sh`` and ``shell`` blocks run as bash scripts
(stopping at the first failing command); ``console`` blocks are transcripts whose ``$ `` lines
run (the other lines are what the commands print); ``python`` blocks run each in a fresh
interpreter. Every other block (``text``, ``json``…) is something to read, not to run.

A block that is an illustration (for a cluster's machines, with a placeholder address) or that
sets up the machine the walk runs on (the installation) says so on the line right above its
fence, in a MyST comment the site does not show: ``% not walked: REASON``. A block of output is
fenced ``text`` (or is a ``console`` transcript's lines without ``$ ``) and needs no mark. Long
commands are not marked: they run in the reduced mode the pages document
(``AEROMAG_QUICK=1``: every command at its ``--quick`` size).
"""

from __future__ import annotations

import re
import shlex
import textwrap
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: The pages walked: getting started and every how-to page (a new page is walked as it comes).
PAGES = ("docs/getting-started.md", "docs/howto/*.md")
#: Fence languages that run, by how.
SHELL, CONSOLE, PYTHON = ("bash", "sh", "shell"), ("console",), ("python",)
#: The MyST comment that keeps the next block from running, and why.
NOT_WALKED = re.compile(r"^%\s*not walked:\s*(?P<reason>\S.*)$")
FENCE = re.compile(
    r"^(?P<indent>[ \t]*)```(?P<lang>[\w-]*)[^\n]*\n(?P<body>.*?)^(?P=indent)```[ \t]*$",
    re.M | re.S,
)
#: Characters of a shell word the shell expands.
EXPANDED = "$*?[`~"
#: The prompt of a ``console`` transcript's command lines.
PROMPT = "$ "


@dataclass(frozen=True)
class Block:
    """One fenced block of a page: its language, its text, its first line (1-based) and, when it
    is not walked, why."""

    lang: str
    body: str
    line: int
    skip: str | None = None

    @property
    def runs(self) -> bool:
        return self.skip is None and self.lang in (*SHELL, *CONSOLE, *PYTHON)

    @property
    def script(self) -> str:
        """What runs: a shell block as it is, a transcript's ``$`` lines, python as it is."""
        if self.lang in CONSOLE:
            lines = _joined(self.body).splitlines()
            return "\n".join(ln[len(PROMPT) :] for ln in lines if ln.startswith(PROMPT)) + "\n"
        return self.body

    def label(self, page: Path) -> str:
        return f"{page.relative_to(ROOT)}:{self.line} ({self.lang})"


def pages() -> list[Path]:
    """The walked pages, in a stable order."""
    found: list[Path] = []
    for pattern in PAGES:
        found.extend(sorted(ROOT.glob(pattern)))
    return found


def blocks(text: str) -> list[Block]:
    """The fenced blocks of a Markdown text, in order, with their ``not walked`` marks."""
    out = []
    for m in FENCE.finditer(text):
        line = text.count("\n", 0, m.start()) + 1
        before = text[: m.start()].rstrip("\n").rsplit("\n", 1)[-1].strip()
        mark = NOT_WALKED.match(before)
        body = textwrap.dedent(m["body"]) if m["indent"] else m["body"]
        out.append(Block(m["lang"], body, line, mark["reason"] if mark else None))
    return out


def _joined(script: str) -> str:
    """Lines continued with a backslash joined into one."""
    return re.sub(r"[ \t]*\\\n[ \t]*", " ", script)


def outputs(script: str) -> list[str]:
    """What the commands of a shell script say they write: their ``--out`` arguments, the
    output file of ``aeromag example`` and ``aeromag convert``, a file stdout is redirected to;
    one the shell expands (a variable of a loop, a glob) is not checked."""
    found = []
    for line in _joined(script).splitlines():
        try:
            words = shlex.split(line, comments=True)
        except ValueError:  # a heredoc's body, an unbalanced quote: no command line
            continue
        found += [words[i + 1] for i, w in enumerate(words[:-1]) if w in ("--out", ">")]
        found += [w.removeprefix("--out=") for w in words if w.startswith("--out=")]
        found += _positional_output(words)
    return [out for out in found if not set(out) & set(EXPANDED)]


def _positional_output(words: list[str]) -> list[str]:
    """The output file of ``aeromag example OUT`` and ``aeromag convert IN OUT``."""
    if len(words) >= 3 and words[0] == "aeromag" and words[1] == "example":
        return [words[2]]
    if len(words) >= 4 and words[0] == "aeromag" and words[1] == "convert":
        return [words[3]]
    return []
