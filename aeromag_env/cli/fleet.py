"""``aeromag compensate`` and ``aeromag discover`` given a folder or a glob: the progress bar, the
lines each flight puts on stderr as it ends, and the summary line. The job itself is
:func:`aeromag_env.jobs.fleet.fleet`; a flight that fails is reported (its row, one line on
stderr with its file) and the others complete; the exit status is then 2.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from aeromag_env.parallel import Outcome


def note_single_file(command: str, ray: str | None) -> None:
    """One line on stderr when ``--ray`` came with a single file (it runs here, not on Ray)."""
    if ray is not None:
        print(
            f"aeromag {command}: --ray: one file runs in this process; Ray takes a folder or "
            "a glob of flight files",
            file=sys.stderr,
        )


def run_fleet(
    command: str, source: str, out: Path, ray: str | None, quiet: bool, options: dict[str, Any]
) -> int:
    """Run :func:`~aeromag_env.jobs.fleet.fleet` (progress bar, warnings and errors on stderr as
    the flights end), print the summary line; the exit status (0, or 2 when a flight failed)."""
    from tqdm import tqdm

    from aeromag_env.jobs.fleet import SUMMARY_PAGE, fleet

    bars: list[Any] = []

    def start(total: int) -> None:
        bars.append(
            tqdm(
                total=total,
                desc=command,
                unit="flight",
                disable=quiet or None,
                file=sys.stderr,
                leave=False,
            )
        )

    def report(outcome: Outcome) -> None:
        bars[0].update()
        for line in stderr_lines(command, outcome):
            bars[0].write(line, file=sys.stderr)

    try:
        result = fleet(source, out, command, ray, on_flight=report, on_start=start, **options)
    finally:
        for bar in bars:
            bar.close()
    print(
        f"{command}: {result.failed} of {len(result.rows)} flights failed ({result.runner} "
        f"runner); wrote {out}/<flight>/ per flight, {out}/fleet.csv, fleet.png"
        + (f", {SUMMARY_PAGE}" if options.get("html", True) else "")
    )
    return 2 if result.failed else 0


def stderr_lines(command: str, outcome: Outcome) -> list[str]:
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
