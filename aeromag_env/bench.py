"""Speed benchmarks for ``aeromag bench``: every figure is measured side by side with its
reference in the same run (these machines are noisy), repeated, and reported as a median.

Figures so far:

* ``simulate_s_per_flight_hour`` — seconds to simulate a 1-hour 10 Hz ``nominal``
  calibration+survey flight (target < 1 s), against ``simulate_direct_igrf_s_per_flight_hour``,
  the same flight with IGRF evaluated directly at every sample instead of on the coarse grid.
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


def run_benchmarks(out: Path, quick: bool = False) -> dict[str, Any]:
    """Run every benchmark, print a table with ratios, write ``out/bench.json``."""
    repeats = 3 if quick else 7
    figures = bench_simulate(repeats)
    rows = [
        (
            "simulate 1 flight-hour (grid IGRF)",
            figures["simulate_s_per_flight_hour"],
            "s",
            figures["simulate_direct_igrf_s_per_flight_hour"]
            / figures["simulate_s_per_flight_hour"],
            "× faster than IGRF at every sample",
        ),
    ]
    print(f"{'benchmark':<40} {'value':>10}  ratio")
    for name, value, unit, ratio, what in rows:
        print(f"{name:<40} {value:>8.3f} {unit}  {ratio:.1f} {what}")
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
