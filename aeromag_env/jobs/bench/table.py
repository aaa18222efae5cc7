"""The table of ``aeromag bench``: one row per figure — the benchmark, its median, its ratio to
the reference measured in the same run, the target and whether it was met — and its text."""

from __future__ import annotations

from typing import Any

#: A row of the table: benchmark, median, ratio, target, target met (None: no target).
Row = tuple[str, str, str, str, bool | None]

#: The most of PPO's wall time the environments may take, by number of environments
#: (``{prefix}_env_share``; with 8, PPO's own work leaves them too little for any target).
ENV_SHARE_TARGETS = {64: 0.20}
#: The most the environments may cost PPO per environment step, in units of the bare compiled
#: filter's cost of the same K samples, by number of environments
#: (``{prefix}_env_to_filter_ratio``).
ENV_TO_FILTER_TARGETS = {8: 1.5}


def rows(f: dict[str, Any]) -> list[Row]:
    """(benchmark, median, ratio to its reference in this run, target, target met)."""
    peak, base = f.get("compensate_10h_peak_mb"), f.get("compensate_baseline_mb")
    return [
        *_simulate_and_filter_rows(f),
        *_env_rows(f),
        *ppo_rows(f, "ppo"),
        *ppo_rows(f, "ppo64"),
        discover_row(f),
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


def _simulate_and_filter_rows(f: dict[str, Any]) -> list[Row]:
    """The simulator's and the filters' rows of :func:`rows`."""
    sim, fp, comp = (
        f["simulate_s_per_flight_hour"],
        f["filterpy_samples_per_s"],
        f["filter_compiled_samples_per_s"],
    )
    batched, numpy_ref = f["filter_batched_samples_per_s"], f["filter_numpy_samples_per_s"]
    warm = f.get("simulate_warm_s_per_flight_hour")  # older bench.json files lack it
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
    ]


def _env_rows(f: dict[str, Any]) -> list[Row]:
    """The environments' rows of :func:`rows` (stepping and resetting, PPO aside)."""
    env1, envn = f["env_single_steps_per_s"], f["env_batched_steps_per_s"]
    return [
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
    ]


def discover_row(f: dict[str, Any]) -> Row:
    """The discrepancy workflow per flight-hour, against real time, with its target (5 s)."""
    disc = f["discover_s_per_flight_hour"]
    return (
        "discover 1 flight-hour",
        _num(disc, "s", ".2f"),
        "n/a" if disc is None else f"{3600 / disc:.0f}× real time",
        "≤ 5 s",
        None if disc is None else disc <= 5.0,
    )


def ppo_rows(f: dict[str, Any], prefix: str) -> list[Row]:
    """Batched + prefetch (with the 1.5× target and the range of its ratio over the repeats),
    batched alone, DummyVecEnv, and the zero-cost environment (PPO alone: the ceiling) when
    measured (older bench.json files lack it); then the environment's share of the time (with
    its target at 64 environments, :data:`ENV_SHARE_TARGETS`) and the environments' cost per
    step against the bare filter's (with its target at 8, :data:`ENV_TO_FILTER_TARGETS`) when
    measured; none when the figures were not measured (``--quick`` skips the 64 environments)."""
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
    if f"{prefix}_free_env_us_per_step" in f:  # older bench.json files lack these figures
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
    if f"{prefix}_env_to_filter_in_ppo_ratio" in f:  # older bench.json files lack it
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


def table_text(rows: list[Row]) -> str:
    """The table as the command line prints it."""
    lines = [f"{'benchmark':<40} {'median':>20}  {'ratio (same run)':<52} target"]
    for name, value, ratio, target, met in rows:
        mark = "" if met is None else (" (met)" if met else " (NOT met)")
        lines.append(f"{name:<40} {value:>20}  {ratio:<52} {target}{mark}")
    return "\n".join(lines)
