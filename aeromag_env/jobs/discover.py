"""Find what the model is missing in a flight: :func:`discover`, the job of ``aeromag discover``.

Outputs in the folder ``out`` (when one is given): ``report.json`` (``missing_effects``, ``gap``,
``candidates``, ``skipped``, ``diagnostics``…), ``report.md`` (the same for people),
``model_config.json`` (the augmented model as a simulator configuration: ``aeromag simulate
--config model_config.json --replay FILE`` re-creates the flight with the named effects),
``residual.png``, ``diagnostics.png`` and ``report.html`` (:mod:`aeromag_env.reports`; not with
``html=False``) (:data:`OUTPUTS`), written as a set
(:func:`write_discover_outputs`, :func:`aeromag_env.atomic.output_set`): refused before the work
if a target is an input, and all replaced together at the end.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from aeromag_env import reports
from aeromag_env.atomic import check_output_set, output_set, write_text
from aeromag_env.configs import to_json
from aeromag_env.discovery.ground import GROUND_MODES
from aeromag_env.discovery.workflow import ALPHA, Discovery
from aeromag_env.discovery.workflow import discover as discover_flight
from aeromag_env.errors import AeromagError, ArgumentError
from aeromag_env.flight.data import Flight
from aeromag_env.flight.mount_choice import in_body_axes
from aeromag_env.flight.selection import select
from aeromag_env.flight.validation import PathLike
from aeromag_env.jobs.discover_plot import plot_discovery
from aeromag_env.jobs.limits import check_calibration_line, check_lines, check_number, check_window
from aeromag_env.jobs.provenance import (
    IN_MEMORY,
    JobWarnings,
    choose_inputs,
    load_source,
    provenance,
)
from aeromag_env.jobs.reports import jsonable

#: 2: the provenance blocks of :func:`aeromag_env.jobs.provenance.provenance`; 3: ``caveats``;
#: 4: ``ground`` (``ground="separate"``), and ``gap.shrink`` 1 where both gaps are 0 (it was inf).
REPORT_VERSION = 4
#: The output set of a discovery, in the folder ``out``.
OUTPUTS = (
    "report.json",
    "report.md",
    "model_config.json",
    "residual.png",
    "diagnostics.png",
    reports.PAGE,
)


@dataclass(frozen=True, kw_only=True)
class DiscoverRequest:
    """Everything a discovery is asked for.

    Attributes
    ----------
    source : Path or Flight
        The flight file, or a flight in memory.
    out : Path or None
        The folder of the output set (None: nothing written).
    flux : str
        The fluxgate id, or ``auto`` (the first clean one).
    calibration_window_s : (float, float) or None
        Fit on T0 ≤ tt ≤ T1 [s], score the rest (None: every third 60-s block held out).
    mount : str
        ``auto``, ``identity`` or a JSON mount file, as for a compensation; an applied mount
        rotates the fluxgate into body axes before the workflow reads it.
    lines, segment_s, calibration_line
        The part of the flight (:func:`aeromag_env.flight.selection.select`); a calibration
        line is fitted on as a calibration window from its first to its last sample.
    ground : str
        ``ignore`` or ``separate`` (:func:`aeromag_env.discovery.workflow.discover`).
    alpha : float
        Family-wise false-alarm level of the effect tests, in (0, 1).
    html : bool
        Write ``report.html`` (:mod:`aeromag_env.reports`) with the set.
    """

    source: Path | Flight
    out: Path | None
    flux: str = "auto"
    calibration_window_s: tuple[float, float] | None = None
    mount: str = "auto"
    lines: tuple[float, ...] | None = None
    segment_s: tuple[float, float] | None = None
    calibration_line: str | None = None
    ground: str = "ignore"
    alpha: float = ALPHA
    html: bool = True

    @property
    def path(self) -> Path | None:
        """The flight file (None for a flight given in memory)."""
        return None if isinstance(self.source, Flight) else self.source

    def check(self) -> None:
        """One-line errors for unusable options (before any file is read), each naming the
        argument (:class:`~aeromag_env.errors.ArgumentError`)."""
        check_window("calibration_window_s", self.calibration_window_s)
        check_lines("lines", self.lines)
        check_window("segment_s", self.segment_s)
        check_calibration_line("calibration_line", self.calibration_line)
        if self.ground not in GROUND_MODES:
            raise ArgumentError("ground", f"must be one of {', '.join(GROUND_MODES)}", self.ground)
        check_number(
            "alpha",
            self.alpha,
            1e-9,
            0.5,
            "(the family-wise false-alarm level of the effect tests)",
        )

    def input_files(self) -> list[Path]:
        """The files the run reads: the flight and a mount file."""
        mount = [] if self.mount in ("auto", "identity") else [Path(self.mount)]
        return [*([] if self.path is None else [self.path]), *mount]

    def outputs(self) -> tuple[str, ...]:
        """The output set: :data:`OUTPUTS`, without the page when ``html`` is off."""
        return OUTPUTS if self.html else tuple(n for n in OUTPUTS if n != reports.PAGE)


#: The options :func:`discover` takes by keyword: the fields of :class:`DiscoverRequest` but the
#: source and the output folder (its positional arguments).
OPTIONS = tuple(
    f.name for f in dataclasses.fields(DiscoverRequest) if f.name not in ("source", "out")
)


@dataclass(frozen=True)
class DiscoverResult:
    """What :func:`discover` produced.

    Attributes
    ----------
    report : dict
        Everything ``report.json`` holds (JSON-ready): ``verdict``, ``missing_effects``, ``gap``,
        ``candidates``, ``diagnostics``, the input's problems and the provenance blocks.
    warnings : tuple of str
        The warnings the run said, one line each, in order (channels, mount, Earth-field check,
        then the report's caveats; the command line prints each as ``aeromag: warning: …``).
    paths : tuple of Path
        The files written (empty without ``out``).
    discovery : Discovery
        The workflow's result: the augmented model (``model``), the residual series, the
        drivers of the named effects.
    """

    report: dict[str, Any]
    warnings: tuple[str, ...]
    paths: tuple[Path, ...]
    discovery: Discovery

    @property
    def model(self) -> Any:
        """The augmented model as a :class:`~aeromag_env.simulation.config.SimulationConfig`."""
        return self.discovery.model

    @property
    def series(self) -> dict[str, np.ndarray]:
        """``tt``, ``residual_before``, ``residual_after`` (n, 3) [nT] and ``held_out``."""
        return self.discovery.series

    @property
    def drivers(self) -> list[tuple[str, str, np.ndarray]]:
        """Per named effect: its name, its driving channel's name and samples (n,)."""
        return self.discovery.drivers


def discover(
    source: PathLike | Flight,
    out: PathLike | None = None,
    progress: Callable[[str], None] | None = None,
    **options: Any,
) -> DiscoverResult:
    """Find what the model is missing in a flight, as ``aeromag discover`` does.

    Reads and checks the file, chooses the fluxgate and altitude, estimates the fluxgate's mount
    (rotating the fluxgate into body axes when it is applied), selects the lines or segment,
    runs the discrepancy workflow (:func:`aeromag_env.discovery.workflow.discover`) and records
    the provenance; with ``out``, writes the output set (module docstring) atomically.

    Parameters
    ----------
    source : str, PathLike or Flight
        A flight file or a flight in memory (then the report has no input hash or format and
        its ``input`` is null).
    out : str, PathLike or None
        Folder for the output set (None: nothing is written, nothing drawn).
    progress : callable or None
        Called with a short message at each stage.
    **options
        Any field of :class:`DiscoverRequest` past ``out`` (:data:`OPTIONS`): ``flux``,
        ``calibration_window_s``, ``mount``, ``lines``, ``segment_s``, ``calibration_line``,
        ``ground``, ``alpha``, with the command line's defaults.

    Returns
    -------
    DiscoverResult
        The same numbers ``aeromag discover`` writes (``report`` is its ``report.json``).

    Warns
    -----
    AeromagWarning
        Each warning the command line prints (channels, mount, Earth-field check, the report's
        caveats), as it is said; the same lines are in the result's ``warnings``.

    Raises
    ------
    AeromagError
        Unusable options or input (one line), before anything is written.
    """
    unknown = sorted(set(options) - set(OPTIONS))
    if unknown:
        raise AeromagError(
            f"discover: unknown option {unknown[0]!r}; options: {', '.join(OPTIONS)}"
        )
    request = DiscoverRequest(
        source=source if isinstance(source, Flight) else Path(source),
        out=None if out is None else Path(out),
        **options,
    )
    return run_discover(request, JobWarnings(), progress)


def run_discover(
    req: DiscoverRequest, warn: JobWarnings, progress: Callable[[str], None] | None = None
) -> DiscoverResult:
    """Do the work of :func:`discover` for a request; its warnings go to ``warn``."""
    req.check()
    if req.out is not None:
        check_output_set(req.out, req.outputs(), req.input_files())
    flight, problems, path = load_source(req.source, ("tt", "position", "attitude", "date"))
    if path is not None:
        flight.attrs.setdefault("path", str(path))
    inputs = choose_inputs(
        flight,
        path or IN_MEMORY,
        req.flux,
        require=("fluxgate", "altitude"),
        mount=req.mount,
        warn=warn,
        kinds=("fluxgate", "altitude"),
    )
    assert inputs.mount is not None  # a fluxgate is required
    chosen = select(
        inputs.work,
        req.lines,
        req.segment_s,
        req.calibration_line,
        req.calibration_window_s,
    )
    calibration_window = req.calibration_window_s
    if chosen.calibration is not None and "calibration_line" in chosen.report:
        tt = chosen.flight.tt[chosen.calibration]
        calibration_window = (float(tt[0]), float(tt[-1]))
    work = in_body_axes(chosen.flight, inputs.mount)
    result = discover_flight(
        work,
        flux=inputs.flux_name,
        calibration_window=calibration_window,
        alpha=req.alpha,
        progress=progress,
        ground=req.ground,
    )
    report = {
        "report_version": REPORT_VERSION,
        "input": None if path is None else str(path),
        **result.report,
        "input_problems": problems,
        "selection": chosen.report,
        **provenance(path, inputs.work, inputs, earth_model_used=True),
    }
    report = jsonable(report)
    for caveat in report["caveats"]:
        warn(caveat)
    paths: tuple[Path, ...] = ()
    if req.out is not None:
        paths = write_discover_outputs(req, report, result)
    return DiscoverResult(report, tuple(warn.lines), paths, result)


def write_discover_outputs(
    req: DiscoverRequest, report: dict[str, Any], result: Discovery
) -> tuple[Path, ...]:
    """Write the output set (:meth:`DiscoverRequest.outputs`) into ``req.out``, all replaced
    together; the files the run read are never overwritten. Returns the paths written."""
    assert req.out is not None
    model = json.loads(to_json(result.model))
    outputs = req.outputs()
    with output_set(req.out, outputs, req.input_files()) as stage:
        write_text(stage / "report.json", json.dumps(report, indent=2))
        write_text(stage / "report.md", markdown(report))
        write_text(stage / "model_config.json", json.dumps(model, indent=2))
        plot_discovery(result, stage)
        if req.html:
            page = reports.discover_page(report, result.series, result.drivers)
            write_text(stage / reports.PAGE, page)
    return tuple(req.out / name for name in outputs)


def markdown(report: dict[str, Any]) -> str:
    """The report for people: verdict, gap, named effects, candidates, diagnostics."""
    gap, data = report["gap"], report["data"]
    lines = [
        f"# Discrepancy report: {report['input']}",
        "",
        f"**Verdict: {report['verdict']}.**",
        "",
        *[f"**Caveat:** {c}.\n" for c in report.get("caveats", [])],
        f"Held-out gap (measured − simulated, above the {gap['white_noise_floor_nt']:.2f} nT "
        f"white-noise floor): {gap['rms_before_nt']:.3f} nT with the base model → "
        f"{gap['rms_after_nt']:.3f} nT with the named effects ({shrink_text(gap)}); raw RMS "
        f"{gap['raw_rms_before_nt']:.3f} → {gap['raw_rms_after_nt']:.3f} nT. "
        f"Held-out scheme: {gap['held_out_scheme']}.",
        "",
        *_ground_lines(report.get("ground") or {"mode": "ignore"}),
    ]
    lines += _effects_table(report["missing_effects"])
    head = "| effect | channel | regressors | identifiable fraction | verdict |"
    lines += ["## Candidates", "", head, "|---|---|---|---|---|"]
    for c in report["candidates"]:
        frac = c.get("identifiable_fraction")
        lines.append(
            f"| `{c['name']}` | {c.get('channel') or '–'} | {c.get('regressors', '–')} | "
            f"{'–' if frac is None else f'{frac:.3g}'} | {c['verdict']} |"
        )
    for s in report["skipped"]:
        lines.append(f"\n* skipped `{s['name']}`: {s['reason']}")
    d = report["diagnostics"]
    wb, wa = d["whiteness"]["before"], d["whiteness"]["after"]
    lines += [
        "",
        "## Where the base model and the measurement disagree",
        "",
        f"* time: median 60-s block RMS {d['segments']['median_rms_nt']:.2f} nT; "
        f"{len(d['segments']['flagged'])} blocks above twice that",
        f"* spectrum: {len(d['spectrum']['peaks'])} narrow peaks "
        + ", ".join(f"{p['frequency_hz']:.3f} Hz" for p in d["spectrum"]["peaks"]),
        f"* heading: range of the 30° bin means per axis {d['heading_range_nt']} nT",
        "* auxiliary channels (partial correlation with the residual, max over axes): "
        + ", ".join(f"{k} {v['max_abs']:.2f}" for k, v in d["aux_partial_correlation"].items()),
        f"* whiteness (Ljung–Box, 20 lags, whitened residual): p = {wb['p_value']:.2g} before, "
        f"{wa['p_value']:.2g} after",
        "",
        f"Data: {data['samples']} samples, {data['calibration_samples']} calibration, "
        f"{data['held_out_samples']} held out, {data['time_gaps']} time gaps, "
        f"{data['nonfinite_samples_dropped']} non-finite samples dropped.",
    ]
    return "\n".join(lines) + "\n"


def shrink_text(gap: dict[str, Any]) -> str:
    """The gap's shrink factor as text (``∞×`` when the named effects close it: report.json
    holds null there)."""
    shrink = gap["shrink"]
    return "∞×" if shrink is None or shrink == float("inf") else f"{shrink:.2f}×"


def _ground_lines(ground: dict[str, Any]) -> list[str]:
    """The report's paragraph on the magnetic ground."""
    if ground["mode"] == "ignore":
        return [
            "Magnetic ground: ignored (`--ground separate` fits only what it cannot explain).",
            "",
        ]
    lo, hi = ground["knot_spacing_s"] or [float("nan")] * 2
    return [
        f"Magnetic ground: separated ({ground['model']}; {ground['runs']} runs, "
        f"{ground['columns']} columns, knots {lo:.1f}–{hi:.1f} s apart; clearance from "
        f"{ground['clearance_source']}). Every series, fit and gap here is off the ground; "
        f"{ground['base_model']}.",
        "",
    ]


def _effects_table(missing: list[dict[str, Any]]) -> list[str]:
    """The named effects' Markdown: their tests, sizes, held-out gaps and parameters."""
    if not missing:
        return []
    head = (
        "| effect | channel | test | F | log10 p | Holm threshold | ΔBIC "
        "| held-out RMS [nT] | held-out gap without → with it [nT] |"
    )
    lines = ["## Missing effects", "", head, "|---|---|---|---|---|---|---|---|---|"]
    for e in missing:
        ev, g = e["evidence"], e["held_out_gap"]
        test = ev.get("test", "F-test, fixed noise model")
        lines.append(
            f"| `{e['name']}` | {e['channel'] or '–'} | {test} | {ev['f_statistic']:.1f} | "
            f"{ev['log10_p_value']:.1f} | {ev['holm_threshold']:.2g} | {ev['delta_bic']:.0f} | "
            f"{ev['held_out_rms_nt']:.2f} | {g['rms_without_nt']:.3f} → "
            f"{g['rms_with_nt']:.3f} |"
        )
    lines.append("")
    for e in missing:
        lines.append(f"* `{e['name']}` parameters: `{json.dumps(e['physical'])[:400]}`")
    return [*lines, ""]
