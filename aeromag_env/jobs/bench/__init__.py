"""Speed benchmarks for ``aeromag bench``: every figure is measured side by side with its
reference in the same run (these machines are noisy), repeated, and reported as a median.

Figures (``bench.json`` → ``figures``):

* ``simulate_s_per_flight_hour`` — seconds to simulate a 1-hour 10 Hz ``nominal``
  calibration+survey flight (target < 1 s), against ``simulate_direct_igrf_s_per_flight_hour``,
  the same flight with IGRF evaluated directly at every sample instead of on the coarse grid;
  both cold (:func:`aeromag_env.simulation.simulate.clear_caches` before each run). With it
  ``simulate_warm_s_per_flight_hour``: another seed of the same pattern, whose track and IGRF
  are remembered — what every episode of a training run costs.
* the filters on the first :data:`FILTER_SAMPLES` samples of that flight
  (:mod:`aeromag_env.jobs.bench.filters`): compiled, batched (64 flights), plain numpy, filterpy.
* environments and PPO training (:mod:`aeromag_env.jobs.bench.envs`), with the two targets of
  the environments inside PPO: at 8 environments their cost per environment step at most
  1.5× the bare compiled filter's over the same K samples (``ppo_env_to_filter_ratio``), at
  64 their share of PPO's time at most 20 % (``ppo64_env_share``).
* ``discover_s_per_flight_hour`` — :func:`aeromag_env.discovery.workflow.discover` on the same
1-hour
  flight, against its duration (null when the module is not there).
* ``compensate_10h_peak_mb`` — peak resident memory of a fresh process running ``aeromag
  compensate FILE --method kf``'s job on a 10-hour 10 Hz flight
  (:func:`~aeromag_env.jobs.bench.workflows.peak_rss_mb`: interpreter, libraries, reading,
  filtering, writing and the figure; target < 1 GB), against
  ``compensate_baseline_mb``, the same process after its imports, before the work.
* ``discover_cli_<hours>h_…`` — ``aeromag discover`` as a user runs it, a fresh process on a
  1- and a 4-flight-hour file, figures and page included
  (:mod:`aeromag_env.jobs.bench.discover_cli`): wall and CPU seconds per flight-hour (target
  5 s) and peak resident memory (target 600 MB on the 1-hour file, and its growth per hour).
* ``stream_<method>_…`` — ``aeromag stream``'s latency per sample (median, 99th percentile) and
  its memory over a 10-hour stream (:mod:`aeromag_env.jobs.bench.stream`), for a Tolles–Lawson
  and a Kalman filter model.
"""

from __future__ import annotations

import json
import os
import platform
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from aeromag_env.atomic import check_output_set, write_text
from aeromag_env.errors import ArgumentError
from aeromag_env.jobs.bench.discover_cli import bench_discover_cli, discover_cli_rows
from aeromag_env.jobs.bench.filters import bench_filter_figures
from aeromag_env.jobs.bench.on_ray import bench_ray, ray_rows
from aeromag_env.jobs.bench.stream import HOURS, QUICK_HOURS, bench_stream, stream_rows
from aeromag_env.jobs.bench.table import Row, discover_row, ppo_rows, rows
from aeromag_env.jobs.bench.workflows import (
    bench_discover,
    bench_memory,
    bench_simulate,
    hour_flight,
)
from aeromag_env.jobs.choices import BENCH_ONLY
from aeromag_env.threads import cores

#: Samples of the 1-hour flight the filter figures run on (quick: 1 000).
FILTER_SAMPLES = 6000
#: Repeats of the PPO figures with 8 and 64 environments (quick: 1): each has a target, a
#: median over at least 5.
PPO_REPEATS, PPO64_REPEATS = 5, 5


@dataclass(frozen=True, kw_only=True)
class BenchRequest:
    """What ``aeromag bench`` is asked to measure (validated by :meth:`check`).

    Attributes
    ----------
    out : Path
        The folder of ``bench.json``.
    quick : bool
        The sizes of :data:`agents.training.quick.QUICK` (about a minute; indicative figures).
    ray : str or None
        None: no Ray figures (Ray not imported); ``local`` or an address: measure them there.
    only : str or None
        One of :data:`BENCH_ONLY`, measured alone; None: every figure.
    """

    out: Path
    quick: bool = False
    ray: str | None = None
    only: str | None = None

    def check(self) -> None:
        """One-line errors for an unknown ``only`` or Ray figures without ``ray``."""
        if self.only is not None and self.only not in BENCH_ONLY:
            raise ArgumentError("only", f"must be one of {', '.join(BENCH_ONLY)}", self.only)
        if self.only == "ray" and self.ray is None:
            raise ArgumentError("ray", "is needed to measure the Ray figures")


@dataclass(frozen=True)
class BenchResult:
    """What :func:`bench` measured.

    Attributes
    ----------
    report : dict
        ``bench.json``'s content: ``figures`` (every number), ``rows`` (the table), the repeats,
        the machine and its load before and after.
    rows : list of Row
        The table's rows: benchmark, median, ratio to its reference, target, target met.
    table : str
        The table as text.
    path : Path
        ``bench.json``.
    """

    report: dict[str, Any]
    rows: list[Row]
    table: str
    path: Path


def bench(
    out: str | Path,
    *,
    quick: bool = False,
    ray: str | None = None,
    only: str | None = None,
    progress: Callable[[str], Any] | None = None,
) -> BenchResult:
    """Run the speed benchmarks, as ``aeromag bench`` does: every figure against its reference
    measured in the same run, medians of repeats; writes ``out/bench.json``.

    Parameters
    ----------
    out : str or Path
        The folder of ``bench.json``.
    quick, ray, only
        See :class:`BenchRequest`.
    progress : callable or None
        Called with the name of each group of figures as it starts.

    Returns
    -------
    BenchResult

    Raises
    ------
    AeromagError
        Bad options, or ``bench.json`` not writable, before minutes of work.
    """
    request = BenchRequest(out=Path(out), quick=quick, ray=ray, only=only)
    request.check()
    check_output_set(request.out, ("bench.json",))  # before minutes of work
    say = progress or (lambda stage: None)
    load_before = _load()
    figures, table_rows = _measure(request, say)
    return _report(request, figures, table_rows, load_before)


def _measure(request: BenchRequest, say: Callable[[str], Any]) -> tuple[dict[str, Any], list[Row]]:
    """The figures ``request`` asks for and the rows of its table."""
    from agents.training.quick import QUICK as q

    quick = request.quick
    repeats = q.bench_repeats if quick else 7
    hours = q.bench_flight_hours if quick else 1.0
    figures: dict[str, Any] = {}
    if request.ray is not None:
        say("ray")
        figures |= bench_ray(request.ray, quick)
    if request.only == "ray":
        return figures, ray_rows(figures)
    if request.only == "discover":
        say("discover")
        figures |= bench_discover(hour_flight(hours), 1 if quick else 3)
        figures |= _discover_cli(quick)
        return figures, [discover_row(figures), *discover_cli_rows(figures)]
    if request.only == "stream":
        say("stream")
        figures |= bench_stream(QUICK_HOURS if quick else HOURS)
        return figures, stream_rows(figures)
    if request.only == "ppo":  # a third of a full run's steps per repeat: 3 runs in 15 minutes
        say("ppo")
        figures |= _bench_ppo_both(quick, scale=3)
        return figures, ppo_rows(figures, "ppo") + ppo_rows(figures, "ppo64")
    say("simulate")
    figures |= bench_simulate(repeats, hours)
    hour = hour_flight(hours)
    say("filters")
    samples = q.bench_filter_samples if quick else FILTER_SAMPLES
    figures |= bench_filter_figures(hour, samples, repeats)
    say("environments")
    from aeromag_env.jobs.bench.envs import bench_env

    figures |= bench_env(repeats)
    say("ppo")
    figures |= _bench_ppo_both(quick)
    say("discover")
    figures |= bench_discover(hour, 1 if quick else 3)
    figures |= _discover_cli(quick)
    if not quick or q.bench_memory:
        say("memory")
        figures |= bench_memory()
    say("stream")
    figures |= bench_stream(QUICK_HOURS if quick else HOURS)
    table_rows = rows(figures) + discover_cli_rows(figures) + stream_rows(figures)
    return figures, table_rows + ray_rows(figures)


def _discover_cli(quick: bool) -> dict[str, Any]:
    """``aeromag discover`` as a user runs it, in fresh processes (1 and 4 flight-hours; quick:
    one run on half an hour)."""
    from aeromag_env.jobs.bench import discover_cli

    if quick:
        return bench_discover_cli(discover_cli.QUICK_HOURS, 1)
    return bench_discover_cli(discover_cli.HOURS, discover_cli.REPEATS)


def _bench_ppo_both(quick: bool, scale: int = 1) -> dict[str, Any]:
    """PPO's figures with 8 environments and (unless ``quick`` skips them) with 64; each repeat
    ``1/scale`` of a full run's steps (the same number of repeats)."""
    from aeromag_env.jobs.bench.envs import bench_ppo
    from agents.training.quick import QUICK as q

    sizes = {k: q.ppo[k] for k in ("n_steps", "batch_size")} if quick else {}
    figures = bench_ppo(
        q.bench_ppo_timesteps if quick else 49152 // scale, 1 if quick else PPO_REPEATS, **sizes
    )
    if not quick or q.bench_ppo64:
        figures |= bench_ppo(
            4096 if quick else -(-163840 // scale // 16384) * 16384,  # whole rollouts
            1 if quick else PPO64_REPEATS,
            n_envs=64,
            prefix="ppo64",
            **sizes,
        )
    return figures


def _report(
    request: BenchRequest, figures: dict[str, Any], table_rows: list[Row], load_before: float | None
) -> BenchResult:
    """Write ``bench.json``; the result with the table."""
    from aeromag_env.jobs.bench.table import table_text
    from agents.training.quick import QUICK

    quick = request.quick
    report = {
        "figures": figures,
        "rows": [
            dict(zip(("benchmark", "median", "ratio", "target", "met"), r, strict=True))
            for r in table_rows
        ],
        "repeats": QUICK.bench_repeats if quick else 7,
        "ppo_repeats": 1 if quick else PPO_REPEATS,
        "ppo64_repeats": (1 if QUICK.bench_ppo64 else 0) if quick else PPO64_REPEATS,
        "statistic": "median",
        "quick": quick,
        "machine": _machine(),
        "load_average_1min": {"before": load_before, "after": _load()},
    }
    path = write_text(request.out / "bench.json", json.dumps(report, indent=2))
    return BenchResult(report, table_rows, table_text(table_rows), path)


def _machine() -> dict[str, Any]:
    """Python, platform, processor, cores and the numeric libraries' versions."""
    import numba
    import numpy

    return {
        "python": platform.python_version(),
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "cpus": cores(),
        "numpy": numpy.__version__,
        "numba": numba.__version__,
    }


def _load() -> float | None:
    """The 1-minute load average (None where the system does not say)."""
    return os.getloadavg()[0] if hasattr(os, "getloadavg") else None
