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

PathLike = str | os.PathLike


def check_not_input(
    path: PathLike, inputs: Iterable[PathLike] = (), error: type[AeromagError] = AeromagError
) -> Path:
    """Return ``path`` as a Path; raise ``error`` (one line) if it is, or resolves to, an input."""
    out = Path(path)
    for source in inputs:
        src = Path(source)
        if out.resolve() == src.resolve() or (out.exists() and src.exists() and out.samefile(src)):
            raise error(f"output path {out} is the input file {src}; choose another output")
    return out


@contextlib.contextmanager
def atomic_path(
    path: PathLike, inputs: Iterable[PathLike] = (), error: type[AeromagError] = AeromagError
) -> Iterator[Path]:
    """Yield a temporary path in the target's folder; on success move it onto ``path``.

    The parent folder is created; the data are flushed to disk before the rename and the file
    gets the permissions of the file it replaces (or the umask default). On any exception the
    temporary file is removed and an existing ``path`` is left untouched.
    """
    out = check_not_input(path, inputs, error)
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, name = tempfile.mkstemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent)
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
        with open(tmp, "rb") as fh:
            os.fsync(fh.fileno())
        os.chmod(tmp, _target_mode(out))
        os.replace(tmp, out)
    finally:
        tmp.unlink(missing_ok=True)


def _target_mode(out: Path) -> int:
    """Permission bits: those of the file replaced, else the default for a new file."""
    if out.exists():
        return out.stat().st_mode & 0o777
    umask = os.umask(0o022)
    os.umask(umask)
    return 0o666 & ~umask


def write_text(path: PathLike, text: str, inputs: Iterable[PathLike] = ()) -> Path:
    """Atomically write a text file (JSON, Markdown)."""
    with atomic_path(path, inputs) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)
