"""Compensate a flight file with one method: :func:`compensate`, the job of ``aeromag compensate``.

Outputs in the folder ``out`` (when one is given): ``compensated.h5`` (the input's fields plus
the compensated ones), ``report.json`` (``method``, ``settings``, ``coefficients``, ``metrics``,
the provenance blocks of :func:`aeromag_env.jobs.provenance.provenance` — input hash and format,
channels, mount, segments, flagged samples, flight date, Earth model — and the real-data accuracy
blocks ``headline`` and, when the file has the vendor's compensated channel,
``vendor_comparison``), ``compensation.png`` and ``report.html`` (:mod:`aeromag_env.reports`;
not with ``html=False``) (:data:`OUTPUTS`), written as a set
(:func:`write_compensate_outputs`, :func:`aeromag_env.atomic.output_set`): refused before the
work if a target is an input, and all replaced together at the end.

The fluxgate, scalar and altitude channels are chosen by :mod:`aeromag_env.flight.channels`
(``flux``/``scalar`` ``auto`` by default) and the fluxgate's mount by
:mod:`aeromag_env.flight.mount_choice` (``mount="auto"`` by default).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from aeromag_env.atomic import check_output_set
from aeromag_env.compensation.calibration_model import CalibrationModel
from aeromag_env.compensation.compensate import (
    FILTER_METHODS,
    METHODS,
    Compensation,
    compensate_scalar,
    compensate_vector,
    held_out_rmse,
    score,
)
from aeromag_env.compensation.model import FilterConfig, paper_filter_config
from aeromag_env.compensation.real_metrics import headline, span_figures, vendor_comparison
from aeromag_env.compensation.tolles_lawson import TollesLawson
from aeromag_env.errors import AeromagError, ArgumentError
from aeromag_env.flight.data import Flight
from aeromag_env.flight.selection import select
from aeromag_env.flight.validation import PathLike
from aeromag_env.jobs.apply_model import (
    check_model_request,
    model_block,
    model_needs,
    model_of,
    model_warnings,
)
from aeromag_env.jobs.choices import FILTER_PRESETS
from aeromag_env.jobs.compensate_output import (
    OUTPUTS,
    REPORT_VERSION,
    CompensationResult,
    OutputTarget,
    check_output_names,
    nonfinite_policy,
    outputs,
    write_compensate_outputs,
)
from aeromag_env.jobs.limits import (
    MAX_TL_TRIM,
    R_STD_RANGE_NT,
    check_bandpass,
    check_calibration_line,
    check_count,
    check_lines,
    check_nonnegative,
    check_number,
    check_window,
)
from aeromag_env.jobs.provenance import (
    IN_MEMORY,
    Inputs,
    JobWarnings,
    choose_inputs,
    file_sha256,
    input_format,
    load_source,
    provenance,
)

__all__ = [
    "OPTIONS",
    "OUTPUTS",
    "REPORT_VERSION",
    "CompensateRequest",
    "CompensationResult",
    "compensate",
    "run_compensate",
]


@dataclass(frozen=True, kw_only=True)
class CompensateRequest:
    """Everything a compensation is asked for (validated by :meth:`check`).

    Attributes
    ----------
    source : Path or Flight
        The flight file, or a flight in memory.
    out : Path or None
        The folder of the output set (None: nothing written).
    method : str or None
        One of :data:`~aeromag_env.compensation.compensate.METHODS`; with a ``model``, None or
        the model's method.
    flux, scalar : str
        The fluxgate and scalar magnetometer ids, or ``auto`` (the first clean one).
    mount : str
        ``auto`` (estimate, apply beyond 1°), ``identity`` or a JSON mount file
        (:mod:`aeromag_env.flight.mount_choice`).
    tl_bandpass_hz : (float, float) or None
        ``tl``'s band-pass LOW, HIGH [Hz]; None for none.
    tl_trim : int
        ``tl``: samples trimmed at each end of each run.
    tl_ridge : float
        ``tl``'s ridge parameter λ [-].
    calibration_window_s : (float, float) or None
        Fit on T0 ≤ tt ≤ T1 [s] only, apply everywhere.
    calibration_line : str or None
        Fit on this flight line (``auto``: the calibration box's), apply to the selection.
    lines : tuple of float or None
        The flight lines to compensate (with the calibration part).
    segment_s : (float, float) or None
        The time span T0, T1 [s] to compensate.
    filter_preset : str
        ``default`` or ``paper`` (the paper's §4 Q(0), R(0), x(0)).
    r_std_nt : float or None
        The filter's measurement-noise std [nT] (None: the preset's).
    html : bool
        Write ``report.html`` (:mod:`aeromag_env.reports`) with the set.
    model : Path, CalibrationModel or None
        Apply this calibrated model (``aeromag calibrate``'s ``model.json``) instead of fitting
        on the flight (:mod:`aeromag_env.jobs.apply_model`); ``method`` is then the model's.
    """

    source: Path | Flight
    out: Path | None
    method: str | None
    flux: str = "auto"
    scalar: str = "auto"
    mount: str = "auto"
    tl_bandpass_hz: tuple[float, float] | None = (0.1, 0.9)
    tl_trim: int = 20
    tl_ridge: float = 0.0
    calibration_window_s: tuple[float, float] | None = None
    calibration_line: str | None = None  # "auto" or a line id
    lines: tuple[float, ...] | None = None
    segment_s: tuple[float, float] | None = None
    filter_preset: str = "default"
    r_std_nt: float | None = None
    html: bool = True
    model: Path | CalibrationModel | None = None

    @property
    def path(self) -> Path | None:
        """The flight file (None for a flight given in memory)."""
        return None if isinstance(self.source, Flight) else self.source

    def check(self) -> None:
        """One-line errors for unusable options (before any file is read), each naming the
        argument (:class:`~aeromag_env.errors.ArgumentError`); with a ``model``, its file is
        read and checked against the options (:func:`~aeromag_env.jobs.apply_model.
        check_model_request`)."""
        if self.model is not None:
            check_model_request(
                model_of(self.model), self.method, self.calibration_line, self.calibration_window_s
            )
        elif self.method not in METHODS:
            raise ArgumentError("method", f"must be one of {', '.join(METHODS)}", self.method)
        if self.filter_preset not in FILTER_PRESETS:
            raise ArgumentError(
                "filter_preset", f"must be one of {', '.join(FILTER_PRESETS)}", self.filter_preset
            )
        check_bandpass("tl_bandpass_hz", self.tl_bandpass_hz)
        check_count("tl_trim", self.tl_trim, 0, MAX_TL_TRIM, "samples", "trimmed at each end")
        check_nonnegative("tl_ridge", self.tl_ridge, "(λ, unitless)")
        check_window("calibration_window_s", self.calibration_window_s)
        check_lines("lines", self.lines)
        check_window("segment_s", self.segment_s)
        check_calibration_line("calibration_line", self.calibration_line)
        if self.r_std_nt is not None:
            lo, hi = R_STD_RANGE_NT
            check_number(
                "r_std_nt",
                self.r_std_nt,
                lo,
                hi,
                "nT",
                "a magnetometer's noise floor to above the Earth's field",
            )

    def outputs(self) -> tuple[str, ...]:
        """The output set: :data:`OUTPUTS`, without the page when ``html`` is off."""
        return outputs(self.html)

    def target(self) -> OutputTarget:
        """Where the output set goes (``out`` must be set)."""
        assert self.out is not None
        return OutputTarget(out=self.out, html=self.html, inputs=self.input_files())

    def needs(self) -> tuple[str, ...]:
        """Fields the method reads besides its magnetometers (chosen after reading: ``tl``
        needs only time, the fluxgate and the scalar)."""
        if self.method == "tl":
            return ("tt",)
        return ("tt", "position", "attitude", "date")

    def required_channels(self) -> tuple[str, ...]:
        """Channel kinds (:data:`aeromag_env.flight.channels.KINDS`) the method needs."""
        return ("fluxgate", "scalar") if self.method == "tl" else ("fluxgate", "altitude")

    def input_files(self) -> list[Path]:
        """The files the run reads: the flight, a mount file, a model file."""
        mount = [] if self.mount in ("auto", "identity") else [Path(self.mount)]
        model = [Path(self.model)] if isinstance(self.model, str | Path) else []
        return [*([] if self.path is None else [self.path]), *mount, *model]

    def filter_config(self) -> FilterConfig:
        """The filter settings: the package defaults or the paper's §4 setting."""
        cfg = FilterConfig()
        if self.filter_preset == "paper" and self.method is not None:
            cfg = paper_filter_config(self.method)
        if self.r_std_nt is not None:
            cfg = replace(cfg, r_std_nt=self.r_std_nt)
        return cfg


#: The options :func:`compensate` takes by keyword: the fields of :class:`CompensateRequest`
#: but the source, the method and the output folder (its positional arguments).
OPTIONS = tuple(
    f.name
    for f in dataclasses.fields(CompensateRequest)
    if f.name not in ("source", "method", "out")
)


def compensate(
    source: PathLike | Flight,
    method: str | None = None,
    out: PathLike | None = None,
    **options: Any,
) -> CompensationResult:
    """Compensate a flight with one method, as ``aeromag compensate`` does, and score it.

    Reads and checks the file, chooses the fluxgate, scalar and altitude channels, estimates the
    fluxgate's mount (and applies it when it is more than 1° from the body axes), selects the
    lines or segment, flags gaps and spikes, compensates, scores, and records the provenance;
    with ``out``, writes the output set (module docstring) atomically.

    Parameters
    ----------
    source : str, PathLike or Flight
        A flight file (HDF5, CSV, Geosoft XYZ or MATLAB ``.mat``) or a flight in memory (then
        the report has no input hash or format and its ``input`` is null).
    method : str or None
        One of :data:`~aeromag_env.compensation.compensate.METHODS` (None: ``tl``, or with a
        ``model`` the model's).
    out : str, PathLike or None
        Folder for ``compensated.h5``, ``report.json`` and ``compensation.png`` (None: nothing
        is written, the plot is not drawn).
    **options
        Any field of :class:`CompensateRequest` past ``method`` (:data:`OPTIONS`): ``flux``,
        ``scalar``, ``mount``, ``tl_bandpass_hz``, ``calibration_line``…, with the command
        line's defaults.

    Returns
    -------
    CompensationResult
        The same numbers ``aeromag compensate`` writes (``report`` is its ``report.json``).

    Warns
    -----
    AeromagWarning
        Each warning the command line prints (a channel chosen or doubted, the mount, the
        Earth-field check), as it is said; the same lines are in the result's ``warnings``.

    Raises
    ------
    AeromagError
        Unusable options or input (one line), before anything is written.
    """
    unknown = sorted(set(options) - set(OPTIONS))
    if unknown:
        raise AeromagError(
            f"compensate: unknown option {unknown[0]!r}; options: {', '.join(OPTIONS)}"
        )
    if method is None and options.get("model") is None:
        method = "tl"
    request = CompensateRequest(
        source=source if isinstance(source, Flight) else Path(source),
        out=None if out is None else Path(out),
        method=method,
        **options,
    )
    return run_compensate(request, JobWarnings())


def run_compensate(req: CompensateRequest, warn: JobWarnings) -> CompensationResult:
    """Do the work of :func:`compensate` for a request; its warnings go to ``warn``."""
    req.check()
    if req.model is not None:
        return _run_with_model(req, warn)
    if req.out is not None:
        check_output_set(req.out, req.outputs(), req.input_files())
    flight, problems, path = load_source(req.source, req.needs())
    # channels and mount from the whole flight (the mount is the installation's, and a single
    # line may turn too little to show it), then the selected part
    inputs = choose_inputs(
        flight,
        path or IN_MEMORY,
        req.flux,
        req.scalar,
        req.required_channels(),
        req.mount,
        mount_matters=req.method != "tl",
        warn=warn,
    )
    chosen = select(
        inputs.work, req.lines, req.segment_s, req.calibration_line, req.calibration_window_s
    )
    work, calibration = chosen.flight, chosen.calibration
    comp = _compensate(req, work, inputs, calibration)
    check_output_names(flight, comp)
    metrics_block = score(work, comp)
    report = {
        "report_version": REPORT_VERSION,
        "input": None if path is None else str(path),
        "method": comp.method,
        "settings": comp.settings,
        "coefficients": comp.coefficients,
        "metrics": metrics_block,
        "nonfinite_policy": nonfinite_policy(comp),
        "input_problems": problems,
        "selection": chosen.report,
        **_provenance_blocks(path, work, inputs, comp, metrics_block),
        "held_out": _held_out(work, comp, calibration),
    }
    kept = {name: values[chosen.keep] for name, values in flight.fields.items()}
    out_flight = Flight({**kept, **comp.fields}, {**flight.attrs, "compensation": comp.method})
    paths: tuple[Path, ...] = ()
    if req.out is not None:
        paths = write_compensate_outputs(req.target(), out_flight, report, work, comp)
    return CompensationResult(
        method=comp.method,
        metrics=metrics_block,
        coefficients=comp.coefficients,
        report=report,
        warnings=tuple(warn.lines),
        paths=paths,
        compensation=comp,
        flight=out_flight,
    )


def _run_with_model(req: CompensateRequest, warn: JobWarnings) -> CompensationResult:
    """:func:`run_compensate` for a request with a calibrated ``model``: read and check the file
    as a fit does, select the lines or segment, apply the model (nothing is fitted), say when it
    no longer fits (:func:`~aeromag_env.jobs.apply_model.model_warnings`), score and write the
    same output set, with the report's ``model`` block."""
    assert req.model is not None
    model = model_of(req.model)
    if req.out is not None:
        check_output_set(req.out, req.outputs(), req.input_files())
    flight, problems, path = load_source(req.source, model_needs(model))
    chosen = select(flight, req.lines, req.segment_s, None, None)
    work = chosen.flight
    comp = model.apply(work)
    check_output_names(flight, comp)
    what = str(path) if path is not None else "this flight"
    drift = comp.settings["drift"]
    for line in model_warnings(model, work, drift, what):
        warn(line)
    metrics_block = score(work, comp)
    report = {
        "report_version": REPORT_VERSION,
        "input": None if path is None else str(path),
        "input_sha256": None if path is None else file_sha256(path),
        "input_format": None if path is None else input_format(path),
        "method": comp.method,
        "settings": comp.settings,
        "coefficients": comp.coefficients,
        "metrics": metrics_block,
        "nonfinite_policy": nonfinite_policy(comp, applied=True),
        "input_problems": problems,
        "selection": chosen.report,
        "model": model_block(req.model, model, drift),
        "warnings": list(warn.lines),
        "held_out": None,
        **_accuracy_blocks(work, comp, model, metrics_block),
    }
    kept = {name: values[chosen.keep] for name, values in flight.fields.items()}
    out_flight = Flight({**kept, **comp.fields}, {**flight.attrs, "compensation": comp.method})
    paths: tuple[Path, ...] = ()
    if req.out is not None:
        paths = write_compensate_outputs(req.target(), out_flight, report, work, comp)
    return CompensationResult(
        method=comp.method,
        metrics=metrics_block,
        coefficients=comp.coefficients,
        report=report,
        warnings=tuple(warn.lines),
        paths=paths,
        compensation=comp,
        flight=out_flight,
    )


def _accuracy_blocks(
    flight: Flight, comp: Compensation, model: CalibrationModel, metrics_block: dict[str, Any]
) -> dict[str, Any]:
    """The real-data accuracy blocks of a model's application (``headline``, and
    ``vendor_comparison`` when the file has the vendor's compensated scalar), as a fit's."""
    scalar: str | None = model.channels.get("scalar")
    vendor = None
    if scalar:
        ours = scalar if comp.method == "tl" else str(model.channels["flux"])
        vendor = vendor_comparison(flight, scalar, comp.total_before, comp.total_after, ours)
    return {
        "headline": headline(
            flight, comp.total_before, comp.total_after, metrics_block.get("fom_nt")
        ),
        "vendor_comparison": vendor,
    }


def _compensate(
    req: CompensateRequest, work: Flight, inputs: Inputs, calibration: np.ndarray | None
) -> Compensation:
    """The method on the selected flight, with the chosen channels and mount."""
    assert req.method is not None  # checked: a request without a model names its method
    flux = inputs.flux_name
    if req.method == "tl":
        tl = TollesLawson(bandpass_hz=req.tl_bandpass_hz, trim=req.tl_trim, ridge=req.tl_ridge)
        scalar = inputs.scalar_name
        assert scalar is not None  # a required channel of tl
        return compensate_scalar(work, flux, scalar, tl, calibration)
    cfg = req.filter_config() if req.method in FILTER_METHODS else None
    mount = inputs.mount.mount if inputs.mount else None
    # the mount was chosen (and warned about) above: no second check
    return compensate_vector(
        work, req.method, flux, cfg, calibration, mount=mount, check_mount=False
    )


def _provenance_blocks(
    path: Path | None,
    flight: Flight,
    inputs: Inputs,
    comp: Compensation,
    metrics_block: dict[str, Any],
) -> dict[str, Any]:
    """Provenance, ``headline`` and ``vendor_comparison`` (when the file has the vendor's
    compensated scalar); ``segments`` / ``flagged_samples`` only if the metrics lack them."""
    blocks = provenance(path, flight, inputs, earth_model_used=comp.model_total is not None)
    for key in ("segments", "flagged_samples"):
        if key in metrics_block:
            del blocks[key]
    ours = (inputs.scalar_name if comp.method == "tl" else None) or inputs.flux_name
    blocks["headline"] = headline(
        flight, comp.total_before, comp.total_after, metrics_block.get("fom_nt")
    )
    blocks["vendor_comparison"] = (
        vendor_comparison(flight, inputs.scalar_name, comp.total_before, comp.total_after, ours)
        if inputs.scalar_name
        else None
    )
    return blocks


def _held_out(
    flight: Flight, comp: Compensation, calibration: np.ndarray | None
) -> dict[str, Any] | None:
    """With a calibration part, the figures of the samples the fit did not see (the industry's
    check: fitted on the box, judged on the lines): band-passed stds and IR, and the RMSE
    against the truth on simulated files."""
    if calibration is None:
        return None
    rest = ~calibration
    return {
        "span": "outside the calibration part",
        **span_figures(flight, comp.total_before, comp.total_after, rest),
        "compensation_rmse_nt": held_out_rmse(flight, comp, rest),
    }
