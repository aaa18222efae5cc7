"""What the command line prints of the jobs' results: one terminal line per compensation or
discovery, the seeds' table of a training, the lines of a search (the evaluation's and the
benchmark's tables come with their results)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from aeromag_env.jobs.discover import shrink_text

#: The adaptive filters that go on as the plain ``kf`` after a runaway.
ADAPTIVE_METHODS = ("fakf", "ding", "sage-husa")

#: Said after the RMSE against a simulated truth when a fluxgate mount was applied: the truth
#: is in body axes, and the fit absorbs the mount's residual rotation (0.07° is ~65 nT on a
#: 53 000 nT field) as induced terms, which the compensated total field does not show.
MOUNT_RMSE_NOTE = (
    " (against the simulated truth in body axes: it includes what the fit "
    "absorbed of the applied mount's error, which the IR does not show)"
)


def compensate_line(report: dict[str, Any], out: Path, html: bool = True) -> str:
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
            if report.get("method") in ADAPTIVE_METHODS
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


def calibrate_line(report: dict[str, Any], out: Path, html: bool = True) -> str:
    """The method, the files written (``html``: with ``report.html``), the figure of merit of
    the last box and the calibration's residual, and the count of input warnings."""
    cal = report["calibration"]
    page = ", report.html" if html else ""
    parts = [f"{report['method']}: wrote {out}/model.json, report.json{page}"]
    parts.append(f"{cal['samples']} calibration samples")
    boxes = cal.get("fom_boxes") or []
    if cal.get("fom_nt") is not None:
        parts.append(f"FOM {cal['fom_nt']:.3g} nT (box {boxes[-1]['box']} of {len(boxes)})")
    residual = cal.get("residual") or {}
    for key, label in (
        ("band_std_nt", "residual std (0.1–0.9 Hz)"),
        ("residual_rms_nt", "fluxgate residual RMS"),
    ):
        if residual.get(key) is not None:
            parts.append(f"{label} {residual[key]:.3g} nT")
    if report["input_problems"]:
        parts.append(
            f"{len(report['input_problems'])} input warning(s), listed in report.json "
            "(aeromag info explains them)"
        )
    return "; ".join(parts)


def discover_line(report: dict[str, Any], out: Path, html: bool = True) -> str:
    """The verdict, the held-out gap, the files written (``html``: with ``report.html``) and the
    count of input warnings."""
    gap, problems = report["gap"], report["input_problems"]
    warned = (
        (f"; {len(problems)} input warning(s), listed in report.json (aeromag info explains them)")
        if problems
        else ""
    )
    return (
        f"{report['verdict']}; held-out gap {gap['rms_before_nt']:.3g} → "
        f"{gap['rms_after_nt']:.3g} nT ({shrink_text(gap)}); wrote {out}/report.json, "
        f"report.md, model_config.json, residual.png, diagnostics.png"
        f"{', report.html' if html else ''}{warned}"
    )


def seed_table(summary: dict[str, Any]) -> str:
    """Markdown: per seed its best validation RMSE, attempts and error; then mean and SD."""
    lines = [
        "| seed | best validation RMSE [nT] | steps | attempts | error |",
        "|---|---|---|---|---|",
    ]
    for r in summary["seeds"]:
        rmse = r["best_validation_rmse_nt"]
        shown = "—" if rmse is None else f"{rmse:.3g}"
        attempts = "unknown" if r["attempts"] is None else r["attempts"]
        lines.append(
            f"| {r['seed']} | {shown} | {r['timesteps'] or '—'} | {attempts} | {r['error'] or ''} |"
        )
    mean, sd = summary["validation_rmse_nt_mean"], summary["validation_rmse_nt_sd"]
    if sd is not None:
        lines += ["", f"over {len(summary['seeds'])} seeds: mean {mean:.3g} nT, SD {sd:.2g} nT"]
    retried = [str(r["seed"]) for r in summary["seeds"] if (r["attempts"] or 0) > 1]
    if retried:
        lines.append(f"retried after a worker died: seed(s) {', '.join(retried)}")
    if any(r["attempts"] is None for r in summary["seeds"]):
        lines.append("retries unknown: the Ray actor counting attempts died during the run")
    return "\n".join(lines) + "\n"


def tune_summary(summary: dict[str, Any], out: str) -> str:
    """The lines ``aeromag tune`` prints: the trials, the best, where it is written."""
    trials, best = summary["trials"], summary["best"]
    stopped = sum(t["stopped_by_asha"] for t in trials)
    failed = sum(t["error"] is not None for t in trials)
    config = ", ".join(
        f"{k} {v:.3g}" if isinstance(v, float) else f"{k} {v}" for k, v in best["config"].items()
    )
    head = (
        f"{len(trials)} trials ({stopped} stopped early by ASHA, {failed} failed) in "
        f"{summary['seconds']:.0f} s on {summary['cpus']} CPUs\n"
    )
    if "learner" in summary:
        learner = summary["learner"]
        return (
            f"{head}best: trial {best['trial']}, validation score "
            f"{best['best_validation_score']:.3g} ({summary['select_by']}; {config})\n"
            f"hyperparameters: {out}/learners.json (aeromag train --learner {learner} "
            f"--hyperparams {out}/learners.json); every trial: {out}/tune.json"
        )
    return (
        f"{head}best: trial {best['trial']}, validation RMSE "
        f"{best['best_validation_rmse_nt']:.3g} nT ({config})\n"
        f"hyperparameters: {out}/ppo.json (aeromag train --scenario {summary['scenario']} "
        f"--hyperparams {out}/ppo.json); every trial: {out}/tune.json"
    )
