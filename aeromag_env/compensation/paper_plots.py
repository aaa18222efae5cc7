"""Figures 3–5 of Zhang, Zhao & Chang (2014), redrawn from our reproduction."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from aeromag_env.atomic import atomic_path
from aeromag_env.compensation.kalman import FilterResult
from aeromag_env.compensation.model import BLOCK_SCALE
from aeromag_env.flight.data import Flight
from aeromag_env.flight.plot import pyplot, shade_maneuvers
from aeromag_env.simulation.interference import STATE_SLICES


def _save(fig: Any, path: Path) -> None:
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")


def plot_field(flight: Flight, fakf: FilterResult, path: Path) -> None:
    """Fig. 3: the field the algorithm computes (``T_m − ΔT̂``) against the true field."""
    plt = pyplot()
    fig, axes = plt.subplots(3, 2, figsize=(12, 8), sharex=True, constrained_layout=True)
    meas, true = flight.vector("flux_a"), flight.vector("truth_earth")
    computed = meas - fakf.interference
    for i, axis in enumerate("xyz"):
        ax = axes[i, 0]
        ax.plot(flight.tt, meas[:, i], color="0.7", lw=0.6, label="measured T_m")
        ax.plot(flight.tt, computed[:, i], lw=0.6, label="computed T_m − ΔT̂ (fakf)")
        ax.plot(flight.tt, true[:, i], "k--", lw=0.6, label="true T")
        ax.set_ylabel(f"T_{axis} [nT]")
        ax = axes[i, 1]
        ax.plot(flight.tt, meas[:, i] - true[:, i], color="0.7", lw=0.5, label="T_m − T")
        ax.plot(flight.tt, computed[:, i] - true[:, i], lw=0.5, label="computed − T")
        ax.set_ylabel("[nT]")
    axes[0, 0].legend(loc="upper right", fontsize=8)
    axes[0, 1].legend(loc="upper right", fontsize=8)
    axes[0, 0].set_title("Fig. 3: field computed by the fuzzy adaptive KF")
    axes[0, 1].set_title("difference to the true field (20 nT noise included)")
    for ax in axes[-1]:
        ax.set_xlabel("time [s]")
    _save(fig, path)
    plt.close(fig)


def plot_states(
    flight: Flight, runs: dict[str, FilterResult], truth: np.ndarray, path: Path
) -> None:
    """Fig. 4: the 21 states over time (fakf solid, plain kf faint), truth dashed."""
    plt = pyplot()
    fig, axes = plt.subplots(3, 1, figsize=(11, 9), sharex=True, constrained_layout=True)
    units = {"permanent": "T_p [nT]", "induced": "A [1e-3]", "eddy": "B [1e-4 s]"}
    for ax, (block, sl), scale in zip(axes, STATE_SLICES.items(), BLOCK_SCALE, strict=True):
        div = 1.0 if block == "permanent" else scale
        colors = plt.cm.tab10(np.arange(sl.stop - sl.start) % 10)
        for j, c in zip(range(sl.start, sl.stop), colors, strict=True):
            ax.plot(flight.tt, runs["kf"].states[:, j] / div, color=c, lw=0.5, alpha=0.35)
            ax.plot(flight.tt, runs["fakf"].states[:, j] / div, color=c, lw=0.8)
            ax.axhline(truth[j] / div, color=c, ls="--", lw=0.6)
        ax.set_ylabel(units[block])
        span = np.ptp(truth[sl] / div)
        mid = np.mean(truth[sl] / div)
        ax.set_ylim(mid - 2 * span - 1e-9, mid + 2 * span + 1e-9)
    axes[0].set_title("Fig. 4: state estimates (fakf solid, plain kf faint, truth dashed)")
    axes[-1].set_xlabel("time [s]")
    _save(fig, path)
    plt.close(fig)


def plot_compensation_axes(flight: Flight, runs: dict[str, FilterResult], path: Path) -> None:
    """Fig. 5: per-axis compensation error, and ROR / QOQ of the fuzzy adaptive KF."""
    plt = pyplot()
    fig, axes = plt.subplots(4, 1, figsize=(11, 10), sharex=True, constrained_layout=True)
    truth = flight.vector("truth_interf")
    for i, axis in enumerate("xyz"):
        ax = axes[i]
        for name, lw in (("kf", 0.5), ("fakf", 0.5), ("kf_true_r", 0.8)):
            ax.plot(flight.tt, truth[:, i] - runs[name].interference[:, i], lw=lw, label=name)
        lim = 3 * np.nanstd((truth - runs["fakf"].interference)[flight.n // 2 :, i]) + 1.0
        ax.set_ylim(-lim, lim)
        ax.set_ylabel(f"ΔT_{axis} error [nT]")
        shade_maneuvers(ax, flight)
    axes[0].legend(loc="upper right", ncol=3)
    axes[0].set_title("Fig. 5: true − estimated interference per axis; ROR and QOQ (fakf)")
    ax = axes[3]
    ax.semilogy(flight.tt, runs["fakf"].ror, lw=0.7, label="ROR")
    ax.semilogy(flight.tt, runs["fakf"].qoq, lw=0.7, label="QOQ")
    ax.axhspan(0.9, 1.1, color="0.85")
    ax.set(ylabel="[-]", xlabel="time [s]")
    ax.legend(loc="upper right")
    _save(fig, path)
    plt.close(fig)


def plot_paper_figures(
    flight: Flight, runs: dict[str, FilterResult], truth_state: np.ndarray, out: Path
) -> None:
    """Write ``fig3_field.png``, ``fig4_states.png`` and ``fig5_compensation.png`` to ``out``."""
    plot_field(flight, runs["fakf"], out / "fig3_field.png")
    plot_states(flight, runs, truth_state, out / "fig4_states.png")
    plot_compensation_axes(flight, runs, out / "fig5_compensation.png")
