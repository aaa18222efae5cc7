"""``aeromag bench --ray [ADDRESS]``: ``evaluate`` of :data:`FLIGHTS` flights on Ray against
the same evaluation in this process, and the cost of a Ray task.

Figures (``bench.json`` → ``figures``), measured side by side in one run:

* ``ray_evaluate_speedup`` — the serial evaluation's seconds over the Ray evaluation's, median of
  paired repeats (serial, then Ray, in turn); Ray already started and its workers warm, as on a
  cluster in use (target ≥ 1.7× on 2 cores). ``ray_evaluate_cold_s`` is the first Ray run with
  Ray's start and the workers' imports, against ``ray_evaluate_serial_s``.
* ``ray_task_overhead_ms`` — wall time per no-op task when :data:`NOOP_TASKS` are submitted
  together (what a task costs at full load), and ``ray_task_round_trip_ms``, one task alone.
* ``ray_results_identical`` — the Ray evaluation's results equal the serial one's.
"""

from __future__ import annotations

import json
import statistics
import time
from typing import Any

from aeromag_env.jobs.bench.table import Row
from aeromag_env.parallel import SerialRunner, Task, runner

#: The evaluation timed: ``aeromag evaluate``'s default policies on this many test flights.
FLIGHTS, SCENARIO = 64, "nonstationary"
POLICIES = ("constant", "fis", "sage_husa", "ding", "tuned_constant", "oracle")
NOOP_TASKS = 200
#: The speed-up asked of Ray on these 2-core machines.
SPEEDUP_TARGET = 1.7


def noop() -> None:
    """A task that does nothing (the Ray overhead figures)."""


def bench_ray(address: str, quick: bool = False) -> dict[str, Any]:
    """The figures above; ``address`` as ``--ray`` (``local``: a Ray started here with this
    machine's cores)."""
    from agents.evaluation.episodes import evaluate_scenarios
    from agents.evaluation.seeds import TEST_SEED_START
    from agents.training.quick import QUICK

    flights, repeats = (QUICK.bench_ray_flights, 1) if quick else (FLIGHTS, 3)
    seeds = list(range(TEST_SEED_START, TEST_SEED_START + flights))

    def timed(runner: Any) -> tuple[float, str]:
        t0 = time.perf_counter()
        results = evaluate_scenarios([SCENARIO], POLICIES, seeds, runner=runner)
        return time.perf_counter() - t0, json.dumps(results, sort_keys=True)

    serial_s, want = timed(SerialRunner())  # also warms this process (imports, numba cache)
    t0 = time.perf_counter()
    with runner(address) as ray:
        _, got = timed(ray)
        cold = time.perf_counter() - t0
        pairs = [(timed(SerialRunner())[0], timed(ray)[0]) for _ in range(repeats)]
        ratios = [s / r for s, r in pairs]
        t1 = time.perf_counter()
        ray.run([Task("noop", noop) for _ in range(NOOP_TASKS)])
        per_task = (time.perf_counter() - t1) / NOOP_TASKS
        trips = []
        for _ in range(20):
            t2 = time.perf_counter()
            ray.run([Task("noop", noop)])
            trips.append(time.perf_counter() - t2)
        cpus = ray.cpus
    return {
        "ray_evaluate_flights": flights,
        "ray_evaluate_episodes": flights * len(POLICIES),
        "ray_cpus": cpus,
        "ray_evaluate_serial_s": statistics.median([s for s, _ in pairs]),
        "ray_evaluate_ray_s": statistics.median([r for _, r in pairs]),
        "ray_evaluate_speedup": statistics.median(ratios),
        "ray_evaluate_speedup_min": min(ratios),
        "ray_evaluate_speedup_max": max(ratios),
        "ray_evaluate_cold_s": cold,
        "ray_evaluate_first_serial_s": serial_s,
        "ray_task_overhead_ms": 1000 * per_task,
        "ray_task_round_trip_ms": 1000 * statistics.median(trips),
        "ray_results_identical": got == want,
    }


def ray_rows(f: dict[str, Any]) -> list[Row]:
    """The table's rows for the figures above (none when they were not measured)."""
    if "ray_evaluate_speedup" not in f:
        return [("evaluate on Ray", "not measured", "run aeromag bench --ray", "≥ 1.7×", None)]
    speedup, n = f["ray_evaluate_speedup"], f["ray_evaluate_flights"]
    low, high = f["ray_evaluate_speedup_min"], f["ray_evaluate_speedup_max"]
    same = "identical results" if f["ray_results_identical"] else "RESULTS DIFFER"
    return [
        (
            f"evaluate {n} flights × {len(POLICIES)} policies, Ray, {f['ray_cpus']} CPUs",
            f"{f['ray_evaluate_ray_s']:.1f} s",
            f"{speedup:.2f}× serial {f['ray_evaluate_serial_s']:.1f} s (repeats {low:.2f}–"
            f"{high:.2f}; {same})",
            f"≥ {SPEEDUP_TARGET}× serial",
            speedup >= SPEEDUP_TARGET,
        ),
        (
            "  the same, first run (Ray start, imports)",
            f"{f['ray_evaluate_cold_s']:.1f} s",
            f"{f['ray_evaluate_first_serial_s'] / f['ray_evaluate_cold_s']:.2f}× serial",
            "",
            None,
        ),
        (
            "Ray task overhead",
            f"{f['ray_task_overhead_ms']:.2f} ms",
            f"per no-op task, {NOOP_TASKS} at once; one alone {f['ray_task_round_trip_ms']:.1f} ms",
            "",
            None,
        ),
    ]
