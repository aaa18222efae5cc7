"""``render_mode="rgb_array"`` of the tuning environments (matplotlib, imported lazily): the
single environment's episode, and each of the vector environment's."""

from __future__ import annotations

from typing import Any

import numpy as np

from aeromag_env.flight.plot import pyplot


def render_episode(env: Any) -> np.ndarray:
    """The single environment's episode so far as an RGB array (H, W, 3) uint8, against time."""
    k, f = env.filter.k, env.filter
    err = env.episode.truth_interf[:k] - f.est[:k]
    x = env.episode.flight.tt[:k]
    return render_panels(
        env.scenario, x, "time [s]", err, f.ror[:k], f.qoq[:k], f.q_scale[:k], f.r_scale[:k]
    )


def render_vector(scenarios: list[str], k: np.ndarray, truth: np.ndarray, filters: Any) -> tuple:
    """Each of a vector environment's episodes so far as :func:`render_episode` draws it (x in
    samples: the batched filters keep no time axis): ``k`` (N,) samples done, ``truth`` (N, L, 3)
    true interference [nT], ``filters`` the stacked filter states."""
    frames = []
    for i, n in enumerate(k.tolist()):
        err, f = truth[i, :n] - filters.est[i, :n], filters
        frames.append(
            render_panels(
                scenarios[i],
                np.arange(n),
                "sample",
                err,
                f.ror[i, :n],
                f.qoq[i, :n],
                f.q_scale[i, :n],
                f.r_scale[i, :n],
            )
        )
    return tuple(frames)


def render_panels(
    scenario: str,
    x: np.ndarray,
    xlabel: str,
    err: np.ndarray,
    ror: np.ndarray,
    qoq: np.ndarray,
    q_scale: np.ndarray,
    r_scale: np.ndarray,
) -> np.ndarray:
    """Three panels as an RGB array (H, W, 3) uint8: the error (n, 3) [nT], ROR/QOQ, Q and R
    scales, each (n,), against ``x``."""
    plt = pyplot()
    fig, axes = plt.subplots(3, 1, figsize=(8, 6), sharex=True, constrained_layout=True)
    axes[0].plot(x, err, lw=0.6)
    axes[0].set(ylabel="[nT]", title=f"{scenario}: true − estimated interference")
    k = x.size
    if k and np.isfinite(err[k // 2 :]).any():
        lim = float(np.nanpercentile(np.abs(err[k // 2 :]), 99)) * 2 + 1.0
        axes[0].set_ylim(-lim, lim)
    axes[1].semilogy(x, ror, lw=0.6, label="ROR")
    axes[1].semilogy(x, qoq, lw=0.6, label="QOQ")
    axes[1].legend(loc="upper right")
    axes[2].semilogy(x, q_scale, lw=0.8, label="Q scale")
    axes[2].semilogy(x, r_scale, lw=0.8, label="R scale")
    axes[2].legend(loc="upper right")
    axes[2].set_xlabel(xlabel)
    fig.canvas.draw()
    image = np.asarray(fig.canvas.buffer_rgba())[:, :, :3].copy()
    plt.close(fig)
    return image
