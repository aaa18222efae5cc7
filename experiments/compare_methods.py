"""Every compensation method on the same simulated flights: the README's method table.

``python experiments/compare_methods.py [--quick] [--out results/methods]`` simulates
``nominal`` calibration flights (30 min each: repeated boxes), compensates each with every method
of ``aeromag compensate`` (package defaults) and writes ``table.md`` and ``results.json`` with
the mean and 95 % interval over seeds of each metric.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aeromag_env.atomic import write_text
from aeromag_env.compensation.compensate import (
    FILTER_METHODS,
    METHODS,
    compensate_scalar,
    compensate_vector,
    score,
)
from aeromag_env.compensation.model import FilterConfig
from aeromag_env.compensation.tolles_lawson import TollesLawson
from aeromag_env.quick import add_quick_option
from aeromag_env.simulation.config import preset, with_overrides
from aeromag_env.simulation.simulate import simulate_flight
from agents.training.quick import QUICK

METRICS = ("compensation_rmse_nt", "improvement_ratio", "fom_nt", "residual_std_nt", "divergences")


def run(seeds: Sequence[int], duration_s: float) -> dict[str, dict[str, list[float]]]:
    """Metric values per method and seed."""
    cfg = with_overrides(preset("nominal"), {"trajectory.duration_s": duration_s})
    values: dict[str, dict[str, list[float]]] = {m: {k: [] for k in METRICS} for m in METHODS}
    for seed in seeds:
        flight = simulate_flight(cfg, seed)
        for method in METHODS:
            if method == "tl":
                comp = compensate_scalar(flight, "flux_a", "mag_1_uc", TollesLawson())
            else:
                fcfg = FilterConfig(method=method) if method in FILTER_METHODS else None
                comp = compensate_vector(flight, method, "flux_a", fcfg)
            metrics = score(flight, comp)
            for key in METRICS:
                values[method][key].append(float(metrics[key]))
    return values


def table(values: dict[str, dict[str, list[float]]], n: int, duration_s: float) -> str:
    """Markdown table: mean [95 % t-interval] over seeds."""
    head = (
        "| method | RMSE vs truth, 2nd half [nT] | IR (2nd half) | FOM, last box [nT] "
        "| residual std [nT] | divergences |\n|---|---|---|---|---|---|\n"
    )
    rows = []
    for method, vals in values.items():
        cells = [_mean_ci(vals[k]) for k in METRICS[:4]] + [str(int(sum(vals["divergences"])))]
        rows.append(f"| `{method}` | " + " | ".join(cells) + " |")
    note = (
        f"\n{n} `nominal` calibration flights of {duration_s:.0f} s (seeds 0–{n - 1}); `tl` is "
        "scored on the scalar stinger, every other method on the fluxgate.\n"
    )
    return head + "\n".join(rows) + "\n" + note


def _mean_ci(v: list[float]) -> str:
    a = np.asarray(v)
    half = 1.96 * a.std(ddof=1) / np.sqrt(a.size) if a.size > 1 else float("nan")
    return f"{a.mean():.3g} ± {half:.2g}"


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_quick_option(parser, "2 seeds of one box (for tests)")
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--out", default="results/methods")
    args = parser.parse_args(argv)
    seeds, duration = (range(QUICK.seeds), 527.2) if args.quick else (range(args.seeds), 1800.0)
    values = run(list(seeds), duration)
    out = Path(args.out)
    text = table(values, len(seeds), duration)
    write_text(out / "table.md", text)
    write_text(
        out / "results.json",
        json.dumps({"duration_s": duration, "seeds": list(seeds), "values": values}, indent=2),
    )
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
