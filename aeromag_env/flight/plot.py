"""Figures of a flight (matplotlib, imported lazily so ``import aeromag_env`` stays light).

:func:`pyplot` is the one door to matplotlib for every figure of the package.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from aeromag_env.atomic import atomic_path
from aeromag_env.errors import AeromagError
from aeromag_env.flight.data import Flight


def pyplot() -> Any:
    """``matplotlib.pyplot`` on the Agg backend; a one-line error without the plot extra."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise AeromagError("figures need matplotlib: pip install 'aeromag-env[plot]'") from None
    return plt


def shade_maneuvers(ax: Any, flight: Flight) -> None:
    """Shade the calibration maneuver windows of ``flight`` on ``ax``."""
    for _mid, t0, t1 in flight.maneuver_windows():
        ax.axvspan(t0, t1, color="0.9", zorder=0)


def plot_flight(flight: Flight, path: str | os.PathLike, title: str = "") -> Path:
    """Overview of a flight: track, attitude, fluxgate field and (simulated) interference.

    Maneuver windows are shaded. Written atomically as PNG.
    """
    plt = pyplot()
    fig, axes = plt.subplots(2, 2, figsize=(12, 7), constrained_layout=True)
    ax = axes[0, 0]
    ax.plot(flight["lon"], flight["lat"], lw=0.8)
    ax.set(xlabel="longitude [deg]", ylabel="latitude [deg]", title="track")
    ax = axes[0, 1]
    for nm in ("ins_roll", "ins_pitch"):
        ax.plot(flight.tt, flight[nm], lw=0.7, label=nm)
    shade_maneuvers(ax, flight)
    ax.set(xlabel="time [s]", ylabel="[deg]", title="attitude (maneuvers shaded)")
    ax.legend(loc="upper right")
    ax = axes[1, 0]
    for flux_id in flight.fluxgates()[:1]:
        for axis, v in zip("xyz", flight.vector(flux_id).T, strict=True):
            ax.plot(flight.tt, v, lw=0.7, label=f"{flux_id}_{axis}")
        ax.legend(loc="upper right")
    ax.set(xlabel="time [s]", ylabel="[nT]", title="vector magnetometer (body axes)")
    ax = axes[1, 1]
    if "truth_interf_x" in flight:
        interf = flight.vector("truth_interf")
        for axis, v in zip("xyz", (interf - np.nanmean(interf, axis=0)).T, strict=True):
            ax.plot(flight.tt, v, lw=0.7, label=f"ΔT_{axis} − mean")
        ax.legend(loc="upper right")
        shade_maneuvers(ax, flight)
    ax.set(xlabel="time [s]", ylabel="[nT]", title="aircraft interference (truth, mean removed)")
    if title:
        fig.suptitle(title)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
    return Path(path)
