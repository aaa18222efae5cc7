"""The plain-numpy pieces both references share: the Kalman prediction and update, in
filterpy's procedural style, and the consistency checks of
:mod:`aeromag_env.compensation.consistency` written out.

Used by :mod:`aeromag_env.compensation.kalman_reference` (the KF and its classical adaptive
variants) and :mod:`aeromag_env.compensation.adaptive_reference` (the variational filters and the
bank of models).
"""

from __future__ import annotations

import numpy as np

from aeromag_env.compensation.kernel_layout import (
    GATE_NIS,
    GATE_POWER,
    GATE_POWER_AFTER,
    RUNAWAY_POWER,
    SHIFT_FRACTION,
)


def kf_predict(x: np.ndarray, p: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eqs. 17–18 with ``Φ = I``: ``x⁻ = x``, ``P⁻ = P + Q``."""
    return x.copy(), p + q  # P⁻ = Φ P Φᵀ + Q


def kf_update(
    x: np.ndarray, p: np.ndarray, y: np.ndarray, h: np.ndarray, r: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Eqs. 19–20, Joseph form. Returns ``x⁺, P⁺, innovation, S, K``.

    Shapes: x (21,), p (21, 21), y (3,), h (3, 21), r (3, 3).
    """
    innov = y - h @ x  # r = y − H x⁻
    s = h @ p @ h.T + r  # S = H P⁻ Hᵀ + R
    k = p @ h.T @ np.linalg.inv(s)  # K = P⁻ Hᵀ S⁻¹
    i_kh = np.eye(x.size) - k @ h
    p_new = i_kh @ p @ i_kh.T + k @ r @ k.T  # Joseph: (I − KH) P⁻ (I − KH)ᵀ + K R Kᵀ
    return x + k @ innov, 0.5 * (p_new + p_new.T), innov, s, k


class Consistency:
    """The checks of :mod:`aeromag_env.compensation.consistency`, written out: the outlier gate
    (its lap reference, the run of rejections and the calm samples since the last) and the
    runaway test."""

    def __init__(self, window: int) -> None:
        self.m = window
        self.clear()

    def clear(self) -> None:
        self.ref, self.adds, self.calm, self.run = 0.0, 0, 0, 0
        self.run_sum, self.run_power = np.zeros(3), 0.0

    def outlier(self, innov: np.ndarray, s: np.ndarray, window: list) -> bool:
        power = float(innov @ innov)
        out = False
        if self.ref > 0 and np.isfinite(power):
            if self.calm < self.m:  # within a window after a rejection: the last lap's mean
                out = power > GATE_POWER_AFTER * self.ref
            else:  # |r|² against the last lap's and the window's mean, and rᵀ S⁻¹ r
                recent = max(self.ref, float(np.mean([v @ v for v, _ in window])))
                nis = innov @ np.linalg.inv(s) @ innov
                out = power > GATE_POWER * recent and nis > GATE_NIS
        if not out:
            self.calm, self.run = self.calm + 1, 0
        return bool(out)

    def reject(self, innov: np.ndarray) -> bool:
        """Count a rejection; True for a whole window of them that shifts the data."""
        if self.run == 0:
            self.run_sum, self.run_power = np.zeros(3), 0.0
        self.run, self.calm = self.run + 1, 0
        self.run_sum = self.run_sum + innov
        self.run_power += float(innov @ innov)
        mean_power = float(self.run_sum @ self.run_sum) / self.run  # |Σr|²/n² against Σ|r|²/n
        return self.run >= self.m and mean_power > SHIFT_FRACTION * self.run_power

    def added(self, window: list) -> bool:
        """An innovation entered the window; True at the end of a lap (a new reference)."""
        self.adds += 1
        if self.adds % self.m:
            return False
        self.ref = float(np.mean([v @ v for v, _ in window]))
        return True


def runaway(k: int, m: int, y: np.ndarray, est: np.ndarray, valid: np.ndarray) -> bool:
    """Over the valid samples among the last m up to k: Σ|y − H z⁻|² > RUNAWAY_POWER Σ|y|²."""
    rows = slice(max(0, k + 1 - m), k + 1)
    ok = valid[rows]
    num, den = np.sum((y[rows] - est[rows])[ok] ** 2), np.sum(y[rows][ok] ** 2)
    return bool(den > 0 and num > RUNAWAY_POWER * den)
