"""``aeromag compensate``'s terminal line (:func:`summary_line`); the job itself is
:func:`aeromag_env.jobs.compensate.compensate`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

#: Said after the RMSE against a simulated truth when a fluxgate mount was applied: the truth
#: is in body axes, and the fit absorbs the mount's residual rotation (0.07° is ~65 nT on a
#: 53 000 nT field) as induced terms, which the compensated total field does not show.
MOUNT_RMSE_NOTE = (
    " (against the simulated truth in body axes: it includes what the fit "
    "absorbed of the applied mount's error, which the IR does not show)"
)


def summary_line(report: dict[str, Any], out: Path, html: bool = True) -> str:
    """One line for the terminal (input problems are listed in report.json); ``html``: the set
    has ``report.html``."""
    m = report["metrics"]
    page = ", report.html" if html else ""
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
