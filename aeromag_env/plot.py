"""Figures (matplotlib, imported lazily so ``import aeromag_env`` stays light)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from aeromag_env.atomic import atomic_path
from aeromag_env.errors import AeromagError
from aeromag_env.flight import Flight


def _pyplot() -> Any:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise AeromagError("figures need matplotlib: pip install 'aeromag-env[plot]'") from None
    return plt


def _shade_maneuvers(ax: Any, flight: Flight) -> None:
    for _mid, t0, t1 in flight.maneuver_windows():
        ax.axvspan(t0, t1, color="0.9", zorder=0)


def plot_flight(flight: Flight, path: str | os.PathLike, title: str = "") -> Path:
    """Overview of a flight: track, attitude, fluxgate field and (simulated) interference.

    Maneuver windows are shaded. Written atomically as PNG.
    """
    plt = _pyplot()
    fig, axes = plt.subplots(2, 2, figsize=(12, 7), constrained_layout=True)
    ax = axes[0, 0]
    ax.plot(flight["lon"], flight["lat"], lw=0.8)
    ax.set(xlabel="longitude [deg]", ylabel="latitude [deg]", title="track")
    ax = axes[0, 1]
    for nm in ("ins_roll", "ins_pitch"):
        ax.plot(flight.tt, flight[nm], lw=0.7, label=nm)
    _shade_maneuvers(ax, flight)
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
        _shade_maneuvers(ax, flight)
    ax.set(xlabel="time [s]", ylabel="[nT]", title="aircraft interference (truth, mean removed)")
    if title:
        fig.suptitle(title)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
    return Path(path)


def plot_compensation(flight: Flight, comp: Any, metrics: dict, path: str | os.PathLike) -> Path:
    """Compensation overview: total field before/after, interference error, filter ratios."""
    plt = _pyplot()
    has_ratios = "ror" in comp.series
    fig, axes = plt.subplots(3 if has_ratios else 2, 1, figsize=(11, 9 if has_ratios else 6.5),
                             sharex=True, constrained_layout=True)  # fmt: skip
    ref = comp.model_total if comp.model_total is not None else np.nanmean(comp.total_before)
    ax = axes[0]
    ax.plot(flight.tt, comp.total_before - ref, lw=0.6, label="uncompensated")
    ax.plot(flight.tt, comp.total_after - ref, lw=0.6, label="compensated")
    _shade_maneuvers(ax, flight)
    ax.set(ylabel="[nT]", title=f"{comp.method}: total field minus model field")
    ax.legend(loc="upper right")
    ax = axes[1]
    if comp.method != "tl" and "truth_interf_x" in flight:
        est = np.column_stack([comp.fields[f"interf_est_{a}"] for a in "xyz"])
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


def render_episode(env: Any) -> np.ndarray:
    """The episode so far as an RGB array (H, W, 3) uint8: error, ROR/QOQ, Q and R scales."""
    plt = _pyplot()
    k = env.filter.k
    tt = env.episode.flight.tt[:k]
    fig, axes = plt.subplots(3, 1, figsize=(8, 6), sharex=True, constrained_layout=True)
    err = env.episode.truth_interf[:k] - env.filter.est[:k]
    axes[0].plot(tt, err, lw=0.6)
    axes[0].set(ylabel="[nT]", title=f"{env.scenario}: true − estimated interference")
    if k:
        lim = float(np.nanpercentile(np.abs(err[k // 2 :]), 99)) * 2 + 1.0
        axes[0].set_ylim(-lim, lim)
    axes[1].semilogy(tt, env.filter.ror[:k], lw=0.6, label="ROR")
    axes[1].semilogy(tt, env.filter.qoq[:k], lw=0.6, label="QOQ")
    axes[1].legend(loc="upper right")
    axes[2].semilogy(tt, env.filter.q_scale[:k], lw=0.8, label="Q scale")
    axes[2].semilogy(tt, env.filter.r_scale[:k], lw=0.8, label="R scale")
    axes[2].legend(loc="upper right")
    axes[2].set_xlabel("time [s]")
    fig.canvas.draw()
    image = np.asarray(fig.canvas.buffer_rgba())[:, :, :3].copy()
    plt.close(fig)
    return image


def plot_evaluation(results: dict, path: str | os.PathLike) -> Path:
    """Mean RMSE per policy with 95 % intervals, and each flight's RMSE (paired lines)."""
    plt = _pyplot()
    names = list(results["policies"])
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5), constrained_layout=True)
    means = [results["policies"][n]["rmse_nt_mean"] for n in names]
    ci = np.array([results["policies"][n]["rmse_nt_ci95"] for n in names])
    axes[0].bar(names, means, yerr=[np.subtract(means, ci[:, 0]), np.subtract(ci[:, 1], means)],
                capsize=4, color="tab:blue", alpha=0.8)  # fmt: skip
    axes[0].set(ylabel="compensation RMSE [nT]", title=f"{results['scenario']}: mean, 95 % CI")
    axes[0].set_yscale("log")
    per = np.array([results["policies"][n]["rmse_nt"] for n in names])
    axes[1].plot(names, per, color="0.5", lw=0.5, alpha=0.6)
    axes[1].set(ylabel="RMSE per flight [nT]", title="each flight across policies (paired)")
    axes[1].set_yscale("log")
    for ax in axes:
        ax.tick_params(axis="x", rotation=30)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
    return Path(path)
