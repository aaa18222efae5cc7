"""Compiled innovation-consistency checks of the recursive compensators.

Called by the per-sample loop (:func:`aeromag_env.compensation.kernels.advance`) for every
method; the thresholds, and what they were measured against, are in
:mod:`aeromag_env.compensation.kernel_layout`.

* **outlier gate** (:func:`outlier`): a sample whose innovation ``r`` is inconsistent both with
  the filter's own prediction (``rᵀ S⁻¹ r > GATE_NIS``) and with the recent innovations
  (``|r|² > GATE_POWER · max(ref, mean |r|²)``: ``ref`` the mean ``|r|²`` of the window's last
  full lap, the mean over the window as it is) is rejected: predict only, not added to the
  window, not adapted to, counted (``INTS.out``). Each test alone is met by clean runs: a
  too-small R (an environment's action) makes every ``rᵀ S⁻¹ r`` large, and an action that
  swings Q by decades can make the innovations of one lap tiny against the next; the filter's
  covariance or the window's own innovations then say so. Both tests together meet a spike, or
  the first sample of a burst of noise. For a window after a rejection the gate is
  ``|r|² > GATE_POWER_AFTER · ref`` alone: the rest of a burst is rejected too, and the samples
  of it that slipped through do not raise ``ref`` until a lap of them has been accepted. The
  gate is armed once a first lap is full; an innovation whose square overflows is left to the
  divergence check.
* **sustained inconsistency** (:func:`reject`): a whole window of consecutive rejections whose
  mean carries more than ``SHIFT_FRACTION`` of their power is a shift of the data (a step far
  beyond what the filter can follow), not noise: the loop restarts the filter from its last
  good state with ``P(0)``, ``Q(0)``, ``R(0)`` and an empty window (:func:`clear_window`),
  counted as a divergence; the gate is then disarmed until a lap has refilled, so the new level
  becomes the reference and a step is never gated for ever. A run of zero-mean rejections (a
  sensor's burst of noise) stays rejected: the filter keeps its estimate.
* **runaway** (:func:`runaway`): checked once per window by the adaptive methods, whose own
  rules move Q and R (a feedback that can run away: Sage–Husa's R and the estimate error grow
  together under large noise): innovations with more than ``RUNAWAY_POWER`` times the power of
  the measurements over the window — an estimate 2× farther from the data than no estimate —
  are a divergence, restarted as a sustained inconsistency, and the filter goes on as the
  plain KF with ``Q(0)``, ``R(0)`` for the rest of the flight (``INTS.fell_back``): restarted
  but still adapting, fakf and Sage–Husa ran away again and again under 1e3 nT noise.
"""

from __future__ import annotations

import numpy as np

from aeromag_env.compensation.kernel_layout import (
    ACC,
    GATE_NIS,
    GATE_POWER,
    GATE_POWER_AFTER,
    INTS,
    RUNAWAY_POWER,
    SHIFT_FRACTION,
)
from aeromag_env.numba_cache import njit

#: Compiled as :data:`aeromag_env.compensation.kernels.per_sample` (without numba's runtime:
#: they neither allocate nor copy arrays).
per_sample = njit(cache=True, _nrt=False)  # type: ignore[call-overload]


@per_sample
def outlier(r: np.ndarray, sinv: np.ndarray, acc: np.ndarray, ints: np.ndarray) -> bool:
    """The innovation ``r`` (3,) [nT] fails the gate (``sinv`` is S⁻¹): a reference is set and
    ``|r|²`` is finite, and either ``|r|² > GATE_POWER · max(ref, mean |r|² of the window)`` and
    ``rᵀ S⁻¹ r > GATE_NIS``, or, within a window after a rejection,
    ``|r|² > GATE_POWER_AFTER · ref``."""
    ref = acc[ACC.ref]
    rr = r[0] ** 2 + r[1] ** 2 + r[2] ** 2
    out = False
    if ref > 0.0 and rr < np.inf:
        if ints[INTS.calm] < ints[INTS.window]:
            out = rr > GATE_POWER_AFTER * ref
        elif rr > GATE_POWER * max(ref, acc[ACC.rr] / ints[INTS.updates]):
            nis = 0.0  # rᵀ S⁻¹ r
            for i in range(3):
                nis += r[i] * (sinv[i, 0] * r[0] + sinv[i, 1] * r[1] + sinv[i, 2] * r[2])
            out = nis > GATE_NIS
    if not out:
        ints[INTS.calm] += 1
        ints[INTS.run] = 0
    return out


@per_sample
def reject(r: np.ndarray, acc: np.ndarray, ints: np.ndarray) -> bool:
    """Count the rejected innovation ``r`` (3,) [nT] into the run of rejections; True when the
    run has lasted a whole window and looks like a shift (the caller restarts the filter)."""
    if ints[INTS.run] == 0:
        for a in range(ACC.run, ACC.run_rr + 1):
            acc[a] = 0.0
    ints[INTS.out] += 1
    ints[INTS.run] += 1
    ints[INTS.calm] = 0
    for i in range(3):
        acc[ACC.run + i] += r[i]
    acc[ACC.run_rr] += r[0] ** 2 + r[1] ** 2 + r[2] ** 2
    n = ints[INTS.run]
    if n < ints[INTS.window]:
        return False
    mean_power = (acc[ACC.run] ** 2 + acc[ACC.run + 1] ** 2 + acc[ACC.run + 2] ** 2) / n
    return mean_power > SHIFT_FRACTION * acc[ACC.run_rr]  # |Σr|²/n² > f Σ|r|²/n


@per_sample
def clear_window(acc: np.ndarray, ints: np.ndarray) -> None:
    """Empty the innovation window (its buffers are overwritten as it refills), its reference
    and the run of rejections."""
    for a in range(acc.shape[0]):
        acc[a] = 0.0
    ints[INTS.updates] = 0
    ints[INTS.pos] = 0
    ints[INTS.run] = 0
    ints[INTS.calm] = 0


@per_sample
def runaway(k: int, y: np.ndarray, est: np.ndarray, valid: np.ndarray, ints: np.ndarray) -> bool:
    """At the end of a lap of the window (once per window): over the valid samples among the
    last M up to k, ``Σ |y − H z⁻|² > RUNAWAY_POWER · Σ |y|²`` (``y`` (n, 3) the measurements,
    ``est`` (n, 3) the a-priori estimates [nT])."""
    if ints[INTS.pos] != 0 or ints[INTS.updates] == 0:
        return False
    num, den = 0.0, 0.0
    for j in range(max(0, k + 1 - ints[INTS.window]), k + 1):
        if valid[j]:
            for i in range(3):
                num += (y[j, i] - est[j, i]) ** 2
                den += y[j, i] ** 2
    return den > 0.0 and num > RUNAWAY_POWER * den
