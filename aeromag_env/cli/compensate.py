"""``aeromag compensate``: read a flight, compensate it with one method, write the results.

Outputs in the folder ``out``: ``compensated.h5`` (the input's fields plus the compensated
ones), ``report.json`` (``method``, ``settings``, ``coefficients``, ``metrics``) and
``compensation.png``. Every file is written atomically; the input is never overwritten.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from aeromag_env.atomic import write_text
from aeromag_env.compensation.compensate import (
    FILTER_METHODS,
    Compensation,
    compensate_scalar,
    compensate_vector,
    score,
)
from aeromag_env.compensation.model import FilterConfig, paper_filter_config
from aeromag_env.compensation.tolles_lawson import TollesLawson
from aeromag_env.errors import AeromagError
from aeromag_env.flight.data import Flight
from aeromag_env.flight.files import load_flight, write_flight

REPORT_VERSION = 1


@dataclass(frozen=True, kw_only=True)
class CompensateRequest:
    """Everything ``aeromag compensate`` was asked for (validated by :meth:`check`)."""

    path: Path
    out: Path
    method: str
    flux: str = "flux_a"
    scalar: str = "mag_1_uc"
    tl_bandpass_hz: tuple[float, float] | None = (0.1, 0.9)
    tl_trim: int = 20
    tl_ridge: float = 0.0
    calibration_window_s: tuple[float, float] | None = None
    filter_preset: str = "default"
    r_std_nt: float | None = None

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

    def needs(self) -> tuple[str, ...]:
        """Fields the method reads (``tl`` needs only time, the fluxgate and the scalar)."""
        if self.method == "tl":
            return ("tt", self.flux, self.scalar)
        return ("tt", self.flux, "position", "attitude", "date")

    def filter_config(self) -> FilterConfig:
        """The filter settings: the package defaults or the paper's §4 setting."""
        cfg = paper_filter_config(self.method) if self.filter_preset == "paper" else FilterConfig()
        if self.r_std_nt is not None:
            cfg = replace(cfg, r_std_nt=self.r_std_nt)
        return cfg


def run_compensate(req: CompensateRequest) -> dict[str, Any]:
    """Do the work of ``aeromag compensate``; return the report (also written to disk)."""
    req.check()
    flight, problems = load_flight(req.path, needs=req.needs())
    calibration = _calibration_mask(flight, req.calibration_window_s)
    if req.method == "tl":
        tl = TollesLawson(bandpass_hz=req.tl_bandpass_hz, trim=req.tl_trim, ridge=req.tl_ridge)
        comp = compensate_scalar(flight, req.flux, req.scalar, tl, calibration)
    else:
        cfg = req.filter_config() if req.method in FILTER_METHODS else None
        comp = compensate_vector(flight, req.method, req.flux, cfg, calibration)
    metrics_block = score(flight, comp)
    report = {
        "report_version": REPORT_VERSION,
        "input": str(req.path),
        "method": comp.method,
        "settings": comp.settings,
        "coefficients": comp.coefficients,
        "metrics": metrics_block,
        "nonfinite_policy": _nonfinite_policy(comp),
        "input_problems": problems,
    }
    out_flight = Flight(
        {**flight.fields, **comp.fields}, {**flight.attrs, "compensation": comp.method}
    )
    write_flight(out_flight, req.out / "compensated.h5", inputs=[req.path])
    write_text(req.out / "report.json", json.dumps(_jsonable(report), indent=2), inputs=[req.path])
    from aeromag_env.compensation.plots import plot_compensation

    plot_compensation(flight, comp, metrics_block, req.out / "compensation.png")
    return report


def _calibration_mask(flight: Flight, window: tuple[float, float] | None) -> np.ndarray | None:
    if window is None:
        return None
    mask = (flight.tt >= window[0]) & (flight.tt <= window[1])
    if mask.sum() < 100:
        raise AeromagError(
            f"--calibration-window {window[0]:g} {window[1]:g} holds {int(mask.sum())} samples "
            f"(need ≥ 100); the flight spans {flight.tt[0]:g}–{flight.tt[-1]:g} s"
        )
    return mask


def _nonfinite_policy(comp: Compensation) -> str:
    if comp.method in FILTER_METHODS:
        return "non-finite samples are skipped by the filter (predict only); outputs there are NaN"
    return "non-finite samples are left out of the fit; outputs there are NaN"


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


def summary_line(report: dict[str, Any], out: Path) -> str:
    """One line for the terminal (input problems are listed in report.json)."""
    m = report["metrics"]
    parts = [f"{report['method']}: wrote {out}/compensated.h5, report.json, compensation.png"]
    for key, label in (("compensation_rmse_nt", "RMSE (2nd half)"), ("improvement_ratio", "IR"),
                       ("fom_nt", "FOM")):  # fmt: skip
        if m.get(key) is not None:
            parts.append(f"{label} {m[key]:.3g}" + (" nT" if key != "improvement_ratio" else ""))
    if m["nonfinite_samples"]:
        parts.append(f"{m['nonfinite_samples']} non-finite samples ({report['nonfinite_policy']})")
    if m["divergences"]:
        parts.append(f"{m['divergences']} divergences detected and recovered")
    return "; ".join(parts)
