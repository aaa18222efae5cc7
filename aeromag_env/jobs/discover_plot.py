"""Figures of a discovery, ``residual.png`` and ``diagnostics.png`` (matplotlib, lazily).

``residual.png``: measured − simulated per axis with the base model and with the named effects,
the held-out part shaded, then the residual against what drives each named effect.
``diagnostics.png``: the residual's spectrum, its mean per heading bin and its partial
correlation with each auxiliary channel.

The time series are drawn from the minimum and maximum of each of
:data:`~aeromag_env.reports.decimate.COLUMNS` pixel columns
(:func:`~aeromag_env.reports.decimate.extreme_indices`): the picture of the whole series, spikes
included, at a cost that does not grow with the flight. The figures are drawn on matplotlib's
``Figure`` directly (``pyplot`` is not imported), with fixed margins (:func:`_margins`, not
``tight_layout``, which measured every label several times) and plain tick labels on the log
axes (not mathtext, whose parser took a second).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from aeromag_env.atomic import atomic_path
from aeromag_env.discovery.workflow import Discovery
from aeromag_env.errors import AeromagError
from aeromag_env.reports.decimate import extreme_indices, runs

#: Resolution of the figures [dots per inch].
DPI = 100
#: Points of the residual drawn against a driving channel, at most (every k-th sample).
DRIVER_POINTS = 4000


def plot_discovery(result: Discovery, out: Path) -> None:
    """Write ``residual.png`` (before/after, held-out shaded) and ``diagnostics.png`` into
    ``out``, each atomically.

    Raises
    ------
    AeromagError
        matplotlib is not installed (one line).
    """
    figure = _figure_class()
    _save(_residual_figure(figure, result), out / "residual.png")
    _save(_diagnostics_figure(figure, result), out / "diagnostics.png")


def _figure_class() -> Any:
    """``matplotlib.figure.Figure``; a one-line error without the plot extra."""
    try:
        from matplotlib.figure import Figure
    except ImportError:
        raise AeromagError("figures need matplotlib: pip install 'aeromag-env[plot]'") from None
    return Figure


def _save(fig: Any, path: Path) -> None:
    with atomic_path(path) as tmp:
        # zlib level 1: a fifth of the encoding time of the default 6 for 10 % more bytes
        fig.savefig(tmp, dpi=DPI, format="png", pil_kwargs={"compress_level": 1})


def _residual_figure(figure: Any, result: Discovery) -> Any:
    """Measured − simulated per axis, then the residual against each named effect's driver."""
    s = result.series
    tt = np.asarray(s["tt"], dtype=float)
    held = runs(tt, np.asarray(s["held_out"], dtype=bool))
    rows = 3 + len(result.drivers)
    fig = figure(figsize=(10, 2.3 * rows))
    axes = fig.subplots(rows, 1, squeeze=False, gridspec_kw=_margins(10, 2.3 * rows, hspace=0.55))[
        :, 0
    ]
    for ax in axes[1:3]:
        ax.sharex(axes[0])
    for i, ax in enumerate(axes[:3]):
        for key, label in (
            ("residual_before", "base model"),
            ("residual_after", "with named effects"),
        ):
            y = s[key][:, i]
            k = extreme_indices(y)
            ax.plot(tt[k], y[k], lw=0.4, label=label)
        ax.broken_barh(
            [(t0, t1 - t0) for t0, t1 in held],
            (0, 1),
            transform=ax.get_xaxis_transform(),
            color="0.9",
            zorder=0,
            label="held out" if i == 0 else None,
        )
        ax.set_ylabel(f"{'xyz'[i]} [nT]")
    axes[0].legend(loc="upper right", fontsize=8)
    axes[0].set_title(f"Measured − simulated ({result.report['verdict']})")
    axes[2].set_xlabel("time [s]")
    for ax, driver in zip(axes[3:], result.drivers, strict=True):
        _against_driver(ax, s["residual_before"], s["residual_after"], *driver)
    return fig


def _margins(width_in: float, height_in: float, **space: float) -> dict[str, float]:
    """Subplot margins for a figure of ``width_in`` × ``height_in`` [in]: room for the tick
    labels and axis labels at the left and bottom and a title at the top (fixed in inches, so
    every figure height gets the same)."""
    return {
        "left": 0.8 / width_in,
        "right": 1 - 0.2 / width_in,
        "bottom": 0.55 / height_in,
        "top": 1 - 0.4 / height_in,
        **space,
    }


def _against_driver(
    ax: Any, before: np.ndarray, after: np.ndarray, name: str, driver: str, x: np.ndarray
) -> None:
    """The residual before and after against what drives a named effect, on the axis where the
    effect changed the residual most (at most :data:`DRIVER_POINTS` points)."""
    i = int(np.nanargmax(np.nanstd(before - after, axis=0)))
    step = max(1, x.size // DRIVER_POINTS)
    for r, label in ((before, "base model"), (after, "with named effects")):
        ax.plot(x[::step], r[::step, i], ".", ms=1.5, alpha=0.5, label=label)
    ax.set(xlabel=driver, ylabel=f"{'xyz'[i]} [nT]", title=f"{name}: residual against {driver}")
    ax.legend(loc="upper right", fontsize=8, markerscale=6)


def _diagnostics_figure(figure: Any, result: Discovery) -> Any:
    """The residual spectrum (Welch), the heading bins and the auxiliary channels."""
    from scipy.signal import welch

    s = result.series
    d = result.report["diagnostics"]
    from matplotlib.ticker import FuncFormatter, NullFormatter

    fig = figure(figsize=(13, 4))
    axes = fig.subplots(1, 3, gridspec_kw=_margins(13, 4, wspace=0.45))
    dt = result.report["data"]["sample_interval_s"]
    for key, label in (("residual_before", "base model"), ("residual_after", "with effects")):
        r = np.nan_to_num(s[key])
        f, p = welch(r, fs=1.0 / dt, nperseg=min(2048, r.shape[0]), axis=0)
        axes[0].loglog(f[1:], p[1:].sum(axis=1), lw=0.8, label=label)
    axes[0].set(xlabel="frequency [Hz]", ylabel="PSD [nT²/Hz]", title="residual spectrum")
    axes[0].legend(fontsize=8)
    for axis in (axes[0].xaxis, axes[0].yaxis):
        axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        axis.set_minor_formatter(NullFormatter())
    bins = d["heading_bins_mean_nt"]
    if bins:
        centers = [float(k.split("-")[0]) + 15 for k in bins]
        vals = np.array(list(bins.values()))
        for i in range(3):
            axes[1].plot(centers, vals[:, i], "o-", label="xyz"[i])
        axes[1].legend(fontsize=8)
    axes[1].set(xlabel="heading [deg]", ylabel="mean residual [nT]", title="heading bins")
    corr = d["aux_partial_correlation"]
    if corr:
        axes[2].barh(list(corr), [v["max_abs"] for v in corr.values()])
    axes[2].set(xlabel="|partial correlation|", title="auxiliary channels")
    return fig
