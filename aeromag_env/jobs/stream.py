"""Compensate samples as they arrive: :func:`stream`, the job of ``aeromag stream --model``.

Input, a text stream of CSV lines (the layout ``aeromag convert FILE out.csv`` writes):
``#`` lines (comments, and the ``#@ {json}`` attribute line) anywhere before the header are
skipped; the header names the channels (the model's, :meth:`CalibrationModel.input_channels`,
must be among them, in any order, other columns ignored); then one line per sample, an empty
cell read as NaN as in a file.

Output, a text stream: a header ``TIME,NAME`` (the time channel and the compensated channel as
``aeromag compensate`` names it, ``aeromag_mag_1_c``), then one line per answered sample, each
written and flushed as soon as the model can answer it (a Tolles–Lawson model answers a sample
when the second after it arrives, :mod:`aeromag_env.compensation.model_apply`). Values are
Python's shortest round-trip ``repr``, so they equal ``aeromag compensate --model`` on the same
flight exactly.

Bad lines (a wrong number of cells, a cell that is not a number, a time not after the previous
one) and flagged samples (a non-finite or spiking magnetometer) are reported to ``warn`` (one
line each, naming the input line) and skipped: never silently used.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import TextIO

from aeromag_env.compensation.calibration_model import CalibrationModel
from aeromag_env.compensation.model_apply import SampleStream, StreamOutput
from aeromag_env.errors import AeromagError

#: Bad or flagged lines reported one by one; past this they are only counted (the summary
#: line at the end gives the total).
MAX_REPORTED = 100


@dataclass
class StreamSummary:
    """What a :func:`stream` run did.

    Attributes
    ----------
    samples_in : int, sample lines read (after the header)
    samples_out : int, compensated samples written
    skipped : int, lines and samples reported and skipped
    """

    samples_in: int = 0
    samples_out: int = 0
    skipped: int = 0
    reported: list[str] = field(default_factory=list)


def stream(
    model: CalibrationModel,
    lines: Iterable[str],
    out: TextIO,
    warn: Callable[[str], None],
) -> StreamSummary:
    """Compensate CSV sample lines with a model, writing each answer as it comes.

    Parameters
    ----------
    model : CalibrationModel
        A calibrated ``tl`` model (:func:`aeromag_env.compensation.calibration_model.load_model`).
    lines : iterable of str
        The input lines (standard input, a file), read one at a time.
    out : text stream
        Where the header and the compensated lines go (flushed after each).
    warn : callable
        Takes each one-line report of a bad line or flagged sample.

    Returns
    -------
    StreamSummary

    Raises
    ------
    AeromagError
        No header, or a header without the model's channels (one line naming them).
    """
    runner = SampleStream(model)
    summary = StreamSummary()
    report = _reporter(warn, summary)
    it = iter(lines)
    header, number = _header(it)
    index = _columns(header, runner.columns)
    out.write(f"{runner.columns[0]},{runner.output_name}\n")
    out.flush()
    where: dict[float, int] = {}  # input line of each held sample (at most a few)
    for text in it:
        number += 1
        if not text.strip() or text.startswith("#"):
            continue
        summary.samples_in += 1
        sample = _parse(text, index, len(header), number)
        if isinstance(sample, str):
            report(sample)
            continue
        try:
            answers = runner.update(sample)
        except AeromagError as e:
            report(f"line {number}: {e}; skipped")
            continue
        where[sample[runner.columns[0]]] = number
        _write(answers, out, where, report, summary)
    _write(runner.flush(), out, where, report, summary)
    if summary.skipped > MAX_REPORTED:
        warn(f"{summary.skipped} lines or samples skipped in all ({MAX_REPORTED} reported)")
    return summary


def _reporter(warn: Callable[[str], None], summary: StreamSummary) -> Callable[[str], None]:
    def report(message: str) -> None:
        summary.skipped += 1
        if summary.skipped <= MAX_REPORTED:
            summary.reported.append(message)
            warn(message)

    return report


def _header(it: Iterable[str]) -> tuple[list[str], int]:
    """The header's cells and its line number (``#`` and blank lines before it skipped)."""
    for number, text in enumerate(it, start=1):
        if text.strip() and not text.startswith("#"):
            return [c.strip() for c in next(csv.reader([text]))], number
    raise AeromagError("stream: no header line (the channel names) before the end of the input")


def _columns(header: list[str], needed: tuple[str, ...]) -> dict[str, int]:
    """Column index of each channel the model needs; one-line error naming the missing."""
    missing = [c for c in needed if c not in header]
    if missing:
        raise AeromagError(
            f"stream: the header lacks channel(s) {', '.join(missing)} that the model needs "
            f"({', '.join(needed)}); it has {', '.join(header[:20])}"
        )
    return {c: header.index(c) for c in needed}


def _parse(text: str, index: dict[str, int], width: int, number: int) -> dict[str, float] | str:
    """The sample of one line, or a one-line report of why it is bad."""
    cells = next(csv.reader([text]), [])
    if len(cells) != width:
        return f"line {number}: {len(cells)} cells where the header has {width}; skipped"
    sample = {}
    for name, i in index.items():
        cell = cells[i].strip()
        try:
            sample[name] = float(cell) if cell else math.nan
        except ValueError:
            return f"line {number}: {name} is {cell[:20]!r}, not a number; skipped"
    return sample


def _write(
    answers: list[StreamOutput],
    out: TextIO,
    where: dict[float, int],
    report: Callable[[str], None],
    summary: StreamSummary,
) -> None:
    for a in answers:
        number = where.pop(a.time_s, None)
        if a.value_nt is None:
            report(f"line {number}: {a.problem}; skipped")
            continue
        out.write(f"{a.time_s!r},{a.value_nt!r}\n")
        out.flush()
        summary.samples_out += 1
