"""A read-only view of what the simulation knows about the flight being flown.

The privileged baselines (``oracle``, ``privileged``, ``tuned_constant``: simulation only, the
anchors of the normalized score) read the true noise, the interference steps and where the
filter is; :func:`flight_truth` gives them that as a frozen dataclass whose arrays are
read-only views, so that a policy cannot change the environment it is evaluated in.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from aeromag_env.compensation.model import MODE

#: The filter's compiled mode (an int) → its method name.
_METHODS = {int(mode): name for name, mode in MODE.items()}


@dataclass(frozen=True)
class FlightTruth:
    """The current flight and filter of one environment, as of the next step.

    Attributes
    ----------
    scenario : the scenario flown (for ``suite``, the one drawn)
    n : samples in the flight
    sample : the next sample the filter processes (0 after ``reset``)
    noise_var : (n,) true per-axis variance of the sensor noise [nT²] (read-only)
    step_samples : sorted sample indices at which an interference step starts (read-only)
    q_log10_true : the Q the truth implies, log10 of its ratio to the initial Q: (induced and
        eddy blocks, T_p between steps) (:class:`~aeromag_env.environment.scenarios.Episode`)
    r0_nt2 : mean of the diagonal of the filter's initial R [nT²]
    log_scales : natural logs of the cumulative Q and R scales relative to their initial values
    filter_method : the filter's method (``kf`` unless ``reset``'s ``filter_method`` option)
    """

    scenario: str
    n: int
    sample: int
    noise_var: np.ndarray
    step_samples: np.ndarray
    q_log10_true: tuple[float, float]
    r0_nt2: float
    log_scales: tuple[float, float]
    filter_method: str


def flight_truth(env: Any) -> FlightTruth:
    """The read-only :class:`FlightTruth` of ``env`` (an ``AeroMagCompensation-v0``, wrapped
    or not, after ``reset``); reading it leaves ``env`` unchanged."""
    inner = env.unwrapped
    ep, f = inner.episode, inner.filter
    return FlightTruth(
        scenario=ep.scenario,
        n=ep.n,
        sample=int(f.k),
        noise_var=_read_only(ep.noise_var),
        step_samples=_read_only(ep.step_samples),
        q_log10_true=ep.q_log10_true,
        r0_nt2=float(np.mean(np.diag(f.r0))),
        log_scales=inner.log_scales,
        filter_method=_METHODS[int(f.mode)],
    )


def _read_only(a: np.ndarray) -> np.ndarray:
    """A view of ``a`` that refuses writes (``a`` itself stays writeable)."""
    view = a.view()
    view.flags.writeable = False
    return view
