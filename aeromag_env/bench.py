"""Speed benchmarks for ``aeromag bench``: every figure is measured side by side with its
reference in the same run (these machines are noisy), repeated, and reported as a median.

Figures so far:

* ``simulate_s_per_flight_hour`` — seconds to simulate a 1-hour 10 Hz ``nominal``
  calibration+survey flight (target < 1 s), against ``simulate_direct_igrf_s_per_flight_hour``,
  the same flight with IGRF evaluated directly at every sample instead of on the coarse grid.
* ``env_single_steps_per_s`` — ``AeroMagCompensation-v0`` steps per second, one env, K = 10
  (target ≥ 5 000), against ``env_numpy_reference_steps_per_s``: the plain-numpy reference
  filter's samples per second divided by K.
"""

from __future__ import annotations

import json
import platform
import statistics
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from aeromag_env.atomic import write_text
from aeromag_env.config import preset, with_overrides


def _median_seconds(fn: Callable[[], object], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def bench_simulate(repeats: int) -> dict[str, float]:
    """Seconds per simulated flight-hour: coarse-grid IGRF vs IGRF at every sample."""
    from aeromag_env.simulate import simulate_flight

    cfg = with_overrides(
        preset("nominal"),
        {"trajectory.pattern": "calibration+survey", "trajectory.duration_s": 3600.0},
    )
    every_sample = with_overrides(cfg, {"earth.igrf_grid_spacing_s": 0.1})
    simulate_flight(cfg, 0)  # warm caches (ppigrf coefficient file, imports)
    grid = _median_seconds(lambda: simulate_flight(cfg, 0), repeats)
    ref = _median_seconds(lambda: simulate_flight(every_sample, 0), repeats)
    return {"simulate_s_per_flight_hour": grid, "simulate_direct_igrf_s_per_flight_hour": ref}


def bench_env(repeats: int) -> dict[str, float]:
    """Env steps per second (one env, K = 10, zero actions, steps only) against the plain-numpy
    reference filter's samples per second / K (an env stepping that filter)."""
    import gymnasium as gym
    import numpy as np

    from aeromag_env.kalman_model import FilterConfig
    from aeromag_env.kalman_reference import run_reference

    env = gym.make("AeroMagCompensation-v0", scenario="nominal")
    action = np.zeros(2, np.float32)

    def episode() -> float:
        env.reset(seed=100_000)
        t0, steps, done = time.perf_counter(), 0, False
        while not done:
            _, _, terminated, truncated, _ = env.step(action)
            steps, done = steps + 1, terminated or truncated
        return steps / (time.perf_counter() - t0)

    episode()  # warm: numba cache load, first-step checks
    rate = statistics.median(episode() for _ in range(repeats))
    ep = env.unwrapped.episode  # type: ignore[attr-defined]
    n = 1000
    t_ref = _median_seconds(
        lambda: run_reference(FilterConfig(), ep.y[:n], ep.t_b[:n], ep.tdot_b[:n]), 3
    )
    return {"env_single_steps_per_s": rate, "env_numpy_reference_steps_per_s": n / t_ref / 10}


def run_benchmarks(out: Path, quick: bool = False) -> dict[str, Any]:
    """Run every benchmark, print a table with ratios, write ``out/bench.json``."""
    repeats = 3 if quick else 7
    figures = {**bench_simulate(repeats), **bench_env(repeats)}
    rows = [
        ("simulate 1 flight-hour (grid IGRF)", "simulate_s_per_flight_hour", "s",
         figures["simulate_direct_igrf_s_per_flight_hour"] / figures["simulate_s_per_flight_hour"],
         "× faster than IGRF at every sample"),
        ("env steps per second (1 env, K = 10)", "env_single_steps_per_s", "/s",
         figures["env_single_steps_per_s"] / figures["env_numpy_reference_steps_per_s"],
         "× an env stepping the numpy reference filter"),
    ]  # fmt: skip
    print(f"{'benchmark':<40} {'value':>12}  ratio")
    for name, key, unit, ratio, what in rows:
        print(f"{name:<40} {figures[key]:>10.4g} {unit}  {ratio:.1f} {what}")
    result = {
        "figures": figures,
        "repeats": repeats,
        "statistic": "median",
        "machine": {
            "python": platform.python_version(),
            "processor": platform.processor() or platform.machine(),
            "cpus": _cpu_count(),
        },
    }
    path = write_text(out / "bench.json", json.dumps(result, indent=2))
    print(f"wrote {path}")
    return result


def _cpu_count() -> int:
    import os

    return (
        len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    )
