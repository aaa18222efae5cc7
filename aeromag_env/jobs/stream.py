"""Compensate samples as they arrive: :func:`stream`, the job of ``aeromag stream --model``.

Input, a text stream of CSV lines (the layout ``aeromag convert FILE out.csv`` writes): ``#``
lines before the header are skipped, except the ``#@ {json}`` attribute line, whose ``date``
a filter's model uses (as a file's); the header names the channels (the model's,
:attr:`SampleStream.columns <aeromag_env.compensation.model_stream.SampleStream.columns>`, must
be among them, in any order, other columns ignored); then one line per sample, an empty cell
read as NaN as in a file. A filter's model needs the flight's date: ``date``, else the attribute
line's, else the first sample's ``year`` and ``doy`` columns.

Output, a text stream: a header (the time channel and the compensated channels as ``aeromag
compensate`` names them: ``tt,aeromag_mag_1_c`` for ``tl``, ``tt,aeromag_flux_a_c_x,…`` for a
filter), then one line per answered sample, each written and flushed as soon as the model can
answer it (:mod:`aeromag_env.compensation.model_apply`,
:mod:`aeromag_env.compensation.model_filter`). Values are Python's shortest round-trip ``repr``,
so they equal ``aeromag compensate --model`` on the same flight.

Bad lines (a wrong number of cells, a cell that is not a number, a time not after the previous
one) and flagged samples (a non-finite or spiking magnetometer, an unknown position) are
reported as warnings (one line each, naming the input line) and skipped: never silently used.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

from aeromag_env import errors
from aeromag_env.compensation.calibration_model import CalibrationModel
from aeromag_env.compensation.model_apply import StreamOutput
from aeromag_env.compensation.model_stream import SampleStream
from aeromag_env.errors import AeromagError
from aeromag_env.flight.formats.csvfile import ATTR_LINE
from aeromag_env.jobs.apply_model import model_of

#: Bad or flagged lines reported one by one; past this they are only counted (the summary
#: line at the end gives the total).
MAX_REPORTED = 100


@dataclass(frozen=True, kw_only=True)
class StreamRequest:
    """What a stream is asked for (validated by :meth:`check`).

    Attributes
    ----------
    model : Path or CalibrationModel
        The calibrated model (``aeromag calibrate``'s ``model.json``).
    date : str or None
        The flight's date (ISO 8601) for a filter's model; None: from the input.
    """

    model: Path | CalibrationModel
    date: str | None = None

    def check(self) -> None:
        """One-line errors for an unreadable or malformed model file, and a date the Earth
        field's model cannot use (before any input is read)."""
        model = model_of(self.model)
        if self.date is not None and model.is_filter:
            model.stream(date=self.date)


@dataclass
class StreamSummary:
    """What a :func:`stream` run did.

    Attributes
    ----------
    samples_in : int, sample lines read (after the header)
    samples_out : int, compensated samples written
    skipped : int, lines and samples reported and skipped
    reported : list of str, the first :data:`MAX_REPORTED` reports
    """

    samples_in: int = 0
    samples_out: int = 0
    skipped: int = 0
    reported: list[str] = field(default_factory=list)


def stream(
    model: str | Path | CalibrationModel,
    lines: Iterable[str],
    out: TextIO,
    *,
    date: str | None = None,
    warn: Callable[[str], None] | None = None,
) -> StreamSummary:
    """Compensate CSV sample lines with a calibrated model, writing each answer as it comes.

    Parameters
    ----------
    model : str, Path or CalibrationModel
        The model, or its file (:func:`aeromag_env.compensation.calibration_model.load_model`).
    lines : iterable of str
        The input lines (standard input, a file), read one at a time.
    out : text stream
        Where the header and the compensated lines go (flushed after each).
    date : str or None
        The flight's date (ISO 8601) for a filter's model (module docstring).
    warn : callable or None
        Takes each one-line report of a bad line or flagged sample (None: issued as an
        :class:`~aeromag_env.errors.AeromagWarning`).

    Returns
    -------
    StreamSummary

    Raises
    ------
    AeromagError
        An unreadable model, no header, or a header without the model's channels (one line
        naming them).
    """
    request = StreamRequest(
        model=model if isinstance(model, CalibrationModel) else Path(model), date=date
    )
    request.check()
    calibrated = model_of(request.model)
    summary = StreamSummary()
    report = _reporter(warn or errors.warn, summary)
    it = iter(lines)
    header, attrs, header_line = _header(it)
    runner = calibrated.stream(header=header, date=date or attrs.get("date"))
    index = _columns(header, runner.columns)
    out.write(",".join((runner.time_name, *runner.output_names)) + "\n")
    out.flush()
    where: dict[float, int] = {}  # input line of each held sample (at most a few)
    for number, text in _numbered(it, header_line):
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
        where[sample[runner.time_name]] = number
        _write(answers, out, where, report, summary)
    _write(runner.flush(), out, where, report, summary)
    if summary.skipped > MAX_REPORTED:
        report_line = f"{summary.skipped} lines or samples skipped in all ({MAX_REPORTED} reported)"
        (warn or errors.warn)(report_line)
    return summary


def _numbered(it: Iterator[str], number: int) -> Iterator[tuple[int, str]]:
    """The sample lines after the header with their line numbers (blank and ``#`` lines
    skipped)."""
    for text in it:
        number += 1
        if text.strip() and not text.startswith("#"):
            yield number, text


def _reporter(warn: Callable[[str], None], summary: StreamSummary) -> Callable[[str], None]:
    def report(message: str) -> None:
        summary.skipped += 1
        if summary.skipped <= MAX_REPORTED:
            summary.reported.append(message)
            warn(message)

    return report


def _header(it: Iterator[str]) -> tuple[list[str], dict, int]:
    """The header's cells, the ``#@`` attributes before it and its line number."""
    attrs: dict = {}
    for number, text in enumerate(it, start=1):
        if text.startswith(ATTR_LINE):
            attrs = _attributes(text[len(ATTR_LINE) :], number)
        elif text.strip() and not text.startswith("#"):
            return [c.strip() for c in next(csv.reader([text]))], attrs, number
    raise AeromagError("stream: no header line (the channel names) before the end of the input")


def _attributes(text: str, number: int) -> dict:
    try:
        attrs = json.loads(text)
    except ValueError as e:
        raise AeromagError(
            f"stream: line {number}: the {ATTR_LINE} line is not JSON ({e})"
        ) from None
    if not isinstance(attrs, dict):
        raise AeromagError(f"stream: line {number}: the {ATTR_LINE} line must hold a JSON object")
    return attrs


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
        if a.values_nt is None:
            report(f"line {number}: {a.problem}; skipped")
            continue
        out.write(",".join(map(repr, (a.time_s, *a.values_nt))) + "\n")
        out.flush()
        summary.samples_out += 1


__all__ = ["MAX_REPORTED", "SampleStream", "StreamRequest", "StreamSummary", "stream"]
