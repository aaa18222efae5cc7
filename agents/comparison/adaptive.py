"""The adaptive filters' benchmark: the classical and variational adaptive filters, the model bank,
the constants and the tuners on the same fresh test flights of every scenario.

:func:`fly` flies every (scenario, policy) pair on the same seeds, pair by pair (each pair is
:func:`agents.evaluation.episodes.policy_rows`, the path of ``aeromag evaluate``), and keeps
every flight's figures; given the flights of an earlier run (the same seeds) it flies only the
pairs they lack, so a run cut short, or a policy added, costs only what is new. :func:`summarize`
turns the flights into the tables: per scenario and policy the mean RMSE with its t interval,
the mean of the worst 10 % of the flights, the normalized score with its paired bootstrap
interval (:func:`agents.evaluation.statistics.normalized_scores`), the flights on which the
filter diverged, and the paired differences against :data:`REFERENCES` with their t intervals.

``experiments/adaptive_benchmark.py`` is the command line; ``docs/results/adaptive_benchmark.json``
the committed run, from which the results page is generated.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from aeromag_env.environment.scenarios import check_scenario
from aeromag_env.errors import AeromagError
from agents.comparison.statistics import CVAR_FRACTION, cvar, tail_size
from agents.evaluation.episodes import policy_rows
from agents.evaluation.seeds import TEST_SEED_START
from agents.evaluation.statistics import ci95, normalized_scores
from agents.policies import POLICIES

#: The policies of the benchmark, in the order of its tables.
BENCHMARK_POLICIES = (
    "constant",
    "fis",
    "sage_husa",
    "ding",
    "vbakf",
    "vbakf_pr",
    "imm",
    "tuned_constant",
    "tuned_constant_suite",
    "general",
    "privileged",
)
#: The adaptive filters (the filter adapts, the policy holds the scales).
FILTERS = ("sage_husa", "ding", "vbakf", "vbakf_pr", "imm")
#: The policies every other is compared with flight by flight.
REFERENCES = ("constant", "tuned_constant", "general")
#: Each flight's figures kept (:func:`agents.evaluation.episodes.run_episode`'s).
FIGURES = ("rmse_nt", "divergences", "outliers_rejected")

#: Flights: scenario → policy → figure → one value per seed, in seed order.
Flights = dict[str, dict[str, dict[str, list[float]]]]


def fly(
    scenarios: Sequence[str],
    policies: Sequence[str],
    seeds: Sequence[int],
    earlier: Flights | None = None,
    progress: Callable[[str, str, float], None] | None = None,
) -> Flights:
    """Every policy on the same ``seeds`` of every scenario; the pairs ``earlier`` holds (flown
    on the same seeds) are kept, not flown again.

    Parameters
    ----------
    scenarios : names of :data:`~aeromag_env.environment.ids.SCENARIOS`
    policies : names of :data:`agents.policies.POLICIES`
    seeds : test seeds (≥ :data:`~agents.evaluation.seeds.TEST_SEED_START`)
    earlier : the flights of an earlier run on the same seeds, or None
    progress : called after each pair with the scenario, the policy and its seconds

    Returns
    -------
    Flights
        ``earlier``'s pairs and the new ones.
    """
    _check(scenarios, policies, seeds)
    out: Flights = {s: dict((earlier or {}).get(s, {})) for s in scenarios}
    for scenario in scenarios:
        for name in policies:
            if name in out[scenario]:
                continue
            t0 = time.perf_counter()
            rows = policy_rows(scenario, name, seeds, {})
            out[scenario][name] = {k: [float(v) for v in rows[k]] for k in FIGURES}
            if progress is not None:
                progress(scenario, name, time.perf_counter() - t0)
    return out


def _check(scenarios: Sequence[str], policies: Sequence[str], seeds: Sequence[int]) -> None:
    for s in scenarios:
        check_scenario(s)
    unknown = [p for p in policies if p not in POLICIES]
    if unknown:
        raise AeromagError(f"unknown policies {', '.join(unknown)}; valid: {', '.join(POLICIES)}")
    if len(seeds) < 2:
        raise AeromagError("the benchmark needs at least 2 flights per scenario (its intervals)")
    if min(seeds) < TEST_SEED_START:
        raise AeromagError(f"test seeds must be ≥ {TEST_SEED_START}, got {min(seeds)}")


def summarize(flights: Flights) -> dict[str, dict[str, Any]]:
    """The tables of :func:`fly`'s flights: scenario → ``{"policies": {name: row}, "anchors":
    ...}``.

    Each row: ``rmse_nt_mean`` and ``rmse_nt_ci95`` [nT]; ``worst10_rmse_nt`` (the mean of the
    worst :data:`~agents.comparison.statistics.CVAR_FRACTION` of the flights, ``worst_flights``
    of them) [nT]; ``normalized_score`` and ``normalized_score_ci95`` (0 = ``tuned_constant``, 1
    = ``privileged``; None without headroom); ``divergences`` (total) and ``diverged_flights``;
    for each of :data:`REFERENCES` flown, ``diff_vs_<ref>_nt_mean`` and ``diff_vs_<ref>_ci95``
    (paired, this policy minus the reference [nT]) and ``vs_<ref>``: ``better``, ``worse`` (the
    interval below or above 0) or ``same``. ``anchors``: the normalized score's headroom, or None.
    """
    out: dict[str, dict[str, Any]] = {}
    for scenario, per in flights.items():
        arrays = {n: {k: np.asarray(v, dtype=float) for k, v in f.items()} for n, f in per.items()}
        rows = {name: _row(f, arrays) for name, f in arrays.items()}
        score = normalized_scores(arrays) or {}
        anchors = score.pop("anchors", None)
        for name, s in score.items():
            rows[name].update(s)
        out[scenario] = {"policies": rows, "anchors": anchors}
    return out


def _row(f: Mapping[str, np.ndarray], arrays: Mapping[str, Mapping[str, np.ndarray]]) -> dict:
    rmse = f["rmse_nt"]
    row: dict[str, Any] = {
        "rmse_nt_mean": float(rmse.mean()),
        "rmse_nt_ci95": ci95(rmse),
        "worst10_rmse_nt": float(cvar(rmse, CVAR_FRACTION)),
        "worst_flights": tail_size(rmse.size, CVAR_FRACTION),
        "divergences": int(f["divergences"].sum()),
        "diverged_flights": int(np.count_nonzero(f["divergences"])),
        "normalized_score": None,
        "normalized_score_ci95": [None, None],
    }
    for ref in REFERENCES:
        if ref in arrays:
            diff = rmse - arrays[ref]["rmse_nt"]
            lo, hi = ci95(diff)
            row[f"diff_vs_{ref}_nt_mean"] = float(diff.mean())
            row[f"diff_vs_{ref}_ci95"] = [lo, hi]
            row[f"vs_{ref}"] = "better" if hi < 0 else "worse" if lo > 0 else "same"
    return row


def best_filter(summary: Mapping[str, Any]) -> str | None:
    """The adaptive filter (:data:`FILTERS`) with the lowest mean RMSE in one scenario's
    summary, or None when none was flown."""
    rows = summary["policies"]
    flown = [f for f in FILTERS if f in rows]
    return min(flown, key=lambda f: rows[f]["rmse_nt_mean"]) if flown else None
