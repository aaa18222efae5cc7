"""A learned tuner over several training seeds: the README's per-seed table and the IQM.

``python experiments/seed_table.py POLICY.npz [POLICY.npz …] [--scenarios nonstationary]
[--episodes 30] [--out results/seed_table] [--ray [ADDRESS]]`` (the policies of ``aeromag train
--seeds 0-4 --out DIR`` are ``DIR/seed_*/policy.npz``) evaluates each exported policy (one per
training seed) beside ``tuned_constant``, ``privileged`` and ``fis`` on the same test flights of
each scenario (``aeromag evaluate``'s path: :func:`agents.evaluation.episodes.evaluate`), and
prints per seed its mean RMSE and normalized score with their intervals, then the interquartile
mean of the normalized scores over seeds × scenarios with a stratified-bootstrap interval
(:func:`agents.evaluation.statistics.iqm_interval`); scenarios without headroom are left out of
the IQM and named. Writes ``table.md`` and ``results.json`` to ``--out``. ``--quick``: 2 test
flights per scenario.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from scipy import stats

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aeromag_env.atomic import write_text
from aeromag_env.parallel import runner
from aeromag_env.quick import add_quick_option
from agents.evaluation.episodes import evaluate_scenarios
from agents.evaluation.seeds import TEST_SEED_START
from agents.evaluation.statistics import BOOTSTRAP_RESAMPLES, ci95, iqm_interval
from agents.training.quick import QUICK

BASELINES = ("tuned_constant", "privileged", "fis")


HEADER = (
    "| training seed | policy | RMSE [nT] (95 % CI) | normalized score (95 % CI) |\n"
    "|---|---|---|---|"
)


def _interval(value: float | None, ci: list, fmt: str) -> str:
    if value is None:
        return "n/a"
    return f"{value:{fmt}} [{ci[0]:{fmt}}, {ci[1]:{fmt}}]"


def seed_rows(results: dict, names: list[str]) -> list[str]:
    """Markdown rows: one per seed's policy (its file), RMSE and normalized score."""
    rows = []
    for k, name in enumerate(names):
        r = results["policies"][name]
        rmse = _interval(r["rmse_nt_mean"], r["rmse_nt_ci95"], ".3g")
        score = _interval(r.get("normalized_score"), r.get("normalized_score_ci95", []), ".2f")
        rows.append(f"| {k} | `{name[4:]}` | {rmse} | {score} |")
    return rows


def scenario_lines(scenario: str, results: dict, names: list[str]) -> list[str]:
    """The scenario's heading (its anchors), the per-seed rows and the spread over seeds."""
    base = results["policies"]
    anchors = ", ".join(f"{b} {base[b]['rmse_nt_mean']:.3g} nT" for b in BASELINES)
    rmse = np.array([base[n]["rmse_nt_mean"] for n in names])
    spread = (
        (
            f"mean over seeds {rmse.mean():.3g} nT, SD {rmse.std(ddof=1):.2g} nT (min "
            f"{rmse.min():.3g}, max {rmse.max():.3g})"
        )
        if len(names) > 1
        else ""
    )
    heading = f"{scenario}: {len(results['seeds'])} test flights; {anchors}"
    return [heading, "", HEADER, *seed_rows(results, names), "", spread, ""]


def _bootstrap_low(diff: np.ndarray) -> float:
    """The lower end of the 95 % percentile-bootstrap interval of the mean of ``diff`` (scipy,
    as many resamples as the normalized score's; fixed seed); -inf for fewer than 2 flights (as
    the t interval, which is undefined there)."""
    if diff.size < 2:
        return -np.inf
    if np.ptp(diff) == 0:  # every resample has the same mean
        return float(diff[0])
    boot = stats.bootstrap(
        (diff,), np.mean, n_resamples=BOOTSTRAP_RESAMPLES, method="percentile", rng=0
    )
    return float(boot.confidence_interval.low)


def general_lines(everything: dict, names: list[str]) -> list[str]:
    """The general tuner's two bars for a policy over several scenarios, per training seed: its
    mean RMSE over the scenarios against ``fis``'s (at least 20 % lower), and the scenarios
    where it is worse than ``tuned_constant`` beyond the paired 95 % interval (none allowed; a t
    interval on the per-flight differences), and besides those the scenarios where only a
    percentile bootstrap of the same differences says so (heavy-tailed differences: a few bad
    flights)."""
    fis = np.mean([r["policies"]["fis"]["rmse_nt_mean"] for r in everything.values()])
    rows = [
        "| training seed | mean RMSE over scenarios [nT] | lower than fis's mean | worse than "
        "tuned_constant beyond the paired 95 % CI | beyond a bootstrap CI only |",
        "|---|---|---|---|---|",
    ]
    gains = []
    for k, name in enumerate(names):
        mean = np.mean([r["policies"][name]["rmse_nt_mean"] for r in everything.values()])
        gains.append(1.0 - mean / fis)
        worse, boot_only = [], []
        for sc, r in everything.items():
            diff = np.subtract(
                r["policies"][name]["rmse_nt"], r["policies"]["tuned_constant"]["rmse_nt"]
            )
            if ci95(diff)[0] > 0:
                worse.append(f"{sc} (+{diff.mean():.2g} nT)")
            elif _bootstrap_low(diff) > 0:
                boot_only.append(f"{sc} (+{diff.mean():.2g} nT)")
        rows.append(
            f"| {k} | {mean:.3g} | {100 * gains[-1]:.0f} % | {', '.join(worse) or 'none'}"
            f" | {', '.join(boot_only) or 'none'} |"
        )
    over = f"fis's mean over the {len(everything)} scenarios: {fis:.3g} nT"
    if len(gains) > 1:
        over += (
            f"; lower than it by {100 * np.mean(gains):.0f} % on the mean over seeds "
            f"(SD {100 * np.std(gains, ddof=1):.1f} points)"
        )
    return [*rows, "", over]


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("policies", nargs="+", help="exported policies, one per training seed")
    parser.add_argument("--scenarios", default="nonstationary")
    parser.add_argument("--episodes", type=int, default=30, help="test flights per scenario")
    parser.add_argument("--out", default="results/seed_table", help="output folder")
    add_quick_option(parser, "2 test flights per scenario")
    parser.add_argument(
        "--ray",
        nargs="?",
        const="local",
        metavar="ADDRESS",
        help="evaluate on Ray (as aeromag evaluate --ray)",
    )
    args = parser.parse_args(argv)
    names = [f"ppo:{p}" for p in args.policies]
    episodes = QUICK.episodes if args.quick else args.episodes
    seeds = list(range(TEST_SEED_START, TEST_SEED_START + episodes))
    lines, scores, skipped = [], [], []
    with runner(args.ray) as tasks:  # every scenario × policy × flights at once
        everything = evaluate_scenarios(
            args.scenarios.split(","), [*BASELINES, *names], seeds, runner=tasks
        )
    for scenario, results in everything.items():
        lines += scenario_lines(scenario, results, names)
        anchors = results.get("normalized_score")
        if anchors is not None and anchors["note"] is None:
            scores.append([results["policies"][n]["normalized_score"] for n in names])
        else:
            skipped.append(scenario)
    if scores:
        point, (lo, hi) = iqm_interval(np.array(scores).T)
        what = f"{len(names)} seed(s) × {len(scores)} scenario(s)"
        lines.append(
            f"IQM of the normalized score over {what}: {point:.2f} [{lo:.2f}, {hi:.2f}]"
            " (stratified bootstrap)"
        )
    if skipped:
        lines.append(f"no headroom, left out of the IQM: {', '.join(skipped)}")
    if len(everything) > 1:
        lines += ["", *general_lines(everything, names)]
    table = "\n".join(lines) + "\n"
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    write_text(out / "table.md", table)
    write_text(out / "results.json", json.dumps(everything, indent=2, default=str))
    print(table)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
