"""The workflows' figures of ``aeromag bench``: simulating a flight-hour (against IGRF at every
sample), the discrepancy workflow per flight-hour, and the peak memory of ``aeromag compensate``'s
job on a 10-hour flight in a fresh process (against the same process after its imports)."""

from __future__ import annotations

import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from aeromag_env.flight.data import Flight
from aeromag_env.simulation.config import preset, with_overrides


def median_seconds(fn: Callable[[], object], repeats: int) -> float:
    """Median wall time of ``repeats`` calls of ``fn`` [s]."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def hour_flight(hours: float = 1.0) -> Flight:
    """The benchmarks' data: a 1-hour (or ``hours``) 10 Hz ``nominal`` calibration+survey
    flight, seed 0."""
    from aeromag_env.simulation.simulate import simulate_flight

    return simulate_flight(_hour_config(hours), 0)


def _hour_config(hours: float = 1.0) -> Any:
    return with_overrides(
        preset("nominal"),
        {"trajectory.pattern": "calibration+survey", "trajectory.duration_s": 3600.0 * hours},
    )


def bench_simulate(repeats: int, hours: float = 1.0) -> dict[str, float]:
    """Seconds per simulated flight-hour (of a ``hours``-long flight): coarse-grid IGRF vs
    IGRF at every sample, both cold (the pattern and its IGRF not remembered from an earlier
    run); and warm: the same pattern again with another seed, as every episode of a training
    run flies it."""
    from aeromag_env.simulation.simulate import clear_caches, simulate_flight

    cfg = _hour_config(hours)
    every_sample = with_overrides(cfg, {"earth.igrf_grid_spacing_s": 0.1})
    simulate_flight(cfg, 0)  # warm the rest (ppigrf coefficient file, imports)

    def cold(c: Any) -> Callable[[], object]:
        def run() -> object:
            clear_caches()
            return simulate_flight(c, 0)

        return run

    grid = median_seconds(cold(cfg), repeats)
    ref = median_seconds(cold(every_sample), repeats)
    simulate_flight(cfg, 0)
    warm = median_seconds(lambda: simulate_flight(cfg, 1), repeats)
    return {
        "simulate_s_per_flight_hour": grid / hours,
        "simulate_direct_igrf_s_per_flight_hour": ref / hours,
        "simulate_warm_s_per_flight_hour": warm / hours,
    }


def bench_discover(flight: Flight, repeats: int) -> dict[str, float | None]:
    """Seconds of the discrepancy workflow per flight-hour (null without the module)."""
    try:
        from aeromag_env.discovery.workflow import discover
    except ImportError:
        return {"discover_s_per_flight_hour": None}
    hours = (float(flight.tt[-1]) - float(flight.tt[0])) / 3600.0
    seconds = median_seconds(lambda: discover(flight, flux="flux_a"), repeats)
    return {"discover_s_per_flight_hour": seconds / hours if hours > 0 else None}


#: The memory benchmark's process: ``aeromag compensate FILE --method kf --out OUT``'s job,
#: the peak after its imports and at the end.
_MEMORY_PROBE = """
import sys
from aeromag_env.jobs.bench.workflows import peak_rss_mb
from aeromag_env.jobs.compensate import compensate
base = peak_rss_mb()
compensate(sys.argv[1], "kf", sys.argv[2])
print(0, base, peak_rss_mb())
"""


def peak_rss_mb() -> float:
    """Peak resident memory of this process so far [MB]: ``VmHWM`` (Linux; it starts afresh at
    ``exec``, unlike ``ru_maxrss``, which a child inherits from the parent it was forked from),
    else ``ru_maxrss``."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    import resource

    scale = 1 if sys.platform == "darwin" else 1024  # bytes on macOS, KiB elsewhere
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * scale / 2**20


def bench_memory(hours: float = 10.0) -> dict[str, float]:
    """Peak RSS of ``aeromag compensate --method kf`` on a ``hours``-long 10 Hz flight [MB]."""
    from aeromag_env.flight.files import write_flight
    from aeromag_env.simulation.simulate import simulate_flight

    with tempfile.TemporaryDirectory() as tmp:
        path = write_flight(simulate_flight(_hour_config(hours), 0), Path(tmp) / "long.h5")
        res = subprocess.run(
            [sys.executable, "-c", _MEMORY_PROBE, str(path), f"{tmp}/out"],
            capture_output=True,
            text=True,
            check=True,
        )
    status, base, peak = res.stdout.split()[-3:]
    if status != "0":
        raise RuntimeError(f"aeromag compensate failed in the memory benchmark: {res.stderr}")
    return {"compensate_10h_peak_mb": float(peak), "compensate_baseline_mb": float(base)}
