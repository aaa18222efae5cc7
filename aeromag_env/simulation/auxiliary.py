"""Simulated auxiliary channels: on-board currents, voltages and temperatures.

Shapes follow the SGL 2020 channels they stand in for (DESIGN.md, "Data files"): loads switched
on and off (``cur_ac_hi``, ``cur_tank``, ``cur_com_1``), strobe pulses at 40–100 flashes per
minute (``cur_strb``), and a sensor temperature that warms up and follows a thermostat
(``temp_*``). Every draw comes from the generator passed in.
"""

from __future__ import annotations

import numpy as np

from aeromag_env.geo.earth import first_order_lag
from aeromag_env.simulation.config import AuxChannelConfig

#: Rise/fall time of a switched load [s] (inrush and electronics smooth the step).
SWITCH_TAU_S = 0.3
#: Strobe pulse length [s].
STROBE_PULSE_S = 0.2
#: Warm-up time constant of a temperature channel [s].
WARMUP_TAU_S = 900.0


def aux_channel(cfg: AuxChannelConfig, tt: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Sample one auxiliary channel on the time grid ``tt`` [s]; shape (n,)."""
    n = tt.size
    dt = float(np.median(np.diff(tt))) if n > 1 else 1.0
    t = tt - tt[0]
    if cfg.kind == "switching":
        x = _on_off(t, cfg.period_s, rng)
        x = first_order_lag(x * cfg.level, dt, SWITCH_TAU_S)
    elif cfg.kind == "strobe":
        phase = rng.uniform(0.0, cfg.period_s)
        x = cfg.level * (((t + phase) % cfg.period_s) < STROBE_PULSE_S)
    elif cfg.kind == "temperature":
        warm = 1.0 - np.exp(-t / WARMUP_TAU_S)
        cycle = np.abs(((t / cfg.period_s + rng.uniform()) % 1.0) * 2.0 - 1.0) - 0.5  # triangle
        x = cfg.level * (warm + 0.3 * cycle)
    else:  # random_walk
        steps = rng.standard_normal(n) * np.sqrt(dt / cfg.period_s)
        x = cfg.level * first_order_lag(np.cumsum(steps), dt, 5.0)
    return np.asarray(x, float) + cfg.offset


def _on_off(t: np.ndarray, period_s: float, rng: np.random.Generator) -> np.ndarray:
    """0/1 state with exponential dwell times of mean ``period_s / 2``, random initial state."""
    out = np.zeros(t.size)
    state, now = float(rng.integers(0, 2)), 0.0
    while now <= t[-1]:
        dwell = rng.exponential(period_s / 2.0) + 1.0
        out[(t >= now) & (t < now + dwell)] = state
        state, now = 1.0 - state, now + dwell
    return out
