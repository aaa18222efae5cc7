"""Sensor noise: white, first-order Gauss–Markov (FOGM) and linear drift, per channel."""

from __future__ import annotations

import numpy as np

from aeromag_env.noise import fogm
from aeromag_env.simulation.config import SensorNoiseConfig


def sensor_noise(
    n: int, dt_s: float, cfg: SensorNoiseConfig, rng: np.random.Generator, dims: int = 3
) -> np.ndarray:
    """Additive noise of one sensor.

    Parameters
    ----------
    n : int
        Number of samples.
    dt_s : float
        Sample interval [s].
    cfg : SensorNoiseConfig
        ``white_std_nt`` [nT], ``fogm_std_nt`` [nT] with ``fogm_tau_s`` [s], and
        ``drift_std_nt_per_h``: each channel drifts linearly at a rate drawn ``N(0, std²)`` [nT/h].
    rng : numpy.random.Generator
    dims : int
        3 for a fluxgate, 1 for a scalar sensor.

    Returns
    -------
    ndarray, shape (n, dims), or (n,) when ``dims == 1`` [nT]
    """
    white = cfg.white_std_nt * rng.standard_normal((n, dims))
    coloured = fogm(n, dt_s, cfg.fogm_std_nt, cfg.fogm_tau_s, rng, dims=dims).reshape(n, dims)
    rate = rng.normal(0.0, cfg.drift_std_nt_per_h, dims) / 3600.0
    drift = (np.arange(n) * dt_s)[:, None] * rate
    out = white + coloured + drift
    return out[:, 0] if dims == 1 else out
