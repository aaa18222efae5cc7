"""Figure of an evaluation: every policy on the same flights (matplotlib, lazily)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from aeromag_env.atomic import atomic_path
from aeromag_env.flight.plot import pyplot


def plot_evaluation(results: dict, path: str | os.PathLike) -> Path:
    """Mean RMSE per policy with 95 % intervals, and each flight's RMSE (paired lines)."""
    plt = pyplot()
    names = list(results["policies"])
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5), constrained_layout=True)
    means = [results["policies"][n]["rmse_nt_mean"] for n in names]
    ci = np.array([results["policies"][n]["rmse_nt_ci95"] for n in names])
    axes[0].bar(
        names,
        means,
        yerr=[np.subtract(means, ci[:, 0]), np.subtract(ci[:, 1], means)],
        capsize=4,
        color="tab:blue",
        alpha=0.8,
    )
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
