"""``aeromag compensate`` and ``aeromag discover`` on a fleet: a folder or a glob of flight files.

Each flight gets the output set the one-file command writes (:func:`aeromag_env.cli.compensate.
run_compensate`, :func:`aeromag_env.cli.discover.run_discover`) in ``OUT/<file stem>/``, and the
fleet a summary, ``OUT/fleet.csv`` (one row per flight: :data:`COMPENSATE_COLUMNS` or
:data:`DISCOVER_COLUMNS`) and ``OUT/fleet.png``, written as a set
(:func:`aeromag_env.atomic.output_set`). The flights run through :mod:`aeromag_env.parallel`:
here, one after another, or on Ray with ``--ray``. A flight that fails is reported (its row,
one line on stderr with its file) and the others complete; the exit status is then 2.

A folder contributes its files with the readers' suffixes (:data:`~aeromag_env.flight.formats.
detect.SUFFIXES`; hidden files left out), a glob (``**`` for subfolders) the matching files
with those suffixes. Two files with the same stem get distinct folders (``f``, ``f-2``, … in
path order; the ``output`` column says which is which). Files this command wrote into ``OUT``
before (``fleet.csv``, ``OUT/*/compensated.h5``) are never read as flights.
"""

from __future__ import annotations

import csv
import glob
import os
import re
import sys
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from aeromag_env import reports
from aeromag_env.atomic import check_output_set, output_set
from aeromag_env.cli.compensate import CompensateRequest
from aeromag_env.errors import AeromagError
from aeromag_env.flight.formats.detect import SUFFIXES
from aeromag_env.parallel import Outcome, Task, runner
from aeromag_env.parallel.tasks import one_line

#: The fleet's summary files in ``OUT``.
OUTPUTS = ("fleet.csv", "fleet.png")
#: Columns of ``fleet.csv`` for ``compensate``: the band-passed (0.1–0.9 Hz) std of the field
#: before and after, its improvement ratio and the FOM, from the report's ``headline`` block
#: (real-data figures, no truth needed) [nT, ratio unitless].
COMPENSATE_COLUMNS = (
    "file",
    "output",
    "status",
    "method",
    "std_uncompensated_nt",
    "std_compensated_nt",
    "improvement_ratio",
    "fom_nt",
    "warnings",
    "warning_text",
    "error",
    "attempts",
)
#: Columns of ``fleet.csv`` for ``discover``: the verdict, the named effects (``name(channel)``,
#: ``;``-joined) and the held-out gap [nT] with the base model, with the effects, and the shrink.
DISCOVER_COLUMNS = (
    "file",
    "output",
    "status",
    "verdict",
    "named_effects",
    "gap_before_nt",
    "gap_after_nt",
    "gap_shrink",
    "warnings",
    "warning_text",
    "error",
    "attempts",
)
#: A warning is cut to this many characters in ``warning_text``.
WARNING_CHARS = 160
_GLOB = re.compile(r"[*?[]")


def is_fleet(arg: str) -> bool:
    """Whether the ``file`` argument names a fleet: a folder, or a glob that is not a file."""
    path = Path(arg)
    return path.is_dir() or (not path.exists() and _GLOB.search(arg) is not None)


def note_single_file(command: str, ray: str | None) -> None:
    """One line on stderr when ``--ray`` came with a single file (it runs here, not on Ray)."""
    if ray is not None:
        print(
            f"aeromag {command}: --ray: one file runs in this process; Ray takes a folder or "
            "a glob of flight files",
            file=sys.stderr,
        )


def fleet_files(arg: str, out: Path) -> list[Path]:
    """The flight files of a folder or glob, sorted, without what a fleet run wrote to ``out``.

    Raises
    ------
    AeromagError
        None there (one line).
    """
    if Path(arg).is_dir():
        found = [p for p in Path(arg).iterdir() if not p.name.startswith(".")]
        where = f"in the folder {arg}"
    else:
        found = [Path(p) for p in glob.glob(arg, recursive=True)]
        where = f"match {arg!r}"
    ours = _written_here(out)
    files = sorted(
        p for p in found if p.is_file() and p.suffix.lower() in SUFFIXES and p.resolve() not in ours
    )
    if not files:
        raise AeromagError(f"no flight files ({', '.join(SUFFIXES)}) {where}")
    return files


def _written_here(out: Path) -> set[Path]:
    """The files of a fleet run into ``out`` that have a flight suffix."""
    out = out.resolve()
    return {out / OUTPUTS[0], *(p.resolve() for p in out.glob("*/compensated.h5"))}


def output_names(files: Sequence[Path]) -> list[str]:
    """One output folder name per file: its stem; ``stem-2``, ``stem-3``… for a stem taken
    before (compared without case, as some file systems do), never a summary file's name."""
    taken = {name.casefold() for name in OUTPUTS}
    names = []
    for path in files:
        name, k = path.stem, 1
        while name.casefold() in taken:
            k += 1
            name = f"{path.stem}-{k}"
        taken.add(name.casefold())
        names.append(name)
    return names


@dataclass(frozen=True, kw_only=True)
class DiscoverJob:
    """One flight of ``aeromag discover`` (the arguments of :func:`~aeromag_env.cli.discover.
    run_discover`)."""

    path: Path
    out: Path
    flux: str = "auto"
    calibration_window: tuple[float, float] | None = None
    mount: str = "auto"
    selection: dict[str, Any] | None = None
    ground: str = "ignore"
    html: bool = True


def compensate_flight(req: CompensateRequest) -> dict[str, Any]:
    """The task of one flight of ``compensate``: run it, return its row (without ``file``,
    ``output`` and ``attempts``); bad input gives a row with status ``error``."""
    from aeromag_env.cli.compensate import run_compensate

    warnings: list[str] = []
    try:
        report = run_compensate(req, warn=warnings.append)
    except (AeromagError, OSError) as e:
        return _failed(e, warnings)
    head = report.get("headline") or {}
    return {
        "status": "ok",
        "method": report["method"],
        **{key: head.get(key) for key in COMPENSATE_COLUMNS[4:8]},
        **_warning_cells([*warnings, *report["input_problems"]]),
    }


def discover_flight(job: DiscoverJob) -> dict[str, Any]:
    """The task of one flight of ``discover``: run it, return its row (as
    :func:`compensate_flight`)."""
    from aeromag_env.cli.discover import run_discover

    warnings: list[str] = []
    try:
        report = run_discover(
            job.path,
            job.out,
            job.flux,
            job.calibration_window,
            None,
            mount=job.mount,
            warn=warnings.append,
            selection=job.selection,
            ground=job.ground,
            html=job.html,
        )
    except (AeromagError, OSError) as e:
        return _failed(e, warnings)
    gap = report["gap"]
    effects = [
        f"{e['name']}({e['channel']})" if e.get("channel") else e["name"]
        for e in report["missing_effects"]
    ]
    return {
        "status": "ok",
        "verdict": report["verdict"],
        "named_effects": "; ".join(effects),
        "gap_before_nt": gap["rms_before_nt"],
        "gap_after_nt": gap["rms_after_nt"],
        "gap_shrink": gap["shrink"],
        **_warning_cells([*warnings, *report["input_problems"]]),
    }


def _failed(e: BaseException, warnings: list[str]) -> dict[str, Any]:
    """The row of a flight refused as bad input: its one-line error and the warnings so far."""
    if isinstance(e, OSError):
        error = f"{e.strerror or e}: {e.filename or ''}"
    elif isinstance(e, AeromagError):
        error = " ".join(str(e).split())
    else:
        error = one_line(e)
    return {"status": "error", "error": error, **_warning_cells(warnings)}


def _warning_cells(warnings: Sequence[str]) -> dict[str, Any]:
    """``warnings`` (the count), ``warning_text`` (each on one line, cut, ``; ``-joined) and
    ``warning_lines`` (each whole, for stderr; not a column of ``fleet.csv``)."""
    lines = [" ".join(str(w).split()) for w in warnings]
    short = [w if len(w) <= WARNING_CHARS else w[: WARNING_CHARS - 1] + "…" for w in lines]
    return {"warnings": len(lines), "warning_text": "; ".join(short), "warning_lines": lines}


def compensate_fleet(req: CompensateRequest, arg: str, ray: str | None) -> int:
    """``aeromag compensate DIR_OR_GLOB``: ``req`` is the request of every flight (its ``path``
    and ``out`` replaced per flight: ``req.out`` is the fleet's folder). Returns the exit
    status (0, or 2 when a flight failed)."""
    req.check()
    files, names = _plan(arg, req.out)
    tasks = [
        Task(str(path), compensate_flight, (replace(req, path=path, out=req.out / name),))
        for path, name in zip(files, names, strict=True)
    ]
    return _run("compensate", tasks, names, req.out, ray, quiet=False, html=req.html)


def discover_fleet(job: DiscoverJob, arg: str, ray: str | None, quiet: bool) -> int:
    """``aeromag discover DIR_OR_GLOB``: as :func:`compensate_fleet`, ``job.out`` the fleet's
    folder."""
    files, names = _plan(arg, job.out)
    tasks = [
        Task(str(path), discover_flight, (replace(job, path=path, out=job.out / name),))
        for path, name in zip(files, names, strict=True)
    ]
    return _run("discover", tasks, names, job.out, ray, quiet, html=job.html)


def _plan(arg: str, out: Path) -> tuple[list[Path], list[str]]:
    """The fleet's files and their output folder names; the summary's targets checked before
    any work."""
    files = fleet_files(arg, out)
    check_output_set(out, (*OUTPUTS, reports.FLEET_PAGE), files)
    return files, output_names(files)


def _run(
    command: str,
    tasks: list[Task],
    names: list[str],
    out: Path,
    ray: str | None,
    quiet: bool,
    html: bool = True,
) -> int:
    """Run the flights (progress bar, warnings and errors on stderr as they end), write the
    summary, print its line; the exit status."""
    from tqdm import tqdm

    def report(outcome: Outcome) -> None:
        bar.update()
        for line in _stderr_lines(command, outcome):
            bar.write(line, file=sys.stderr)

    bar = tqdm(
        total=len(tasks),
        desc=command,
        unit="flight",
        disable=quiet or None,
        file=sys.stderr,
        leave=False,
    )
    with runner(ray) as r, bar:
        outcomes = r.run(tasks, report)
    rows = [_row(o, name) for o, name in zip(outcomes, names, strict=True)]
    columns = COMPENSATE_COLUMNS if command == "compensate" else DISCOVER_COLUMNS
    write_summary(out, rows, columns, [Path(t.label) for t in tasks], command, html)
    failed = sum(row["status"] != "ok" for row in rows)
    print(
        f"{command}: {failed} of {len(rows)} flights failed ({r.name} runner); wrote "
        f"{out}/<flight>/ per flight, {out}/fleet.csv, fleet.png"
        + (f", {reports.FLEET_PAGE}" if html else "")
    )
    return 2 if failed else 0


def _stderr_lines(command: str, outcome: Outcome) -> list[str]:
    """The lines a finished flight puts on stderr: its warnings, its error (the traceback of a
    crashed task too with ``AEROMAG_DEBUG=1``)."""
    head = f"aeromag {command}: {outcome.label}:"
    if not outcome.ok:
        debug = os.environ.get("AEROMAG_DEBUG") == "1" and outcome.details
        return [f"{head} error: {outcome.error}", *([outcome.details] if debug else [])]
    row = outcome.value
    lines = [f"{head} warning: {w}" for w in row.get("warning_lines", [])]
    if row["status"] != "ok":  # without the file's name when the message starts with it
        lines.append(f"{head} error: {row['error'].removeprefix(outcome.label + ': ')}")
    return lines


def _row(outcome: Outcome, name: str) -> dict[str, Any]:
    """The summary row of a flight: its task's row, or the runner's error (the task crashed or
    its worker died)."""
    row = dict(outcome.value) if outcome.ok else {"status": "error", "error": outcome.error}
    return {"file": outcome.label, "output": name, **row, "attempts": outcome.attempts}


def write_summary(
    out: Path,
    rows: list[dict[str, Any]],
    columns: Sequence[str],
    inputs: Sequence[Path],
    command: str,
    html: bool = True,
) -> None:
    """``fleet.csv`` and ``fleet.png`` in ``out``, and with ``html`` the index page
    (``index.html``, a row per flight linking to its ``report.html``), as a set."""
    from aeromag_env.cli.fleet_plot import plot_fleet

    outputs = (*OUTPUTS, reports.FLEET_PAGE) if html else OUTPUTS
    with output_set(out, outputs, inputs) as stage:
        _write_csv(stage / OUTPUTS[0], rows, columns)
        plot_fleet(rows, command, stage / OUTPUTS[1])
        if html:
            page = reports.fleet_page(rows, columns, command, reports.PAGE)
            (stage / reports.FLEET_PAGE).write_text(page, encoding="utf-8")


def _write_csv(path: Path, rows: list[dict[str, Any]], columns: Sequence[str]) -> None:
    """The rows as CSV (floats to 6 significant digits, None empty)."""
    with open(path, "w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(columns), extrasaction="ignore")
        writer.writeheader()
        for row in rows:
            writer.writerow({c: _cell(row.get(c)) for c in columns})


def _cell(value: Any) -> Any:
    if value is None:
        return ""
    if isinstance(value, float):
        return f"{value:.6g}"
    return value
