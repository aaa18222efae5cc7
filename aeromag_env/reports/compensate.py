"""The page of ``aeromag compensate``: where the aircraft flew and how well it was compensated.

:func:`compensate_page` takes the report (what ``report.json`` holds) and plain arrays
(:func:`compensate_arrays` gathers them from a flight and a compensation without importing
either's module). Shown: the headline figures; the track in local metres coloured by the
compensated residual; the measured and compensated field and the estimated interference over
time, with the time gaps, the spikes and the flagged samples marked and the FOM manoeuvres
shaded; for the recursive filters the consistency ratios ROR/QOQ and the Q and R scales; the
coefficients; the warnings; the provenance.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from aeromag_env.reports import html as h
from aeromag_env.reports.decimate import extreme_indices
from aeromag_env.reports.plots import gap_windows, lines, markers, new_figure, shade

#: The headline figures: label, key in the report, unit.
HEADLINES = (
    ("RMSE vs truth (2nd half)", "metrics.compensation_rmse_nt", "nT"),
    ("improvement ratio", "metrics.improvement_ratio", ""),
    ("FOM", "metrics.fom_nt", "nT"),
    ("FOM uncompensated", "metrics.fom_uncompensated_nt", "nT"),
    ("band-passed std after", "headline.std_compensated_nt", "nT"),
    ("IR outside calibration", "held_out.improvement_ratio", ""),
    ("divergences", "metrics.divergences", ""),
    ("non-finite samples", "metrics.nonfinite_samples", ""),
)
#: Mean Earth radius for the local plane [m] (the track spans a few hundred km at most).
EARTH_RADIUS_M = 6_371_000.0
#: Points of the coloured track (its residual's extremes per column are kept).
TRACK_COLUMNS = 2500


def compensate_arrays(flight: Any, comp: Any) -> dict[str, np.ndarray]:
    """The arrays :func:`compensate_page` draws, read from a flight (``tt``, fields by name,
    ``maneuver_windows()``) and a compensation (``total_before``, ``total_after``,
    ``model_total``, ``fields``, ``series``, ``samples``).

    Returns
    -------
    dict
        ``tt`` (n,) [s]; ``total_before``, ``total_after`` (n,) [nT]; when known
        ``model_total`` (n,) [nT], ``lat``/``lon`` (n,) [deg], ``interference_true`` and
        ``interference_estimated`` (n, 3) [nT], ``spikes``/``nonfinite`` (n,) bool, ``ror``,
        ``qoq``, ``q_scale``, ``r_scale`` (n,) [-], ``maneuvers`` (m, 2) [s].
    """
    out: dict[str, np.ndarray] = {
        "tt": np.asarray(flight.tt, dtype=float),
        "total_before": np.asarray(comp.total_before, dtype=float),
        "total_after": np.asarray(comp.total_after, dtype=float),
    }
    if comp.model_total is not None:
        out["model_total"] = np.asarray(comp.model_total, dtype=float)
    for name in ("lat", "lon"):
        if name in flight:
            out[name] = np.asarray(flight[name], dtype=float)
    # the estimate's channels end in interf_est_x/y/z (their prefix is the compensator's)
    stem = next((n[:-2] for n in comp.fields if n.endswith("interf_est_x")), None)
    estimated = [f"{stem}_{a}" for a in "xyz"]
    true = [f"truth_interf_{a}" for a in "xyz"]
    if stem and all(n in comp.fields for n in estimated) and all(n in flight for n in true):
        out["interference_estimated"] = np.column_stack([comp.fields[n] for n in estimated])
        out["interference_true"] = np.column_stack([flight[n] for n in true])
    samples = comp.samples
    if samples is not None:
        n = out["tt"].size
        out["spikes"] = _any_mask(samples.spikes.values(), n)
        out["nonfinite"] = _any_mask(samples.nonfinite.values(), n)
    for key in ("ror", "qoq", "q_scale", "r_scale"):
        if key in comp.series:
            out[key] = np.asarray(comp.series[key], dtype=float)
    windows = [(t0, t1) for _id, t0, t1 in flight.maneuver_windows()]
    out["maneuvers"] = np.array(windows, dtype=float).reshape(-1, 2)
    return out


def _any_mask(masks: Any, n: int) -> np.ndarray:
    out = np.zeros(n, dtype=bool)
    for mask in masks:
        out |= np.asarray(mask, dtype=bool)
    return out


@h.page_builder
def compensate_page(report: dict[str, Any], arrays: dict[str, np.ndarray]) -> str:
    """The HTML page of one compensated flight.

    Parameters
    ----------
    report : dict
        What ``report.json`` holds (``method``, ``metrics``, ``coefficients``…).
    arrays : dict
        As :func:`compensate_arrays` returns.

    Returns
    -------
    str
        A self-contained HTML document.
    """
    tt = arrays["tt"]
    time_plots = _time_plots(report, arrays)
    blocks: list[Any] = [h.headline_block(report, HEADLINES)]
    blocks += _warnings(report)
    track = _track(arrays)
    if track is not None:
        blocks += [h.heading("Track, coloured by the compensated residual"), track]
    blocks += [h.heading("Over time"), *time_plots]
    blocks += [h.heading("Coefficients"), h.card(_coefficients(report.get("coefficients") or {}))]
    blocks += [h.heading("Provenance"), h.card(h.definitions(_provenance(report)))]
    duration = float(tt[-1] - tt[0]) if tt.size else 0.0
    subtitle = (
        f"{report.get('input', '')} · method {report.get('method', '?')} · "
        f"{tt.size} samples, {duration / 60:.1f} min"
    )
    return h.render_page(f"Compensation: {report.get('method', '')}", subtitle, blocks)


def _warnings(report: dict[str, Any]) -> list[str]:
    """The input problems and filter events, each one line."""
    items = [str(p) for p in report.get("input_problems") or []]
    m = report.get("metrics") or {}
    if m.get("divergences"):
        items.append(f"{m['divergences']} filter divergences detected and recovered")
    if m.get("outliers_rejected"):
        items.append(f"{m['outliers_rejected']} samples rejected by the filter's outlier gate")
    if m.get("nonfinite_samples"):
        items.append(f"{m['nonfinite_samples']} non-finite samples: {report['nonfinite_policy']}")
    return [h.heading("Warnings"), h.card(h.notes(items, "no warnings"))]


def _residual(arrays: dict[str, np.ndarray]) -> tuple[np.ndarray, str]:
    """The compensated field minus the model field (or its mean) [nT], and its name."""
    after = arrays["total_after"]
    if "model_total" in arrays:
        return after - arrays["model_total"], "compensated − model field"
    finite = after[np.isfinite(after)]
    return after - (finite.mean() if finite.size else 0.0), "compensated − its mean"


def _track(arrays: dict[str, np.ndarray]) -> Any:
    """East/north [m] from the first fix (local tangent plane), coloured by the residual."""
    if "lat" not in arrays or "lon" not in arrays:
        return None
    from bokeh.models import ColorBar, ColumnDataSource, LinearColorMapper
    from bokeh.palettes import RdBu11

    lat, lon = np.radians(arrays["lat"]), np.radians(arrays["lon"])
    ok = np.isfinite(lat) & np.isfinite(lon)
    if not ok.any():
        return None
    first = np.flatnonzero(ok)[0]
    east = EARTH_RADIUS_M * np.cos(lat[first]) * (lon - lon[first])
    north = EARTH_RADIUS_M * (lat - lat[first])
    residual, name = _residual(arrays)
    residual = residual - np.nanmedian(residual) if np.isfinite(residual).any() else residual
    idx = extreme_indices(np.where(ok, residual, np.nan), TRACK_COLUMNS)
    idx = idx[ok[idx]]
    values = residual[idx]
    span = float(np.nanpercentile(np.abs(values), 98)) if np.isfinite(values).any() else 1.0
    mapper = LinearColorMapper(
        palette=list(reversed(RdBu11)), low=-span, high=span, nan_color="#bbbbbb"
    )
    source = ColumnDataSource(
        {"e": east[idx] / 1e3, "n": north[idx] / 1e3, "r": values, "t": arrays["tt"][idx]}
    )
    fig = new_figure(
        f"track ({name}, median removed; colour clipped at ±{span:.3g} nT)",
        "east [km]",
        "north [km]",
        height=430,
        tools="pan,wheel_zoom,box_zoom,reset,save,hover",
        match_aspect=True,
        tooltips=[("t", "@t{0.0} s"), ("residual", "@r{0.000} nT")],
    )
    fig.line("e", "n", source=source, color="#c8c8c8", line_width=1)
    fig.scatter("e", "n", source=source, size=4, color={"field": "r", "transform": mapper})
    fig.add_layout(ColorBar(color_mapper=mapper, title="[nT]", width=10), "right")
    return fig


def _time_plots(report: dict[str, Any], arrays: dict[str, np.ndarray]) -> list[Any]:
    """Field before/after, interference, filter statistics: one shared time axis."""
    tt = arrays["tt"]
    before, after = arrays["total_before"], arrays["total_after"]
    ref = arrays.get("model_total")
    what = "minus the model field" if ref is not None else "minus its mean"
    if ref is None:
        ref = np.full_like(before, np.nanmean(before) if np.isfinite(before).any() else 0.0)
    field = new_figure(f"total field {what}", "time [s]", "[nT]")
    lines(field, tt, [("measured", before - ref), ("compensated", after - ref)])
    _flags(field, tt, before - ref, arrays)
    plots = [field]
    interference = new_figure(
        "estimated interference (measured − compensated)", "time [s]", "[nT]", x_range=field.x_range
    )
    lines(interference, tt, [("estimated", before - after)], colours=("#009E73",))
    plots.append(interference)
    if "interference_true" in arrays:
        err = arrays["interference_true"] - arrays["interference_estimated"]
        rmse = h.number((report.get("metrics") or {}).get("compensation_rmse_nt"))
        error = new_figure(
            f"true − estimated interference per axis (RMSE 2nd half {rmse} nT)",
            "time [s]",
            "[nT]",
            x_range=field.x_range,
        )
        lines(error, tt, [(f"error {a}", err[:, i]) for i, a in enumerate("xyz")])
        _clip_to_steady_state(error, err)
        plots.append(error)
    ratios = [
        (k.upper().replace("_", " "), arrays[k])
        for k in ("ror", "qoq", "q_scale", "r_scale")
        if k in arrays
    ]
    if ratios:
        stats = new_figure(
            "filter consistency (ROR, QOQ; 1 = consistent) and the Q, R scales",
            "time [s]",
            "[-]",
            x_range=field.x_range,
            y_log=True,
        )
        lines(stats, tt, ratios, positive=True)
        plots.append(stats)
    windows = [tuple(w) for w in arrays.get("maneuvers", np.empty((0, 2)))]
    for fig in plots:
        shade(fig, windows)
        shade(fig, gap_windows(tt), colour="#888888")
    return plots


def _clip_to_steady_state(fig: Any, err: np.ndarray) -> None:
    """Show ±1.5 × the 99.5th percentile of |error| after the first quarter (the filter's
    start-up transient would flatten the rest; zooming out still shows it)."""
    from bokeh.models import Range1d

    late = np.abs(err[err.shape[0] // 4 :])
    if np.isfinite(late).any():
        lim = 1.5 * float(np.nanpercentile(late, 99.5))
        if lim > 0:
            fig.y_range = Range1d(-lim, lim)


def _flags(fig: Any, tt: np.ndarray, y: np.ndarray, arrays: dict[str, np.ndarray]) -> None:
    """Spikes and non-finite samples marked on the measured field."""
    if "spikes" in arrays:
        markers(fig, tt, y, arrays["spikes"], "spikes", "#D55E00", "x")
    if "nonfinite" in arrays:
        markers(fig, tt, y, arrays["nonfinite"], "non-finite input", "#CC79A7", "triangle")


def _coefficients(coefficients: dict[str, Any]) -> str:
    """The fitted coefficients: vectors and matrices as small tables, the rest as numbers."""
    parts = []
    for name, value in coefficients.items():
        arr = np.asarray(value, dtype=object)
        if arr.ndim == 2:
            rows = [
                [f"row {'xyz'[i] if arr.shape[0] == 3 else i}", *r]
                for i, r in enumerate(arr.tolist())
            ]
            header = ["", *("xyz" if arr.shape[1] == 3 else [str(j) for j in range(arr.shape[1])])]
            parts.append(f"<h3>{h.esc(name)}</h3>{h.table(header, rows)}")
        elif arr.ndim == 1:
            header = list("xyz") if arr.size == 3 else [str(j) for j in range(arr.size)]
            parts.append(f"<h3>{h.esc(name)}</h3>{h.table(header, [arr.tolist()], 0)}")
        else:
            parts.append(f"<p>{h.esc(name)}: {h.esc(h.number(value))}</p>")
    return "".join(parts) or "<p>none</p>"


#: Report keys shown under Provenance (in this order, when present).
PROVENANCE = (
    "input",
    "input_sha256",
    "input_format",
    "flight_date",
    "earth_model",
    "channels",
    "mount",
    "selection",
    "segments",
    "flagged_samples",
    "nonfinite_policy",
    "settings",
    "headline",
    "vendor_comparison",
    "held_out",
)


def _provenance(report: dict[str, Any]) -> dict[str, Any]:
    return {key: report[key] for key in PROVENANCE if report.get(key) is not None}
