"""Fit a compensation model on a calibration flight: :func:`calibrate`, the job of
``aeromag calibrate``.

Outputs in the folder ``out`` (:data:`OUTPUTS`), written as a set
(:func:`aeromag_env.atomic.output_set`): ``model.json`` (the
:class:`~aeromag_env.compensation.calibration_model.CalibrationModel`, which ``aeromag compensate
--model`` and ``aeromag stream --model`` apply to other flights), ``report.json`` (the method,
the calibration's figures of merit box by box, the residual the recalibrate check compares
against, the channels, the mount and the provenance) and ``report.html``
(:func:`aeromag_env.reports.calibrate.calibrate_page`; not with ``html=False``).

Reading, channel choice and the mount are those of ``aeromag compensate``
(:mod:`aeromag_env.jobs.provenance`); the fit is on the whole file, or on its calibration line
(``calibration_line``) or time window (``calibration_window_s``).
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

from aeromag_env import reports
from aeromag_env.atomic import check_output_set, output_set, write_text
from aeromag_env.compensation.calibration_model import CalibrationModel
from aeromag_env.compensation.compensate import Compensation
from aeromag_env.compensation.model_fit import FIT_METHODS, fit_model
from aeromag_env.compensation.tolles_lawson import TollesLawson
from aeromag_env.errors import AeromagError, ArgumentError
from aeromag_env.flight.data import Flight
from aeromag_env.flight.selection import select
from aeromag_env.flight.validation import PathLike
from aeromag_env.jobs.compensate import CompensateRequest
from aeromag_env.jobs.provenance import (
    IN_MEMORY,
    JobWarnings,
    choose_inputs,
    file_sha256,
    load_source,
)
from aeromag_env.jobs.reports import jsonable, report_json
from aeromag_env.version import __version__

#: The output set of a calibration, in the folder ``out``.
OUTPUTS = ("model.json", "report.json", reports.PAGE)


@dataclass(frozen=True, kw_only=True)
class CalibrateRequest:
    """Everything a calibration is asked for (validated by :meth:`check`).

    Attributes
    ----------
    source : Path or Flight
        The calibration flight's file, or a flight in memory.
    out : Path or None
        The folder of the output set (None: nothing written).
    method : str
        One of :data:`~aeromag_env.compensation.model_fit.FIT_METHODS`.
    flux, scalar, mount, tl_bandpass_hz, tl_trim, tl_ridge, filter_preset, r_std_nt, html
        As :class:`~aeromag_env.jobs.compensate.CompensateRequest` takes them.
    calibration_window_s : (float, float) or None
        Fit on T0 ≤ tt ≤ T1 [s] only.
    calibration_line : str or None
        Fit on this flight line (``auto``: the calibration box's).
    """

    source: Path | Flight
    out: Path | None
    method: str
    flux: str = "auto"
    scalar: str = "auto"
    mount: str = "auto"
    tl_bandpass_hz: tuple[float, float] | None = (0.1, 0.9)
    tl_trim: int = 20
    tl_ridge: float = 0.0
    calibration_window_s: tuple[float, float] | None = None
    calibration_line: str | None = None
    filter_preset: str = "default"
    r_std_nt: float | None = None
    html: bool = True

    def check(self) -> None:
        """One-line errors for unusable options (before any file is read), each naming the
        argument (:class:`~aeromag_env.errors.ArgumentError`)."""
        if self.method not in FIT_METHODS:
            raise ArgumentError("method", f"must be one of {', '.join(FIT_METHODS)}", self.method)
        self.fit().check()

    def fit(self) -> CompensateRequest:
        """The same options as a compensation's request (what reading, choosing the channels
        and the mount, and the method's settings take)."""
        shared = {f.name: getattr(self, f.name) for f in fields(self)}
        return CompensateRequest(**shared)

    def outputs(self) -> tuple[str, ...]:
        """The output set: :data:`OUTPUTS`, without the page when ``html`` is off."""
        return OUTPUTS if self.html else OUTPUTS[:2]


#: The options :func:`calibrate` takes by keyword: the fields of :class:`CalibrateRequest` but
#: the source, the method and the output folder.
OPTIONS = tuple(
    f.name for f in fields(CalibrateRequest) if f.name not in ("source", "method", "out")
)


@dataclass(frozen=True)
class CalibrationResult:
    """What :func:`calibrate` produced.

    Attributes
    ----------
    model : CalibrationModel
        The fitted model: ``model.apply(flight)``, ``model.stream()``, ``model.save(path)``.
    report : dict
        What ``report.json`` holds.
    warnings : tuple of str
        The warnings the run said, one line each.
    paths : tuple of Path
        The files written (empty without ``out``).
    compensation : Compensation
        The calibration flight compensated by the fit.
    flight : Flight
        The calibration flight as fitted (the selected part).
    """

    model: CalibrationModel
    report: dict[str, Any]
    warnings: tuple[str, ...]
    paths: tuple[Path, ...]
    compensation: Compensation
    flight: Flight


def calibrate(
    source: PathLike | Flight,
    method: str = "tl",
    out: PathLike | None = None,
    **options: Any,
) -> CalibrationResult:
    """Fit a compensation model on a calibration flight, as ``aeromag calibrate`` does.

    Parameters
    ----------
    source : str, PathLike or Flight
        The calibration flight (a file or a flight in memory).
    method : str
        ``tl`` (Tolles–Lawson) or a recursive filter (``kf``, ``fakf``, ``rls``,
        ``sage-husa``, ``ding``).
    out : str, PathLike or None
        Folder for ``model.json``, ``report.json`` and ``report.html`` (None: nothing written).
    **options
        :data:`OPTIONS`, as ``aeromag compensate`` takes them: ``calibration_line`` (a line id,
        or ``auto`` for the calibration box's), ``calibration_window_s`` (T0, T1) [s], ``flux``,
        ``scalar``, ``mount``, ``tl_bandpass_hz``, ``tl_trim``, ``tl_ridge``,
        ``filter_preset``, ``r_std_nt``, ``html``.

    Returns
    -------
    CalibrationResult

    Raises
    ------
    AeromagError
        Unusable options or input (one line), before anything is written.
    """
    unknown = sorted(set(options) - set(OPTIONS))
    if unknown:
        raise AeromagError(
            f"calibrate: unknown option {unknown[0]!r}; options: {', '.join(OPTIONS)}"
        )
    req = CalibrateRequest(
        source=source if isinstance(source, Flight) else Path(source),
        out=None if out is None else Path(out),
        method=method,
        **options,
    )
    return run_calibrate(req, JobWarnings())


def run_calibrate(req: CalibrateRequest, warn: JobWarnings) -> CalibrationResult:
    """Do the work of :func:`calibrate` for a request; its warnings go to ``warn``."""
    req.check()
    fit = req.fit()
    if req.out is not None:
        check_output_set(req.out, req.outputs(), fit.input_files())
    flight, problems, path = load_source(req.source, fit.needs())
    inputs = choose_inputs(
        flight,
        path or IN_MEMORY,
        req.flux,
        req.scalar,
        fit.required_channels(),
        req.mount,
        mount_matters=req.method != "tl",
        warn=warn,
    )
    chosen = select(inputs.work, None, None, req.calibration_line, req.calibration_window_s)
    given = {
        "input": None if path is None else str(path),
        "input_sha256": None if path is None else file_sha256(path),
        "package_version": __version__,
    }
    model, comp = fit_model(
        chosen.flight,
        req.method,
        flux=inputs.flux_name,
        scalar=inputs.scalar_name if req.method == "tl" else None,
        mount=inputs.mount.mount if inputs.mount and req.method != "tl" else None,
        calibration=chosen.calibration,
        tl=_tl(req) if req.method == "tl" else None,
        filter_cfg=None if req.method == "tl" else fit.filter_config(),
        provenance=given,
    )
    report = calibration_report(model, problems, chosen.report, tuple(warn.lines))
    paths: tuple[Path, ...] = ()
    if req.out is not None:
        paths = _write(req, fit.input_files(), model, report, chosen.flight, comp)
    return CalibrationResult(model, report, tuple(warn.lines), paths, comp, chosen.flight)


def _tl(req: CalibrateRequest) -> TollesLawson:
    return TollesLawson(bandpass_hz=req.tl_bandpass_hz, trim=req.tl_trim, ridge=req.tl_ridge)


def calibration_report(
    model: CalibrationModel,
    problems: list[str],
    selection: dict[str, Any],
    warnings: tuple[str, ...],
) -> dict[str, Any]:
    """The ``report.json`` of a calibration: the model's figures and where they came from."""
    cal = dict(model.calibration)
    cal["box_count"] = len(cal.get("fom_boxes") or [])
    return {
        "report_version": 1,
        "input": model.provenance.get("input"),
        "method": model.method,
        "calibration": cal,
        "model_summary": {
            "channels": model.channels,
            "sample_rate_hz": model.sample_rate_hz,
            "settings": model.settings,
            "coefficients": model.coefficients
            if model.method == "tl"
            else {"state": model.coefficients["state"]},
            "spike_threshold_nt": model.spike_threshold_nt,
        },
        "mount": model.mount,
        "selection": selection,
        "input_problems": problems,
        "warnings": list(warnings),
        "provenance": model.provenance,
    }


def _write(
    req: CalibrateRequest,
    inputs: list[Path],
    model: CalibrationModel,
    report: dict[str, Any],
    flight: Flight,
    comp: Compensation,
) -> tuple[Path, ...]:
    """Write the output set into ``req.out``, all replaced together (never over ``inputs``)."""
    assert req.out is not None
    outputs = req.outputs()
    with output_set(req.out, outputs, inputs) as stage:
        write_text(stage / "model.json", model.to_json())
        write_text(stage / "report.json", report_json(report))
        if req.html:
            arrays = reports.compensate_arrays(flight, comp)
            write_text(stage / reports.PAGE, reports.calibrate_page(jsonable(report), arrays))
    return tuple(req.out / name for name in outputs)
