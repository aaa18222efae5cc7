"""A job on a fleet, a folder or a glob of flight files: :func:`fleet`, the job of ``aeromag
compensate`` and ``aeromag discover`` given a folder or a glob.

Each flight gets the output set the one-file job writes (:func:`aeromag_env.jobs.compensate.
compensate`, :func:`aeromag_env.jobs.discover.discover`) in ``OUT/<file stem>/``, and the fleet a
summary, ``OUT/fleet.csv`` (one row per flight: :data:`COMPENSATE_COLUMNS` or
:data:`DISCOVER_COLUMNS`) and ``OUT/fleet.png``, written as a set (:func:`write_summary`,
:func:`aeromag_env.atomic.output_set`). The flights run through :mod:`aeromag_env.parallel`:
here, one after another, or on Ray (``ray``). A flight that fails is reported (its row, its
error) and the others complete.

A folder contributes its files with the readers' suffixes (:data:`~aeromag_env.flight.formats.
detect.SUFFIXES`; hidden files left out), a glob (``**`` for subfolders) the matching files
with those suffixes. Two files with the same stem get distinct folders (``f``, ``f-2``, … in
path order; the ``output`` column says which is which). Files this command wrote into ``OUT``
before (``fleet.csv``, ``OUT/*/compensated.h5``) are never read as flights.
"""

from __future__ import annotations

import csv
import glob
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from aeromag_env import errors, reports
from aeromag_env.atomic import check_output_set, output_set, write_text
from aeromag_env.errors import AeromagError
from aeromag_env.flight.formats.detect import SUFFIXES
from aeromag_env.flight.validation import PathLike
from aeromag_env.jobs import compensate as compensate_job
from aeromag_env.jobs import discover as discover_job
from aeromag_env.jobs.provenance import JobWarnings
from aeromag_env.parallel import Outcome, Task, runner
from aeromag_env.parallel.tasks import one_line

#: A fleet's summary page in the output folder (the interactive index of the flights).
SUMMARY_PAGE = reports.FLEET_PAGE

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


def compensate_flight(req: compensate_job.CompensateRequest) -> dict[str, Any]:
    """The task of one flight of a compensation fleet: run it, return its row (without
    ``file``, ``output`` and ``attempts``); bad input gives a row with status ``error``."""
    warnings = JobWarnings(emit=False)
    try:
        result = compensate_job.run_compensate(req, warnings)
    except (AeromagError, OSError) as e:
        return _failed(e, warnings.lines)
    report = result.report
    head = report.get("headline") or {}
    return {
        "status": "ok",
        "method": report["method"],
        **{key: head.get(key) for key in COMPENSATE_COLUMNS[4:8]},
        **_warning_cells([*warnings.lines, *report["input_problems"]]),
    }


def discover_flight(req: discover_job.DiscoverRequest) -> dict[str, Any]:
    """The task of one flight of a discovery fleet: run it, return its row (as
    :func:`compensate_flight`)."""
    warnings = JobWarnings(emit=False)
    try:
        report = discover_job.run_discover(req, warnings).report
    except (AeromagError, OSError) as e:
        return _failed(e, warnings.lines)
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
        **_warning_cells([*warnings.lines, *report["input_problems"]]),
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


#: The jobs a fleet runs: the task of one flight and the columns of ``fleet.csv``.
JOBS: dict[str, tuple[Callable[..., dict[str, Any]], tuple[str, ...]]] = {
    "compensate": (compensate_flight, COMPENSATE_COLUMNS),
    "discover": (discover_flight, DISCOVER_COLUMNS),
}


@dataclass(frozen=True)
class FleetResult:
    """What :func:`fleet` produced.

    Attributes
    ----------
    job : str
        ``compensate`` or ``discover``.
    rows : tuple of dict
        One per flight, in file order: the columns of ``fleet.csv`` (:data:`COMPENSATE_COLUMNS`
        or :data:`DISCOVER_COLUMNS`), and ``warning_lines``, each warning whole.
    outcomes : tuple of Outcome
        The runner's outcome of each flight (its error and traceback when its task crashed).
    runner : str
        The runner's name (``serial`` or ``ray``).
    paths : tuple of Path
        The summary files written (``fleet.csv``, ``fleet.png``); each flight's output set is
        in ``out/<row's output>/``.
    """

    job: str
    rows: tuple[dict[str, Any], ...]
    outcomes: tuple[Outcome, ...]
    runner: str
    paths: tuple[Path, ...]

    @property
    def failed(self) -> int:
        """How many flights failed."""
        return sum(row["status"] != "ok" for row in self.rows)

    @property
    def warnings(self) -> tuple[str, ...]:
        """Every flight's warnings, ``FILE: warning``, in file order."""
        return tuple(
            f"{row['file']}: {w}" for row in self.rows for w in row.get("warning_lines", [])
        )


def fleet(
    source: PathLike,
    out: PathLike,
    job: str = "compensate",
    ray: str | None = None,
    on_flight: Callable[[Outcome], None] | None = None,
    on_start: Callable[[int], None] | None = None,
    **options: Any,
) -> FleetResult:
    """Run a job on every flight file of a folder or glob, as ``aeromag compensate DIR`` and
    ``aeromag discover DIR`` do (module docstring).

    Parameters
    ----------
    source : str or PathLike
        A folder (its flight files) or a glob (``**`` for subfolders).
    out : str or PathLike
        The fleet's folder: each flight's output set in ``out/<file stem>/``, the summary
        ``fleet.csv`` and ``fleet.png`` in ``out``.
    job : str
        ``compensate`` or ``discover``.
    ray : str or None
        None: the flights run in this process, one after another; ``""`` or an address: on Ray
        (:func:`aeromag_env.parallel.runner`).
    on_flight : callable or None
        Called with each flight's :class:`~aeromag_env.parallel.Outcome` as it ends (its row in
        ``outcome.value`` when it ran). None: each flight's warnings are issued as
        :class:`~aeromag_env.errors.AeromagWarning` (``FILE: warning``) as it ends.
    on_start : callable or None
        Called with the number of flights once the files are found, before the first starts.
    **options
        The job's options (:data:`aeromag_env.jobs.compensate.OPTIONS`, ``method`` included,
        or :data:`aeromag_env.jobs.discover.OPTIONS`), the same for every flight.

    Returns
    -------
    FleetResult
        The rows of ``fleet.csv``; a flight that failed has status ``error`` and its message.

    Raises
    ------
    AeromagError
        An unknown job or option, unusable options, or no flight file (one line), before any
        work.
    """
    if job not in JOBS:
        raise AeromagError(f"fleet: job must be one of {', '.join(JOBS)}, got {job!r}")
    folder = Path(out)
    template = _request(job, Path(source), folder, options)
    files, names = _plan(str(source), folder, template.html)
    task, columns = JOBS[job]
    tasks = [
        Task(str(path), task, (replace(template, source=path, out=folder / name),))
        for path, name in zip(files, names, strict=True)
    ]
    if on_start is not None:
        on_start(len(tasks))
    with runner(ray) as r:
        outcomes = r.run(tasks, on_flight or _warn_flight)
    rows = [_row(o, name) for o, name in zip(outcomes, names, strict=True)]
    paths = write_summary(folder, rows, columns, files, job, template.html)
    return FleetResult(job, tuple(rows), tuple(outcomes), r.name, paths)


def _request(job: str, source: Path, out: Path, options: dict[str, Any]) -> Any:
    """The request of every flight (its ``source`` and ``out`` replaced per flight), checked."""
    known = (*compensate_job.OPTIONS, "method") if job == "compensate" else discover_job.OPTIONS
    unknown = sorted(set(options) - set(known))
    if unknown:
        raise AeromagError(f"{job}: unknown option {unknown[0]!r}; options: {', '.join(known)}")
    request: Any
    if job == "discover":
        request = discover_job.DiscoverRequest(source=source, out=out, **options)
    else:
        method = options.get("method") or (None if options.get("model") else "tl")
        request = compensate_job.CompensateRequest(
            source=source, out=out, **{**options, "method": method}
        )
    request.check()
    return request


def _plan(arg: str, out: Path, html: bool) -> tuple[list[Path], list[str]]:
    """The fleet's files and their output folder names; the summary's targets checked before
    any work."""
    files = fleet_files(arg, out)
    check_output_set(out, summary_outputs(html), files)
    return files, output_names(files)


def _warn_flight(outcome: Outcome) -> None:
    """The default of :func:`fleet`'s ``on_flight``: a flight's warnings, as it ends."""
    if outcome.ok:
        for line in outcome.value.get("warning_lines", []):
            errors.warn(f"{outcome.label}: {line}")


def _row(outcome: Outcome, name: str) -> dict[str, Any]:
    """The summary row of a flight: its task's row, or the runner's error (the task crashed or
    its worker died)."""
    row = dict(outcome.value) if outcome.ok else {"status": "error", "error": outcome.error}
    return {"file": outcome.label, "output": name, **row, "attempts": outcome.attempts}


def summary_outputs(html: bool) -> tuple[str, ...]:
    """The fleet's summary files: :data:`OUTPUTS`, and with ``html`` the index page."""
    return (*OUTPUTS, reports.FLEET_PAGE) if html else OUTPUTS


def write_summary(
    out: Path,
    rows: list[dict[str, Any]],
    columns: Sequence[str],
    inputs: Sequence[Path],
    command: str,
    html: bool = True,
) -> tuple[Path, ...]:
    """``fleet.csv`` and ``fleet.png`` in ``out``, and with ``html`` the index page
    (``index.html``, a row per flight linking to its ``report.html``), as a set; returns their
    paths."""
    from aeromag_env.jobs.fleet_plot import plot_fleet

    outputs = summary_outputs(html)
    with output_set(out, outputs, inputs) as stage:
        _write_csv(stage / OUTPUTS[0], rows, columns)
        plot_fleet(rows, command, stage / OUTPUTS[1])
        if html:
            page = reports.fleet_page(rows, columns, command, reports.PAGE)
            write_text(stage / reports.FLEET_PAGE, page)
    return tuple(out / name for name in outputs)


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
