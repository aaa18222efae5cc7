"""How far can a scenario-blind tuner that picks among constants get? Bounds for the general tuner.

``python experiments/general_tuner_bounds.py [--flights 8] [--out PATH] [--quick]`` flies
validation flights (seeds from 50 000; never test flights) of every scenario of the suite with:

* ``tuned_constant`` (the scenario's own constant, which reads the scenario's name) and
  ``privileged`` (knows the noise and the steps): the normalized score's anchors 0 and 1;
* every scenario's tuned constant on every other scenario (``TargetScalePolicy`` at that row of
  ``agents/policies/tuned_constants.json``): the cross matrix. Its best row is the best
  scenario-blind constant among the table's; the per-flight minimum over the rows is what a
  fallback or a multiple-model switch among these constants could reach with hindsight;
* the filters that adapt by the innovations' likelihood or statistics without a label: ``imm``
  (its default bank) and ``vbakf``, through the environment's ``filter_method``.

It writes ``--out`` (default ``results/general_tuner_bounds.json``): every flight's RMSE [nT]
per scenario and policy, the scores on the mean RMSE and their interquartile mean over the
scenarios with headroom. About 6 minutes with 8 flights per scenario on a 2-core machine.
``--quick``: 2 flights of 2 scenarios.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import aeromag_env  # noqa: F401  (registers the environment ids)
from aeromag_env.atomic import write_text
from aeromag_env.environment.scenarios import SCENARIOS
from aeromag_env.quick import add_quick_option
from agents.evaluation.episodes import run_episode
from agents.evaluation.seeds import VALIDATION_SEEDS
from agents.policies import make_policy, policy_env_kwargs
from agents.policies.baselines import ClassicalPolicy, TargetScalePolicy
from agents.policies.tuned_table import load_tuned
from agents.training.quick import QUICK

#: The label-free adaptive filters flown beside the constants (environment ``filter_method``).
ADAPTIVE = ("imm", "vbakf")


def _rmse(env: Any, policy: Any, seeds: Sequence[int]) -> list[float]:
    return [run_episode(env, policy, s)["rmse_nt"] for s in seeds]


def fly(scenario: str, seeds: Sequence[int], table: dict[str, Any]) -> dict[str, list[float]]:
    """Every flight's RMSE [nT] of ``scenario`` per policy: the anchors, each row of the tuned
    table as a constant (``constant:ROW``), the label-free adaptive filters."""
    env = gym.make("AeroMagCompensation-v0", scenario=scenario)
    privileged_env = gym.make(
        "AeroMagCompensation-v0", scenario=scenario, **policy_env_kwargs("privileged")
    )
    out = {
        "tuned_constant": _rmse(env, make_policy("tuned_constant", env), seeds),
        "privileged": _rmse(privileged_env, make_policy("privileged", privileged_env), seeds),
    }
    for row, entry in table.items():
        policy = TargetScalePolicy(
            env, math.log(10.0) * entry["log10_q"], math.log(10.0) * entry["log10_r"]
        )
        out[f"constant:{row}"] = _rmse(env, policy, seeds)
    for method in ADAPTIVE:
        out[method] = _rmse(env, ClassicalPolicy(method, env), seeds)
    return out


def _iqm(x: Sequence[float]) -> float | None:
    """Interquartile mean (the middle 50 %, by scipy's trimmed mean); None of nothing."""
    from scipy import stats

    return float(stats.trim_mean(np.asarray(x, float), 0.25)) if len(x) else None


def summarise(flights: dict[str, dict[str, list[float]]]) -> dict[str, Any]:
    """Per scenario the mean RMSE of each policy and its normalized score (None without
    headroom: ``privileged`` not below ``tuned_constant`` beyond the paired 95 % t interval),
    the hindsight minimum over the table's constants per flight, the best scenario-blind row
    (lowest geometric mean of its RMSE over ``tuned_constant``'s), and each policy's IQM of
    the scores over the scenarios with headroom."""
    from agents.evaluation.statistics import ci95

    rows = [k for k in next(iter(flights.values())) if k.startswith("constant:")]
    ratio = {
        r: math.exp(
            float(
                np.mean(
                    [
                        math.log(np.mean(f[r]) / np.mean(f["tuned_constant"]))
                        for f in flights.values()
                    ]
                )
            )
        )
        for r in rows
    }
    blind = min(ratio, key=ratio.__getitem__)
    per: dict[str, Any] = {}
    for scenario, f in flights.items():
        arrays = {k: np.asarray(v) for k, v in f.items()}
        arrays["hindsight_best_constant"] = np.min([arrays[r] for r in rows], axis=0)
        arrays["best_blind_constant"] = arrays[blind]
        zero, one = arrays["tuned_constant"], arrays["privileged"]
        has_headroom = ci95(zero - one)[0] > 0
        per[scenario] = {
            "headroom_nt": float(zero.mean() - one.mean()),
            "has_headroom": bool(has_headroom),
            "mean_rmse_nt": {k: float(v.mean()) for k, v in arrays.items()},
            "score": {
                k: float((zero.mean() - v.mean()) / (zero.mean() - one.mean()))
                if has_headroom
                else None
                for k, v in arrays.items()
            },
        }
    names = list(next(iter(per.values()))["score"])
    iqm = {k: _iqm([p["score"][k] for p in per.values() if p["has_headroom"]]) for k in names}
    return {"best_blind_row": blind, "blind_ratio_to_tuned": ratio, "scenarios": per, "iqm": iqm}


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--flights", type=int, default=8, help="validation flights per scenario")
    parser.add_argument(
        "--out", type=Path, default=Path("results/general_tuner_bounds.json"), help="results"
    )
    add_quick_option(parser, "2 flights of 2 scenarios")
    args = parser.parse_args(argv)
    if args.flights < 2:
        parser.error("--flights must be at least 2")
    scenarios, n = list(SCENARIOS), args.flights
    if args.quick:
        scenarios, n = scenarios[:2], QUICK.seeds
    seeds = range(VALIDATION_SEEDS.start, VALIDATION_SEEDS.start + n)
    table, t0, flights = load_tuned(), time.perf_counter(), {}
    for scenario in scenarios:
        flights[scenario] = fly(scenario, seeds, table)
        print(f"{scenario}: {time.perf_counter() - t0:.0f} s", flush=True)
    result = {
        "command": "python experiments/general_tuner_bounds.py " + " ".join(argv or sys.argv[1:]),
        "date": time.strftime("%Y-%m-%d"),
        "seeds": list(seeds),
        "seconds": round(time.perf_counter() - t0),
        "flights": flights,
        "summary": summarise(flights),
    }
    write_text(args.out, json.dumps(result, indent=1) + "\n")
    s = result["summary"]
    print(f"best scenario-blind constant: {s['best_blind_row']}, IQM of scores: {s['iqm']}")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
