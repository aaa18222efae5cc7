"""``aeromag discover``'s terminal line (:func:`summary_line`); the job itself is
:func:`aeromag_env.jobs.discover.discover`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from aeromag_env.jobs.discover import shrink_text


def summary_line(report: dict[str, Any], out: Path, html: bool = True) -> str:
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
