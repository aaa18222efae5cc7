"""The page of ``aeromag calibrate``: the calibration's figure of merit box by box, the fit, and
the calibration flight compensated with the model.

:func:`calibrate_page` takes the report (what ``report.json`` holds) and the arrays of
:func:`~aeromag_env.reports.compensate.compensate_arrays` for the calibration flight.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from aeromag_env.reports import html as h
from aeromag_env.reports.compensate import _time_plots

#: The headline figures: label, key in the report, unit.
HEADLINES = (
    ("FOM (last box)", "calibration.fom_nt", "nT"),
    ("boxes", "calibration.box_count", ""),
    ("calibration samples", "calibration.samples", ""),
    ("residual std (0.1–0.9 Hz)", "calibration.residual.band_std_nt", "nT"),
    ("fluxgate residual RMS", "calibration.residual.residual_rms_nt", "nT"),
)


@h.page_builder
def calibrate_page(report: dict[str, Any], arrays: dict[str, np.ndarray]) -> str:
    """The HTML page of one calibration.

    Parameters
    ----------
    report : dict
        What ``report.json`` holds (``method``, ``calibration``, ``model``…).
    arrays : dict
        As :func:`~aeromag_env.reports.compensate.compensate_arrays` returns.

    Returns
    -------
    str
        A self-contained HTML document.
    """
    cal = report.get("calibration") or {}
    blocks: list[Any] = [h.headline_block(report, HEADLINES)]
    blocks += [h.card(h.esc(w)) for w in report.get("warnings") or []]
    rows = [
        [
            f"box {b['box']}",
            f"{b['windows'][0]}–{b['windows'][1]}",
            b["fom_nt"],
            b["fom_uncompensated_nt"],
        ]
        for b in cal.get("fom_boxes") or []
    ]
    blocks += [h.heading("Figure of merit, box by box")]
    if rows:
        header = ("box", "windows", "FOM compensated [nT]", "FOM uncompensated [nT]")
        blocks += [h.card(h.table(header, rows, text_columns=2))]
    else:
        blocks += [h.card("No complete calibration box is labelled in this flight.")]
    blocks += [h.heading("Over time"), *_time_plots(report, arrays)]
    blocks += [h.heading("Model"), h.card(h.definitions(report.get("model_summary") or {}))]
    blocks += [h.heading("Provenance"), h.card(h.definitions(report.get("provenance") or {}))]
    subtitle = f"{report.get('input', '')} · method {report.get('method', '?')}"
    return h.render_page(f"Calibration: {report.get('method', '')}", subtitle, blocks)
