"""What ``aeromag compensate`` produces, whether it fitted on the flight or applied a calibrated
model: the result (:class:`CompensationResult`), the output set (:data:`OUTPUTS`, written as a
set by :func:`write_compensate_outputs`) and the report's shared blocks."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from aeromag_env import reports
from aeromag_env.atomic import output_set, write_text
from aeromag_env.compensation.compensate import FILTER_METHODS, Compensation
from aeromag_env.errors import AeromagError
from aeromag_env.flight.data import Flight
from aeromag_env.flight.files import write_flight
from aeromag_env.jobs.reports import jsonable, report_json

#: 2: provenance (input_sha256, input_format, channels, mount, segments, flagged_samples,
#: flight_date, earth_model) and the headline / vendor_comparison blocks.
REPORT_VERSION = 2
#: The output set of a compensation, in the folder ``out``.
OUTPUTS = ("compensated.h5", "report.json", "compensation.png", reports.PAGE)


@dataclass(frozen=True)
class OutputTarget:
    """Where an output set goes: the folder ``out``, whether ``report.html`` is written, and
    the files the run read (never overwritten)."""

    out: Path
    html: bool
    inputs: list[Path]


@dataclass(frozen=True)
class CompensationResult:
    """What :func:`compensate` produced.

    Attributes
    ----------
    method : str
    metrics : dict
        The report's ``metrics`` block (:func:`~aeromag_env.compensation.compensate.score`).
    coefficients : dict
        The report's ``coefficients``: T_p, A, B (vector methods) or the 18 TL terms.
    report : dict
        Everything ``report.json`` holds (NaN and infinities as floats here, ``null`` in the
        file: :func:`aeromag_env.jobs.reports.report_json` gives its text).
    warnings : tuple of str
        The warnings the run said, one line each, in order (the command line prints each on
        stderr as ``aeromag: warning: …``). The input file's problems are in
        :attr:`input_problems`, not here.
    paths : tuple of Path
        The files written (empty without ``out``).
    compensation : Compensation
        The method's series: compensated fields, totals before and after [nT], diagnostics.
    flight : Flight
        What ``compensated.h5`` holds: the selected samples of the input plus the compensated
        channels.
    """

    method: str
    metrics: dict[str, Any]
    coefficients: dict[str, Any]
    report: dict[str, Any]
    warnings: tuple[str, ...]
    paths: tuple[Path, ...]
    compensation: Compensation
    flight: Flight

    @property
    def input_problems(self) -> list[str]:
        """What the reader found in the input (aliases, non-finite samples, gaps, spikes…)."""
        return list(self.report["input_problems"])


def outputs(html: bool) -> tuple[str, ...]:
    """The output set: :data:`OUTPUTS`, without the page when ``html`` is off."""
    return OUTPUTS if html else tuple(n for n in OUTPUTS if n != reports.PAGE)


def write_compensate_outputs(
    target: OutputTarget,
    out_flight: Flight,
    report: dict[str, Any],
    work: Flight,
    comp: Compensation,
) -> tuple[Path, ...]:
    """Write the output set (:func:`outputs`) into ``target.out``, all replaced together; the
    files the run read (``target.inputs``) are never overwritten. Returns the paths written."""
    from aeromag_env.compensation.plots import plot_compensation

    names = outputs(target.html)
    with output_set(target.out, names, target.inputs) as stage:
        write_flight(out_flight, stage / "compensated.h5")
        write_text(stage / "report.json", report_json(report))
        plot_compensation(work, comp, report["metrics"], stage / "compensation.png")
        if target.html:
            page = reports.compensate_page(jsonable(report), reports.compensate_arrays(work, comp))
            write_text(stage / reports.PAGE, page)
    return tuple(target.out / name for name in names)


def check_output_names(flight: Flight, comp: Compensation) -> None:
    """One-line error when an output channel would replace a field of the input file."""
    clash = [nm for nm in comp.fields if nm in flight]
    if clash:
        raise AeromagError(
            f"the input already has field(s) {', '.join(clash)}, which compensate writes; "
            "refusing to replace an input field (rename or drop them in the input first)"
        )


def nonfinite_policy(comp: Compensation, applied: bool = False) -> str:
    """What the report says happened to flagged samples and gaps (``nonfinite_policy``);
    ``applied``: a calibrated model was applied (nothing was fitted)."""
    flagged = "flagged samples (a non-finite input, or a spike in the magnetometer used) are"
    rest = "outputs there are NaN; the rate, band-passes and filters restart at each time gap"
    if comp.method in FILTER_METHODS:
        return f"{flagged} skipped by the filter (predict only); {rest}"
    if applied:
        return f"{flagged} not compensated; {rest}"
    return f"{flagged} left out of the fit; {rest}"
