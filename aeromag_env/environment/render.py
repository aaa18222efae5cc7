"""``render_mode="rgb_array"`` of the tuning environment (matplotlib, imported lazily)."""

from __future__ import annotations

from typing import Any

import numpy as np

from aeromag_env.flight.plot import pyplot


def render_episode(env: Any) -> np.ndarray:
    """The episode so far as an RGB array (H, W, 3) uint8: error, ROR/QOQ, Q and R scales."""
    plt = pyplot()
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
