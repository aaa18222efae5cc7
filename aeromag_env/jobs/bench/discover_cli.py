"""``aeromag discover`` as a user runs it: a fresh process on a flight file, figures and page
included (:func:`bench_discover_cli`).

Each measured run is ``aeromag discover FILE --out DIR`` (the command line's ``main``) in a new
process, on a simulated 10 Hz ``nominal`` calibration+survey flight of ``hours`` flight-hours
(seed 0, the flight of ``aeromag bench``); its wall time counts the interpreter's start, the
imports, reading, the workflow, ``report.json``/``report.md``, both PNG figures and
``report.html``. Peak memory is the child's own peak resident set (``VmHWM``, which the child
reports as it ends; ``ru_maxrss`` would carry the benchmark's own memory across the ``exec``).
A first, unmeasured run per file warms the disk cache and numba's compiled-kernel cache, as any
user's second run finds them.

The machines these run on are shared: every figure is a median of repeats, the CPU time (user
+ system) is reported beside the wall time, and the 1-minute load average before and after is
kept with the figures.
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from aeromag_env.errors import AeromagError

#: Flight lengths measured by default [flight-hours] (``--quick``: :data:`QUICK_HOURS`).
HOURS = (1.0, 4.0)
QUICK_HOURS = (0.5,)
#: Measured runs per flight length (the median is reported).
REPEATS = 3
#: The targets: wall seconds per flight-hour, and peak resident memory of a 1-hour run [MB].
TARGET_S_PER_FLIGHT_HOUR = 5.0
TARGET_PEAK_MB_1H = 600.0


@dataclass(frozen=True)
class Run:
    """One fresh ``aeromag discover`` process: wall and CPU seconds, peak resident memory [MB]."""

    wall_s: float
    cpu_s: float
    peak_mb: float | None


def bench_discover_cli(
    hours: Sequence[float] = HOURS, repeats: int = REPEATS, workdir: Path | None = None
) -> dict[str, Any]:
    """Seconds per flight-hour and peak memory of ``aeromag discover`` as a user runs it.

    Parameters
    ----------
    hours : sequence of float
        Flight lengths [flight-hours], each > 0.2 (discovery needs 5 min of calibration).
    repeats : int
        Measured runs per length, ≥ 1 (plus one unmeasured warm-up run).
    workdir : Path or None
        Where the flights and outputs go (a temporary folder when None, removed after).

    Returns
    -------
    dict
        Per length, with ``L`` its label (``1h``, ``4h``, ``0.5h``):
        ``discover_cli_L_s_per_flight_hour`` (median wall time / hours),
        ``discover_cli_L_cpu_s_per_flight_hour`` (median user + system time / hours) and
        ``discover_cli_L_peak_mb`` (median peak resident memory [MB], None where the child
        could not say it); then ``discover_cli_peak_growth_mb_per_flight_hour`` (the peak's growth
        between the shortest and the longest flight, per flight-hour; None with one length),
        ``discover_cli_repeats``, ``discover_cli_load`` (1-minute load average before and
        after; None where unknown) and the targets ``discover_cli_target_s_per_flight_hour``
        and ``discover_cli_target_peak_mb_1h``.

    Raises
    ------
    AeromagError
        A length ≤ 0.2 h or ``repeats`` < 1 (one line); a run that fails (its stderr's last
        line).
    """
    if repeats < 1:
        raise AeromagError(f"repeats must be ≥ 1, got {repeats}")
    if not hours or min(hours) <= 0.2:
        raise AeromagError(f"hours must each be > 0.2 flight-hours, got {list(hours)}")
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        load_before = _load()
        runs = {h: _measure(Path(tmp), h, repeats) for h in hours}
        load_after = _load()
    figures: dict[str, Any] = {}
    for h, measured in runs.items():
        label = f"discover_cli_{h:g}h"
        peaks = [r.peak_mb for r in measured if r.peak_mb is not None]
        figures[f"{label}_s_per_flight_hour"] = statistics.median(r.wall_s for r in measured) / h
        figures[f"{label}_cpu_s_per_flight_hour"] = statistics.median(r.cpu_s for r in measured) / h
        figures[f"{label}_peak_mb"] = statistics.median(peaks) if peaks else None
    lo, hi = min(hours), max(hours)
    peak_lo, peak_hi = (
        figures[f"discover_cli_{lo:g}h_peak_mb"],
        figures[f"discover_cli_{hi:g}h_peak_mb"],
    )
    growth = None if hi == lo or None in (peak_lo, peak_hi) else (peak_hi - peak_lo) / (hi - lo)
    return figures | {
        "discover_cli_peak_growth_mb_per_flight_hour": growth,
        "discover_cli_repeats": repeats,
        "discover_cli_load": [load_before, load_after],
        "discover_cli_target_s_per_flight_hour": TARGET_S_PER_FLIGHT_HOUR,
        "discover_cli_target_peak_mb_1h": TARGET_PEAK_MB_1H,
    }


def _measure(tmp: Path, hours: float, repeats: int) -> list[Run]:
    """A warm-up run, then ``repeats`` measured runs, on a fresh ``hours``-long flight file."""
    path = write_hour_flight(tmp / f"flight_{hours:g}h.h5", hours)
    _run(path, tmp / "warm-up")
    return [_run(path, tmp / f"out_{hours:g}h_{k}") for k in range(repeats)]


def write_hour_flight(path: Path, hours: float) -> Path:
    """Simulate the benchmarks' flight (``nominal``, calibration+survey, 10 Hz, seed 0) of
    ``hours`` flight-hours and write it to ``path``."""
    from aeromag_env.flight.files import write_flight
    from aeromag_env.simulation.config import preset, with_overrides
    from aeromag_env.simulation.simulate import simulate_flight

    cfg = with_overrides(
        preset("nominal"),
        {"trajectory.pattern": "calibration+survey", "trajectory.duration_s": 3600.0 * hours},
    )
    return write_flight(simulate_flight(cfg, 0), path)


#: The tag of the child's last stderr line, its peak resident memory [MB].
PEAK_TAG = "peak_mb"
#: The child's program: ``aeromag discover`` as the console script runs it, then its own peak
#: resident memory on stderr (``VmHWM``: ``ru_maxrss`` of a child keeps the memory of the
#: process it was forked from, here the benchmark's, across ``exec``).
_PROBE = (
    "import sys\n"
    "from aeromag_env.cli.main import main\n"
    "from aeromag_env.jobs.bench.workflows import peak_rss_mb\n"
    "code = main(sys.argv[1:])\n"
    f"print('{PEAK_TAG}', peak_rss_mb(), file=sys.stderr)\n"
    "sys.exit(code)\n"
)


def _run(path: Path, out: Path) -> Run:
    """``aeromag discover path --out out`` in a fresh process: its wall and CPU time and peak
    resident memory (its own, :data:`_PROBE`)."""
    cmd = [sys.executable, "-c", _PROBE, "discover", str(path), "--out", str(out)]
    t0 = time.perf_counter()
    child = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    stderr = child.stderr.read() if child.stderr else ""
    if hasattr(os, "wait4"):
        _, status, usage = os.wait4(child.pid, 0)
        wall = time.perf_counter() - t0
        child.returncode = os.waitstatus_to_exitcode(status)
        cpu = usage.ru_utime + usage.ru_stime
    else:  # no per-child resource usage
        child.wait()
        wall = time.perf_counter() - t0
        cpu = float("nan")
    lines = stderr.strip().splitlines()
    if child.returncode != 0:
        last = next((x for x in reversed(lines) if not x.startswith(PEAK_TAG)), None)
        raise AeromagError(
            f"aeromag discover failed in the benchmark: {last or f'exit {child.returncode}'}"
        )
    peaks = [float(x.split()[1]) for x in lines if x.startswith(PEAK_TAG + " ")]
    return Run(wall, cpu, peaks[-1] if peaks else None)


def _load() -> float | None:
    """The 1-minute load average (None where the system has none)."""
    try:
        return float(os.getloadavg()[0])
    except (AttributeError, OSError):
        return None


def discover_cli_rows(f: dict[str, Any]) -> list[tuple[str, str, str, str, bool | None]]:
    """The table's rows of :func:`bench_discover_cli`'s figures: per flight length the wall
    seconds per flight-hour (target :data:`TARGET_S_PER_FLIGHT_HOUR`) and the peak memory
    (target :data:`TARGET_PEAK_MB_1H` for the 1-hour flight; the others against its growth)."""
    out: list[tuple[str, str, str, str, bool | None]] = []
    lengths = sorted(
        float(k.removeprefix("discover_cli_").removesuffix("h_s_per_flight_hour"))
        for k in f
        if k.startswith("discover_cli_") and k.endswith("h_s_per_flight_hour")
    )
    for h in lengths:
        label = f"discover_cli_{h:g}h"
        wall, cpu = f[f"{label}_s_per_flight_hour"], f[f"{label}_cpu_s_per_flight_hour"]
        peak = f[f"{label}_peak_mb"]
        out.append(
            (
                f"aeromag discover, fresh process, {h:g} flight-hour file",
                f"{wall:.2f} s per flight-hour",
                f"CPU {cpu:.2f} s per flight-hour",
                f"≤ {TARGET_S_PER_FLIGHT_HOUR:g} s",
                wall <= TARGET_S_PER_FLIGHT_HOUR,
            )
        )
        out.append(
            (
                f"aeromag discover, {h:g} flight-hour file, peak RSS",
                "n/a" if peak is None else f"{peak:.0f} MB",
                "n/a"
                if f.get("discover_cli_peak_growth_mb_per_flight_hour") is None
                else f"grows {f['discover_cli_peak_growth_mb_per_flight_hour']:.0f} MB per "
                "flight-hour",
                f"≤ {TARGET_PEAK_MB_1H:g} MB" if h == 1.0 else "",
                None if peak is None or h != 1.0 else peak <= TARGET_PEAK_MB_1H,
            )
        )
    return out
