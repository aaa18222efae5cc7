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
  (:mod:`aeromag_env.cli.bench_filters`): compiled, batched (64 flights), plain numpy, filterpy.
* environments and PPO training (:mod:`aeromag_env.cli.bench_envs`), with the two targets of
  the environments inside PPO: at 8 environments their cost per environment step at most
  1.5× the bare compiled filter's over the same K samples (``ppo_env_to_filter_ratio``), at
  64 their share of PPO's time at most 20 % (``ppo64_env_share``).
* ``discover_s_per_flight_hour`` — :func:`aeromag_env.discovery.workflow.discover` on the same
1-hour
  flight, against its duration (null when the module is not there).
* ``compensate_10h_peak_mb`` — peak resident memory of a fresh process running ``aeromag
  compensate FILE --method kf`` on a 10-hour 10 Hz flight (:func:`peak_rss_mb`: interpreter,
  libraries, reading, filtering, writing and the figure; target < 1 GB), against
  ``compensate_baseline_mb``, the same process after its imports, before the work.
"""

from __future__ import annotations

import json
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from aeromag_env.atomic import check_output_set, write_text
from aeromag_env.cli.bench_ray import Row, bench_ray, ray_rows
from aeromag_env.flight.data import Flight
from aeromag_env.simulation.config import preset, with_overrides
from aeromag_env.threads import cores

#: Samples of the 1-hour flight the filter figures run on (quick: 1 000).
FILTER_SAMPLES = 6000
#: Repeats of the PPO figures with 8 and 64 environments (quick: 1): each has a target, a
#: median over at least 5.
PPO_REPEATS, PPO64_REPEATS = 5, 5
#: The most of PPO's wall time the environments may take, by number of environments
#: (``{prefix}_env_share``; with 8, PPO's own work leaves them too little for any target).
ENV_SHARE_TARGETS = {64: 0.20}
#: The most the environments may cost PPO per environment step, in units of the bare compiled
#: filter's cost of the same K samples, by number of environments
#: (``{prefix}_env_to_filter_ratio``).
ENV_TO_FILTER_TARGETS = {8: 1.5}


def _median_seconds(fn: Callable[[], object], repeats: int) -> float:
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

    grid = _median_seconds(cold(cfg), repeats)
    ref = _median_seconds(cold(every_sample), repeats)
    simulate_flight(cfg, 0)
    warm = _median_seconds(lambda: simulate_flight(cfg, 1), repeats)
    return {
        "simulate_s_per_flight_hour": grid / hours,
        "simulate_direct_igrf_s_per_flight_hour": ref / hours,
        "simulate_warm_s_per_flight_hour": warm / hours,
    }


def bench_filter_figures(flight: Flight, samples: int, repeats: int) -> dict[str, float | None]:
    from aeromag_env.cli.bench_filters import bench_filters
    from aeromag_env.compensation.compensate import earth_model

    t_b, tdot_b = earth_model(flight)
    y = flight.vector("flux_a") - t_b
    return bench_filters(y[:samples], t_b[:samples], tdot_b[:samples], repeats)


def bench_discover(flight: Flight, repeats: int) -> dict[str, float | None]:
    """Seconds of the discrepancy workflow per flight-hour (null without the module)."""
    try:
        from aeromag_env.discovery.workflow import discover
    except ImportError:
        return {"discover_s_per_flight_hour": None}
    hours = (float(flight.tt[-1]) - float(flight.tt[0])) / 3600.0
    seconds = _median_seconds(lambda: discover(flight, flux="flux_a"), repeats)
    return {"discover_s_per_flight_hour": seconds / hours if hours > 0 else None}


_MEMORY_PROBE = """
import sys
from aeromag_env.cli.bench import peak_rss_mb
from aeromag_env.cli.main import main
base = peak_rss_mb()
status = main(["compensate", sys.argv[1], "--method", "kf", "--out", sys.argv[2]])
print(status, base, peak_rss_mb())
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


def run_benchmarks(
    out: Path, quick: bool = False, ray: str | None = None, only: str | None = None
) -> dict[str, Any]:
    """Run every benchmark, print a table with ratios, write ``out/bench.json``. ``ray`` is
    ``--ray`` (None: the Ray figures are not measured and Ray is not imported); ``only``
    ``"ray"``, ``"discover"`` or ``"ppo"`` (PPO at 8 and 64 environments: the speed targets'
    figures) measures those figures alone. ``quick``: the sizes of
    :data:`agents.quick.QUICK` (about a minute; the figures are then only indicative)."""
    check_output_set(out, ("bench.json",))  # before minutes of work
    from aeromag_env.cli.bench_envs import bench_env
    from agents.quick import QUICK

    q = QUICK
    repeats = q.bench_repeats if quick else 7
    hours = q.bench_flight_hours if quick else 1.0
    load_before = _load()
    figures: dict[str, Any] = {} if ray is None else bench_ray(ray, quick)
    if only == "ray":
        return _report(out, figures, ray_rows(figures), quick, repeats, load_before)
    if only == "discover":
        figures |= bench_discover(hour_flight(hours), 1 if quick else 3)
        return _report(out, figures, [_discover_row(figures)], quick, repeats, load_before)
    if only == "ppo":  # a third of the full run's steps per repeat: three runs in a quarter hour
        figures |= _bench_ppo_both(quick, scale=3)
        rows = _ppo_rows(figures, "ppo") + _ppo_rows(figures, "ppo64")
        return _report(out, figures, rows, quick, repeats, load_before)
    figures |= bench_simulate(repeats, hours)
    hour = hour_flight(hours)
    figures |= bench_filter_figures(
        hour, q.bench_filter_samples if quick else FILTER_SAMPLES, repeats
    )
    figures |= bench_env(repeats)
    figures |= _bench_ppo_both(quick)
    figures |= bench_discover(hour, 1 if quick else 3)
    if not quick or q.bench_memory:
        figures |= bench_memory()
    return _report(out, figures, _rows(figures) + ray_rows(figures), quick, repeats, load_before)


def _bench_ppo_both(quick: bool, scale: int = 1) -> dict[str, Any]:
    """PPO's figures with 8 environments and (unless ``quick`` skips them) with 64; each repeat
    ``1/scale`` of a full run's steps (the same number of repeats)."""
    from aeromag_env.cli.bench_envs import bench_ppo
    from agents.quick import QUICK as q

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
    out: Path,
    figures: dict[str, Any],
    rows: list[Row],
    quick: bool,
    repeats: int,
    load_before: float | None,
) -> dict[str, Any]:
    """Print the table, write ``bench.json``; return its content."""
    from agents.quick import QUICK

    _print_table(rows)
    result = {
        "figures": figures,
        "rows": [
            dict(zip(("benchmark", "median", "ratio", "target", "met"), r, strict=True))
            for r in rows
        ],
        "repeats": repeats,
        "ppo_repeats": 1 if quick else PPO_REPEATS,
        "ppo64_repeats": (1 if QUICK.bench_ppo64 else 0) if quick else PPO64_REPEATS,
        "statistic": "median",
        "quick": quick,
        "machine": _machine(),
        "load_average_1min": {"before": load_before, "after": _load()},
    }
    path = write_text(out / "bench.json", json.dumps(result, indent=2))
    print(f"wrote {path}")
    return result


def _rows(f: dict[str, Any]) -> list[Row]:
    """(benchmark, median, ratio to its reference in this run, target, target met)."""
    sim, fp, comp = (
        f["simulate_s_per_flight_hour"],
        f["filterpy_samples_per_s"],
        f["filter_compiled_samples_per_s"],
    )
    batched, numpy_ref = f["filter_batched_samples_per_s"], f["filter_numpy_samples_per_s"]
    warm = f.get("simulate_warm_s_per_flight_hour")  # not in bench.json before 2026-11
    env1, envn = f["env_single_steps_per_s"], f["env_batched_steps_per_s"]
    peak, base = f.get("compensate_10h_peak_mb"), f.get("compensate_baseline_mb")
    return [
        (
            "simulate 1 flight-hour (grid IGRF)",
            f"{sim:.3f} s",
            f"{f['simulate_direct_igrf_s_per_flight_hour'] / sim:.0f}× faster than IGRF at every "
            "sample",
            "< 1 s",
            sim < 1.0,
        ),
        (
            "simulate it again (pattern remembered)",
            _num(warm, "s", ".3f"),
            "n/a" if warm is None else f"{sim / warm:.1f}× faster than the first time",
            "",
            None,
        ),
        (
            "filter, compiled, 1 flight",
            f"{comp:,.0f} samples/s",
            _ratio(comp, fp, "filterpy", ".1f"),
            "≥ 30× filterpy",
            None if fp is None else comp >= 30 * fp,
        ),
        (
            "filter, batched, 64 flights",
            f"{batched:,.0f} samples/s",
            f"{batched / comp:.1f}× compiled 1 flight",
            "≥ 1 000 000 samples/s",
            batched >= 1e6,
        ),
        (
            "filter, plain numpy reference",
            f"{numpy_ref:,.0f} samples/s",
            _ratio(numpy_ref, fp, "filterpy", ".2f"),
            "",
            None,
        ),
        ("filterpy KalmanFilter (reference)", _num(fp, "samples/s"), "1×", "", None),
        (
            "env steps, 1 env, K = 10",
            f"{env1:,.0f} /s",
            f"{env1 / f['env_numpy_reference_steps_per_s']:.0f}× an env on the numpy filter",
            "≥ 20 000 /s",
            env1 >= 20_000,
        ),
        (
            "env steps, 64 envs batched, K = 10",
            f"{envn:,.0f} /s",
            f"{envn / env1:.1f}× 1 env",
            "≥ 100 000 /s",
            envn >= 100_000,
        ),
        (
            "env reset (simulate a nominal flight)",
            f"{1000 * f['env_reset_s']:.0f} ms",
            f"= {f['env_reset_s'] * env1:.0f} steps of 1 env",
            "",
            None,
        ),
        *_ppo_rows(f, "ppo"),
        *_ppo_rows(f, "ppo64"),
        _discover_row(f),
        (
            "compensate 10-hour flight, peak RSS",
            _num(peak, "MB"),
            "n/a (not measured: --quick)"
            if peak is None or base is None
            else f"{peak / base:.1f}× the process after imports ({base:.0f} MB)",
            "< 1024 MB",
            None if peak is None else peak < 1024,
        ),
    ]


def _discover_row(f: dict[str, Any]) -> Row:
    """The discrepancy workflow per flight-hour, against real time, with issue 22's target."""
    disc = f["discover_s_per_flight_hour"]
    return (
        "discover 1 flight-hour",
        _num(disc, "s", ".2f"),
        "n/a" if disc is None else f"{3600 / disc:.0f}× real time",
        "≤ 5 s",
        None if disc is None else disc <= 5.0,
    )


def _ppo_rows(f: dict[str, Any], prefix: str) -> list[Row]:
    """Batched + prefetch (with the 1.5× target and the range of its ratio over the repeats),
    batched alone, DummyVecEnv, and the zero-cost environment (PPO alone: the ceiling) when
    measured (from 2026-11-23 on); then the environment's share of the time (with its target
    at 64 environments, :data:`ENV_SHARE_TARGETS`) and the environments' cost per step against
    the bare filter's (with its target at 8, :data:`ENV_TO_FILTER_TARGETS`) when measured; none
    when the figures were not measured (``--quick`` skips the 64 environments)."""
    if f"{prefix}_n_envs" not in f:
        return []
    n, dummy = f[f"{prefix}_n_envs"], f[f"{prefix}_dummyvec_steps_per_s"]
    rows: list[Row] = []
    for variant, label in (
        ("batched", "batched + prefetch"),
        ("batched_no_prefetch", "batched"),
        ("dummyvec", "DummyVecEnv"),
        ("free", "zero-cost env"),
    ):
        rate = f.get(f"{prefix}_{variant}_steps_per_s")
        if rate is None:
            continue
        first, share = variant == "batched", f[f"{prefix}_{variant}_env_time_share"]
        note = f"env: {share:.0%} of the time"
        if first and f"{prefix}_batched_ratio_min" in f:
            low, high = f[f"{prefix}_batched_ratio_min"], f[f"{prefix}_batched_ratio_max"]
            note = f"repeats {low:.2f}–{high:.2f}; {note}"
        if variant == "free":
            note = "PPO alone: the most any env allows"
        rows.append(
            (
                f"PPO learn, {label}, {n} envs",
                f"{rate:,.0f} steps/s",
                f"{rate / dummy:.2f}× DummyVecEnv ({note})",
                "≥ 1.5× DummyVecEnv" if first else "",
                rate >= 1.5 * dummy if first else None,
            )
        )
    if f"{prefix}_free_env_us_per_step" in f:  # from 2026-11-27 on
        rows.append(_extra_time_row(f, prefix, n))
    share, target = f.get(f"{prefix}_env_share"), ENV_SHARE_TARGETS.get(n)
    if share is not None:
        low, high = f[f"{prefix}_env_share_min"], f[f"{prefix}_env_share_max"]
        rows.append(
            (
                f"PPO learn, the env's share, {n} envs",
                f"{share:.1%}",
                f"1 − batched/zero-cost, paired repeats {100 * low:.1f}–{100 * high:.1f}%",
                "" if target is None else f"≤ {target:.0%}",
                None if target is None else share <= target,
            )
        )
    if f"{prefix}_env_to_filter_ratio" in f:  # not in older bench.json files
        rows.append(_filter_row(f, prefix, n))
    if f"{prefix}_env_to_filter_in_ppo_ratio" in f:  # from 2026-11-28 on
        rows.append(_filter_in_ppo_row(f, prefix, n))
    return rows


def _filter_in_ppo_row(f: dict[str, Any], prefix: str, n: int) -> Row:
    """The environments' cost per step against the same bare filter stepped inside PPO (a
    diagnostic: no target; what the environments cost beyond it is their own work)."""
    ratio = f[f"{prefix}_env_to_filter_in_ppo_ratio"]
    low = f[f"{prefix}_env_to_filter_in_ppo_ratio_min"]
    high = f[f"{prefix}_env_to_filter_in_ppo_ratio_max"]
    return (
        f"PPO learn, the envs per step vs the filter inside PPO, {n} envs",
        f"{f[f'{prefix}_env_us_per_step']:.1f} µs per env step",
        f"{ratio:.2f}× the filter's {f[f'{prefix}_filter_in_ppo_us_per_step']:.1f} µs stepped "
        f"inside PPO as the envs are (repeats {low:.2f}–{high:.2f})",
        "",
        None,
    )


def _filter_row(f: dict[str, Any], prefix: str, n: int) -> Row:
    """The environments' ``step_wait`` per environment step inside PPO against the bare
    compiled filter's cost of the same K samples, with the target where there is one."""
    env, ratio = f[f"{prefix}_env_us_per_step"], f[f"{prefix}_env_to_filter_ratio"]
    low, high = f[f"{prefix}_env_to_filter_ratio_min"], f[f"{prefix}_env_to_filter_ratio_max"]
    target = ENV_TO_FILTER_TARGETS.get(n)
    return (
        f"PPO learn, the envs per step vs the bare filter, {n} envs",
        f"{env:.1f} µs per env step",
        f"{ratio:.2f}× the filter's {f[f'{prefix}_filter_us_per_step']:.1f} µs for K = "
        f"{f[f'{prefix}_decision_window']} samples (repeats {low:.2f}–{high:.2f})",
        "" if target is None else f"≤ {target}× the filter",
        None if target is None else ratio <= target,
    )


def _extra_time_row(f: dict[str, Any], prefix: str, n: int) -> Row:
    """Where the batched + prefetch run's time beyond the zero-cost run's goes, in µs per
    environment step (medians over the repeats, part by part): the environments' ``step_wait``,
    and what the policy's forward pass, the updates and the rest took beyond theirs there
    (separated by semicolons: a comma after a number would read as a thousands separator when
    ``experiments/bench_table.py`` joins runs)."""
    us = f"{prefix}_{{}}_{{}}_us_per_step".format
    extra = {
        part: f[us("batched", part)] - f[us("free", part)]
        for part in ("env", "forward", "update", "rest")
    }
    total = 1e6 / f[f"{prefix}_batched_steps_per_s"] - 1e6 / f[f"{prefix}_free_steps_per_s"]
    return (
        f"PPO learn, batched + prefetch beyond zero-cost, {n} envs",
        f"{total:.0f} µs per env step",
        f"environments {extra['env']:.0f}; policy forward {extra['forward']:.0f}; updates "
        f"{extra['update']:.0f}; rest {extra['rest']:.0f} µs more",
        "",
        None,
    )


def _ratio(value: float, reference: float | None, name: str, fmt: str = ".0f") -> str:
    return "n/a" if reference is None else f"{value / reference:{fmt}}× {name}"


def _num(value: float | None, unit: str, fmt: str = ",.0f") -> str:
    return "n/a" if value is None else f"{value:{fmt}} {unit}"


def _print_table(rows: list[Row]) -> None:
    print(f"{'benchmark':<40} {'median':>20}  {'ratio (same run)':<52} target")
    for name, value, ratio, target, met in rows:
        mark = "" if met is None else (" (met)" if met else " (NOT met)")
        print(f"{name:<40} {value:>20}  {ratio:<52} {target}{mark}")


def _machine() -> dict[str, Any]:
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
    import os

    return os.getloadavg()[0] if hasattr(os, "getloadavg") else None
