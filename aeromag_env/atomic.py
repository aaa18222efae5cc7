"""Atomic output: single files and whole output sets, never over an input.

* :func:`atomic_path` writes one file: to a temporary file beside the target, flushed, then
  renamed over it. An interrupted run leaves the old file or the new one, never a partial one.
* :func:`output_set` writes a command's outputs (``compensated.h5``, ``report.json``,
  ``compensation.png``…) as a set: every file into a staging folder inside the output folder;
  when all are written, a commit mark; then each file renamed into place. Everything is checked
  (no target is an input, a folder, or in a folder we cannot write) before the work starts and
  again before anything is renamed, so a refusal leaves the folder as it was. A kill before the
  commit mark leaves the old set (the next run removes the stale staging folder); a kill during
  the renames (microseconds) leaves a committed staging folder that the next run into the same
  folder, or :func:`recover`, completes: the new set.

Temporary names carry the writer's process id, so a later run removes those of dead processes
and leaves a running one's alone.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path

from aeromag_env.errors import AeromagError

PathLike = str | os.PathLike

#: Prefix of the staging folders of :func:`output_set` (inside the output folder).
STAGE_PREFIX = ".aeromag-stage-"
#: The commit mark inside a staging folder: the set's file names, one per line.
COMMIT_MARK = "COMMITTED"


def check_not_input(
    path: PathLike, inputs: Iterable[PathLike] = (), error: type[AeromagError] = AeromagError
) -> Path:
    """Return ``path`` as a Path; raise ``error`` (one line) if it is, or resolves to, an input
    (the same path, a symbolic link to it, or a hard link to the same file)."""
    out = Path(path)
    for source in inputs:
        src = Path(source)
        if out.resolve() == src.resolve() or (out.exists() and src.exists() and out.samefile(src)):
            raise error(f"output path {out} is the input file {src}; choose another output")
    return out


def check_output_file(
    path: PathLike, inputs: Iterable[PathLike] = (), error: type[AeromagError] = AeromagError
) -> Path:
    """Refuse, before any work, an output file that is an input (or a link to one), a folder,
    or in a folder we may not write to. Returns ``path`` as a Path."""
    out = check_not_input(path, inputs, error)
    if out.is_dir():
        raise error(f"output path {out} is a folder; give a file name")
    _check_writable(out.parent, error)
    return out


def _check_writable(folder: Path, error: type[AeromagError]) -> None:
    """``folder``, or its nearest existing parent, must be a folder we may write to."""
    existing = next((p for p in [folder, *folder.parents] if p.exists()), None)
    if existing is not None and not existing.is_dir():
        raise error(f"cannot write under {existing}: it is a file, not a folder")
    if existing is not None and not os.access(existing, os.W_OK | os.X_OK):
        raise error(f"cannot write to {existing}: permission denied; choose another output")


def _pid_alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's live process
        return True
    return True


def _writer_pid(name: str, prefix: str) -> int | None:
    """The process id in a temporary name ``{prefix}{pid}-…``, or None if there is none."""
    head = name[len(prefix) :].split("-", 1)[0].split(".", 1)[0]
    return int(head) if head.isdigit() else None


def clean_stale_temporaries(folder: PathLike, name: str) -> None:
    """Remove the temporary files of :func:`atomic_path` for ``name`` in ``folder`` that a dead
    process left behind (a kill between writing and renaming)."""
    prefix = f".{name}.tmp-"
    with contextlib.suppress(OSError):
        for entry in Path(folder).iterdir():
            pid = _writer_pid(entry.name, prefix) if entry.name.startswith(prefix) else None
            if pid is not None and not _pid_alive(pid):
                entry.unlink(missing_ok=True)


@contextlib.contextmanager
def atomic_path(
    path: PathLike, inputs: Iterable[PathLike] = (), error: type[AeromagError] = AeromagError
) -> Iterator[Path]:
    """Yield a temporary path in the target's folder; on success move it onto ``path``.

    The parent folder is created; the data are flushed to disk before the rename and the file
    gets the permissions of the file it replaces (or the umask default). On any exception the
    temporary file is removed and an existing ``path`` is left untouched; temporary files of
    killed earlier runs are removed first.
    """
    out = check_output_file(path, inputs, error)
    out.parent.mkdir(parents=True, exist_ok=True)
    clean_stale_temporaries(out.parent, out.name)
    fd, name = tempfile.mkstemp(prefix=f".{out.name}.tmp-{os.getpid()}-", dir=out.parent)
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


def check_output_set(
    folder: PathLike,
    names: Sequence[str],
    inputs: Iterable[PathLike] = (),
    error: type[AeromagError] = AeromagError,
) -> Path:
    """Refuse, before any work, an output set that could not be written or would replace an
    input: ``folder`` an existing file, a target that is an input (or a link to one) or a
    folder, a folder we may not write to. Returns ``folder`` as a Path."""
    out = Path(folder)
    if out.exists() and not out.is_dir():
        raise error(f"--out {out} is a file, not a folder; give a folder for the outputs")
    sources = [Path(p) for p in inputs if p is not None]
    for name in names:
        target = check_not_input(out / name, sources, error)
        if target.is_dir():
            raise error(f"output {target} is a folder; move it away or choose another --out")
    _check_writable(out, error)
    return out


def recover(folder: PathLike) -> list[str]:
    """Finish or remove what killed runs left in ``folder``: a committed staging folder is
    renamed into place (its set is complete), an uncommitted one removed. Staging folders of
    live processes are left alone. Returns the names of the files put into place."""
    placed: list[str] = []
    out = Path(folder)
    if not out.is_dir():
        return placed
    for stage in sorted(out.glob(f"{STAGE_PREFIX}*")):
        pid = _writer_pid(stage.name, STAGE_PREFIX)
        if not stage.is_dir() or pid is None or _pid_alive(pid):
            continue
        mark = stage / COMMIT_MARK
        if mark.exists():
            names = mark.read_text(encoding="utf-8").split("\n")
            placed += _move_into_place(stage, out, [n for n in names if n])
        shutil.rmtree(stage, ignore_errors=True)
    return placed


def _move_into_place(stage: Path, out: Path, names: Sequence[str]) -> list[str]:
    moved = []
    for name in names:
        if (stage / name).exists():
            os.replace(stage / name, out / name)
            moved.append(name)
    _fsync_dir(out)
    return moved


def _fsync_dir(folder: Path) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


@contextlib.contextmanager
def output_set(
    folder: PathLike,
    names: Sequence[str],
    inputs: Iterable[PathLike] = (),
    error: type[AeromagError] = AeromagError,
) -> Iterator[Path]:
    """Yield a staging folder; write the files ``names`` into it; on leaving the block they
    replace the files of the same names in ``folder`` as a set (see the module docstring).

    Parameters
    ----------
    folder : path
        The output folder (created if missing).
    names : sequence of str
        The set's file names; each must be written into the staging folder.
    inputs : iterable of path
        The run's input files: no target may be one of them.
    error : type
        Exception raised for a refused target (one line).

    Raises
    ------
    AeromagError
        A target is an input, a folder, or not writable (nothing written); a file of the set
        was not written (nothing replaced).
    """
    sources = [Path(p) for p in inputs if p is not None]
    out = check_output_set(folder, names, sources, error)
    created = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    recover(out)
    stage = Path(tempfile.mkdtemp(prefix=f"{STAGE_PREFIX}{os.getpid()}-", dir=out))
    committed = False
    try:
        yield stage
        missing = [name for name in names if not (stage / name).is_file()]
        if missing:
            raise error(f"internal: the output set lacks {', '.join(missing)}; nothing replaced")
        check_output_set(out, names, sources, error)  # the folder may have changed meanwhile
        for name in names:
            with open(stage / name, "rb") as fh:
                os.fsync(fh.fileno())
        with atomic_path(stage / COMMIT_MARK) as tmp:
            tmp.write_text("\n".join(names) + "\n", encoding="utf-8")
        committed = True
        _move_into_place(stage, out, names)
    finally:
        if not committed or _all_moved(stage, names):  # else the next run completes it
            shutil.rmtree(stage, ignore_errors=True)
        if created and not any(out.iterdir()):
            out.rmdir()


def _all_moved(stage: Path, names: Sequence[str]) -> bool:
    return not any((stage / name).exists() for name in names)
