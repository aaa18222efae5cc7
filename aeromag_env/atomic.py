"""Atomic output: write to a temporary file beside the target, then rename over it.

An interrupted run leaves either the old file or the new one, never a partial file; a target
that is one of the run's inputs is refused, so an input is never overwritten.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path

from aeromag_env.errors import AeromagError


def check_not_input(path: str | os.PathLike, inputs: Iterable[str | os.PathLike] = ()) -> Path:
    """Return ``path`` as a Path; one-line error if it names the same file as an input."""
    out = Path(path)
    for inp in inputs:
        p = Path(inp)
        same = out.resolve() == p.resolve() or (
            out.exists() and p.exists() and os.path.samefile(out, p)
        )
        if same:
            raise AeromagError(f"output path {out} is the input file {p}; choose another output")
    return out


@contextlib.contextmanager
def atomic_path(
    path: str | os.PathLike, inputs: Iterable[str | os.PathLike] = ()
) -> Iterator[Path]:
    """Yield a temporary path in the target's folder; rename it onto ``path`` on success.

    The parent folder is created. On any exception the temporary file is removed and an
    existing ``path`` is left untouched.
    """
    out = check_not_input(path, inputs)
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{out.name}.", suffix=out.suffix + ".tmp", dir=out.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.replace(tmp, out)
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)


def write_text(
    path: str | os.PathLike, text: str, inputs: Iterable[str | os.PathLike] = ()
) -> Path:
    """Atomically write a text file (JSON, Markdown)."""
    with atomic_path(path, inputs) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)
