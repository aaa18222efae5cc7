"""``aeromag compensate``: read a flight, compensate it with one method, write the results.

Outputs in the folder ``out``: ``compensated.h5`` (the input's fields plus the compensated
ones), ``report.json`` (``method``, ``settings``, ``coefficients``, ``metrics``, the provenance
blocks of :func:`aeromag_env.cli.provenance.provenance` — input hash and format, channels, mount,
segments, flagged samples, flight date, Earth model — and the real-data accuracy blocks
``headline`` and, when the file has the vendor's compensated channel, ``vendor_comparison``) and
``compensation.png`` and ``report.html`` (:mod:`aeromag_env.reports`; not with ``html`` off)
(:data:`OUTPUTS`), written as a set (:func:`aeromag_env.atomic.output_set`):
refused before the work if a target is an input, and all replaced together at the end.

The fluxgate, scalar and altitude channels are chosen by :mod:`aeromag_env.flight.channels`
(``--flux``/``--scalar`` ``auto`` by default) and the fluxgate's mount by
:mod:`aeromag_env.flight.mount_choice` (``--mount auto`` by default).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from aeromag_env import reports
from aeromag_env.atomic import check_output_set, output_set, write_text
from aeromag_env.cli.provenance import (
    Inputs,
    Warn,
    choose_inputs,
    provenance,
    warn_stderr,
)
from aeromag_env.compensation.compensate import (
    FILTER_METHODS,
    Compensation,
    compensate_scalar,
    compensate_vector,
    held_out_rmse,
    score,
)
from aeromag_env.compensation.model import FilterConfig, paper_filter_config
from aeromag_env.compensation.real_metrics import headline, span_figures, vendor_comparison
from aeromag_env.compensation.tolles_lawson import TollesLawson
from aeromag_env.errors import AeromagError
from aeromag_env.flight.data import Flight
from aeromag_env.flight.files import load_flight, write_flight
from aeromag_env.flight.selection import select

#: 2: provenance (input_sha256, input_format, channels, mount, segments, flagged_samples,
#: flight_date, earth_model) and the headline / vendor_comparison blocks.
REPORT_VERSION = 2
#: The output set of ``aeromag compensate``, in the folder ``--out``.
OUTPUTS = ("compensated.h5", "report.json", "compensation.png", reports.PAGE)


@dataclass(frozen=True, kw_only=True)
class CompensateRequest:
    """Everything ``aeromag compensate`` was asked for (validated by :meth:`check`)."""

    path: Path
    out: Path
    method: str
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
    html: bool = True  # report.html beside report.json

    def check(self) -> None:
        """One-line errors for unusable options (before any file is read)."""
        if self.tl_bandpass_hz is not None:
            lo, hi = self.tl_bandpass_hz
            if not (0 <= lo < hi):
                raise AeromagError(f"--tl-bandpass needs 0 ≤ LOW < HIGH [Hz], got {lo} {hi}")
        if self.tl_trim < 0:
            raise AeromagError(f"--tl-trim must be ≥ 0, got {self.tl_trim}")
        if self.tl_ridge < 0:
            raise AeromagError(f"--tl-ridge must be ≥ 0, got {self.tl_ridge}")
        if self.calibration_window_s is not None and not (
            self.calibration_window_s[0] < self.calibration_window_s[1]
        ):
            raise AeromagError("--calibration-window needs T0 < T1 [s]")
        if self.r_std_nt is not None and not self.r_std_nt > 0:
            raise AeromagError(f"--r-std-nt must be > 0, got {self.r_std_nt}")

    def outputs(self) -> tuple[str, ...]:
        """The output set: :data:`OUTPUTS`, without the page when ``html`` is off."""
        return OUTPUTS if self.html else tuple(n for n in OUTPUTS if n != reports.PAGE)

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
        """The files the run reads: the flight and a ``--mount`` file."""
        mount = [] if self.mount in ("auto", "identity") else [Path(self.mount)]
        return [self.path, *mount]

    def filter_config(self) -> FilterConfig:
        """The filter settings: the package defaults or the paper's §4 setting."""
        cfg = paper_filter_config(self.method) if self.filter_preset == "paper" else FilterConfig()
        if self.r_std_nt is not None:
            cfg = replace(cfg, r_std_nt=self.r_std_nt)
        return cfg


def run_compensate(req: CompensateRequest, warn: Warn = warn_stderr) -> dict[str, Any]:
    """Do the work of ``aeromag compensate``; return the report (also written to disk).

    Warnings about the channels and the mount go to ``warn``, one line each (stderr)."""
    req.check()
    check_output_set(req.out, req.outputs(), req.input_files())
    flight, problems = load_flight(req.path, needs=req.needs())
    # channels and mount from the whole flight (the mount is the installation's, and a single
    # line may turn too little to show it), then the selected part
    inputs = choose_inputs(
        flight,
        req.path,
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
    work, flux, calibration = chosen.flight, inputs.flux_name, chosen.calibration
    if req.method == "tl":
        tl = TollesLawson(bandpass_hz=req.tl_bandpass_hz, trim=req.tl_trim, ridge=req.tl_ridge)
        scalar = inputs.scalar_name
        assert scalar is not None  # a required channel of tl
        comp = compensate_scalar(work, flux, scalar, tl, calibration)
    else:
        cfg = req.filter_config() if req.method in FILTER_METHODS else None
        mount = inputs.mount.mount if inputs.mount else None
        comp = compensate_vector(work, req.method, flux, cfg, calibration, mount=mount)
    _check_output_names(flight, comp)
    metrics_block = score(work, comp)
    report = {
        "report_version": REPORT_VERSION,
        "input": str(req.path),
        "method": comp.method,
        "settings": comp.settings,
        "coefficients": comp.coefficients,
        "metrics": metrics_block,
        "nonfinite_policy": _nonfinite_policy(comp),
        "input_problems": problems,
        "selection": chosen.report,
        **_provenance_blocks(req.path, work, inputs, comp, metrics_block),
        "held_out": _held_out(work, comp, calibration),
    }
    kept = {name: values[chosen.keep] for name, values in flight.fields.items()}
    out_flight = Flight({**kept, **comp.fields}, {**flight.attrs, "compensation": comp.method})
    from aeromag_env.compensation.plots import plot_compensation

    with output_set(req.out, req.outputs(), req.input_files()) as stage:
        write_flight(out_flight, stage / "compensated.h5")
        write_text(stage / "report.json", json.dumps(_jsonable(report), indent=2))
        plot_compensation(work, comp, metrics_block, stage / "compensation.png")
        if req.html:
            page = reports.compensate_page(_jsonable(report), reports.compensate_arrays(work, comp))
            write_text(stage / reports.PAGE, page)
    return report


def _provenance_blocks(
    path: Path, flight: Flight, inputs: Inputs, comp: Compensation, metrics_block: dict[str, Any]
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


def _check_output_names(flight: Flight, comp: Compensation) -> None:
    """One-line error when an output channel would replace a field of the input file."""
    clash = [nm for nm in comp.fields if nm in flight]
    if clash:
        raise AeromagError(
            f"the input already has field(s) {', '.join(clash)}, which compensate writes; "
            "refusing to replace an input field (rename or drop them in the input first)"
        )


def _nonfinite_policy(comp: Compensation) -> str:
    flagged = "flagged samples (a non-finite input, or a spike in the magnetometer used) are"
    rest = "outputs there are NaN; the rate, band-passes and filters restart at each time gap"
    if comp.method in FILTER_METHODS:
        return f"{flagged} skipped by the filter (predict only); {rest}"
    return f"{flagged} left out of the fit; {rest}"


def _jsonable(obj: Any) -> Any:
    """Replace NaN/inf by None so that report.json is strict JSON."""
    if isinstance(obj, dict):
        return {k: _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, (float, np.floating)):
        return float(obj) if np.isfinite(obj) else None
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


#: Said after the RMSE against a simulated truth when a fluxgate mount was applied: the truth
#: is in body axes, and the fit absorbs the mount's residual rotation (0.07° is ~65 nT on a
#: 53 000 nT field) as induced terms, which the compensated total field does not show.
MOUNT_RMSE_NOTE = (
    " (against the simulated truth in body axes: it includes what the fit "
    "absorbed of the applied mount's error, which the IR does not show)"
)


def summary_line(report: dict[str, Any], out: Path) -> str:
    """One line for the terminal (input problems are listed in report.json)."""
    m = report["metrics"]
    page = ", report.html" if (out / reports.PAGE).exists() else ""
    parts = [f"{report['method']}: wrote {out}/compensated.h5, report.json, compensation.png{page}"]
    for key, label in (
        ("compensation_rmse_nt", "RMSE (2nd half)"),
        ("improvement_ratio", "IR"),
        ("fom_nt", "FOM"),
    ):
        if m.get(key) is not None:
            parts.append(f"{label} {m[key]:.3g}" + (" nT" if key != "improvement_ratio" else ""))
    mount = report.get("mount") or {}
    if m.get("compensation_rmse_nt") is not None and mount.get("applied"):
        parts[1] += MOUNT_RMSE_NOTE
    head = report.get("headline") or {}
    if m.get("fom_nt") is None and head.get("fom_nt") is not None:
        parts.append(f"FOM {head['fom_nt']:.3g} nT (box detected from the attitude)")
    held = report.get("held_out") or {}
    if held.get("improvement_ratio") is not None:
        parts.append(f"IR {held['improvement_ratio']:.3g} outside the calibration part")
    vendor = report.get("vendor_comparison") or {}
    if vendor.get("improvement_ratio_vendor") is not None:
        parts.append(
            f"vendor's {vendor['vendor_channel']} IR {vendor['improvement_ratio_vendor']:.3g}"
        )
    if m["nonfinite_samples"]:
        parts.append(f"{m['nonfinite_samples']} non-finite samples ({report['nonfinite_policy']})")
    if m["divergences"]:
        fell_back = (
            " (a runaway makes an adaptive filter the plain kf)"
            if report.get("method") in ("fakf", "ding", "sage-husa")
            else ""
        )
        parts.append(f"{m['divergences']} divergences detected and recovered{fell_back}")
    if m.get("outliers_rejected"):
        parts.append(
            f"{m['outliers_rejected']} samples rejected by the filter's outlier gate (predict only)"
        )
    if report["input_problems"]:
        parts.append(
            f"{len(report['input_problems'])} input warning(s), listed in report.json "
            "(aeromag info explains them)"
        )
    return "; ".join(parts)
