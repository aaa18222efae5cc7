"""Figure of a compensated flight (matplotlib, imported lazily)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from aeromag_env.atomic import atomic_path
from aeromag_env.compensation.compensate import INTERFERENCE
from aeromag_env.flight.data import Flight, vector_names
from aeromag_env.flight.plot import pyplot, shade_maneuvers


def plot_compensation(flight: Flight, comp: Any, metrics: dict, path: str | os.PathLike) -> Path:
    """Compensation overview: total field before/after, interference error, filter ratios."""
    plt = pyplot()
    has_ratios = "ror" in comp.series
    fig, axes = plt.subplots(
        3 if has_ratios else 2,
        1,
        figsize=(11, 9 if has_ratios else 6.5),
        sharex=True,
        constrained_layout=True,
    )
    ref = comp.model_total if comp.model_total is not None else np.nanmean(comp.total_before)
    ax = axes[0]
    ax.plot(flight.tt, comp.total_before - ref, lw=0.6, label="uncompensated")
    ax.plot(flight.tt, comp.total_after - ref, lw=0.6, label="compensated")
    shade_maneuvers(ax, flight)
    ax.set(ylabel="[nT]", title=f"{comp.method}: total field minus model field")
    ax.legend(loc="upper right")
    ax = axes[1]
    if comp.method != "tl" and "truth_interf_x" in flight:
        est = np.column_stack([comp.fields[nm] for nm in vector_names(INTERFERENCE)])
        err = flight.vector("truth_interf") - est
        for a, v in zip("xyz", err.T, strict=True):
            ax.plot(flight.tt, v, lw=0.6, label=f"error {a}")
        rmse = metrics.get("compensation_rmse_nt")
        ax.set(ylabel="[nT]", title=f"true − estimated interference (RMSE 2nd half {rmse:.3g} nT)")
        lim = np.nanpercentile(np.abs(err[flight.n // 4 :]), 99.5) * 1.5
        ax.set_ylim(-lim, lim)
    else:
        est = comp.total_before - comp.total_after
        ax.plot(flight.tt, est - np.nanmean(est), lw=0.6, label="estimated interference")
        ax.set(ylabel="[nT]", title="estimated interference (mean removed)")
    ax.legend(loc="upper right")
    if has_ratios:
        ax = axes[2]
        for key in ("ror", "qoq", "q_scale", "r_scale"):
            ax.semilogy(flight.tt, comp.series[key], lw=0.7, label=key.upper().replace("_", " "))
        ax.axhline(1.0, color="k", lw=0.5)
        ax.set(ylabel="[-]", title="consistency ratios and Q, R scales")
        ax.legend(loc="upper right", ncol=4)
    axes[-1].set_xlabel("time [s]")
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
    return Path(path)
