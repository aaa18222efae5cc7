"""Random processes shared by the simulator stages: first-order Gauss–Markov (FOGM) noise.

Every draw comes from the ``numpy.random.Generator`` passed in; nothing touches global state.
"""

from __future__ import annotations

import numpy as np


def fogm(
    n: int, dt_s: float, std: float, tau_s: float, rng: np.random.Generator, dims: int = 1
) -> np.ndarray:
    """Stationary first-order Gauss–Markov process, exactly discretised.

    Parameters
    ----------
    n : int
        Number of samples.
    dt_s : float
        Sample interval [s].
    std : float
        Stationary standard deviation [unit of the output].
    tau_s : float
        Correlation time [s]; the autocorrelation is ``std² exp(-|lag| / tau_s)``.
    rng : numpy.random.Generator
    dims : int
        Number of independent channels.

    Returns
    -------
    ndarray, shape (n,) if ``dims == 1`` else (n, dims)

    Notes
    -----
    ``x[k] = a x[k-1] + sqrt(1 - a²) std w[k]`` with ``a = exp(-dt/tau)``, ``w ~ N(0, 1)``, and
    ``x[0] ~ N(0, std²)`` so the process is stationary from the first sample.
    """
    from scipy.signal import lfilter  # lazy: keeps `import aeromag_env` light

    out_shape = (n,) if dims == 1 else (n, dims)
    if std == 0.0 or n == 0:
        return np.zeros(out_shape)
    a = float(np.exp(-dt_s / tau_s))
    w = rng.standard_normal((n, dims))
    w[1:] *= np.sqrt(1.0 - a * a)
    x0 = w[0].copy()
    w[0] = 0.0
    x, _ = lfilter([1.0], [1.0, -a], w, axis=0, zi=(a * x0)[None, :])
    x = std * x
    x[0] = std * x0
    return x[:, 0] if dims == 1 else x
