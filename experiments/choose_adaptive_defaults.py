"""Choose the defaults of ``vbakf``, ``vbakf-pr`` and ``imm`` on simulated training flights.

``python experiments/choose_adaptive_defaults.py [--quick] [--seeds 4] [--out FILE]`` flies every
scenario of the suite (:data:`aeromag_env.environment.ids.SCENARIOS`) on training seeds 1000,
1001, … (far below ``agents.evaluate.TEST_SEED_START``), compensates each flight with
``compensate_vector`` (the scenario's own initial Q(0), R(0)) and scores the RMSE of the
interference estimate against the simulator's truth over the second half of the flight
(``score``'s ``compensation_rmse_nt``). Each method's settings are searched one at a time, from a
starting point (the papers' values where they give them), in the order listed in
:data:`SEARCHES`: every value of a setting is tried with the others at their best so far, and
the one with the lowest mean log RMSE ratio to ``kf`` over all flights is kept — where a value
listed earlier (cheaper: fewer iterations or models, or the papers') is within
:data:`TIE_RATIO` of it, that one; values in :data:`INELIGIBLE` are scored but not chosen
(the reason is recorded). The baselines
``kf``, ``sage-husa`` and ``ding`` run with their package defaults. The chosen settings are then
scored with the baselines on other training seeds (from :data:`CHECK_SEED`), which the search
never saw: the table the documentation quotes. Writes the JSON that
``aeromag_env/compensation/adaptive_settings.py`` cites (default
``docs/results/adaptive_defaults.json``; ``--quick`` writes ``results/`` by default).
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import sys
import time
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import aeromag_env
from aeromag_env.atomic import write_text
from aeromag_env.compensation.adaptive_settings import (
    BankModel,
    ModelBank,
    VbakfPrSettings,
    VbakfSettings,
)
from aeromag_env.compensation.compensate import compensate_vector, score
from aeromag_env.compensation.model import FilterConfig
from aeromag_env.configs import to_dict
from aeromag_env.environment.ids import SCENARIOS
from aeromag_env.environment.scenarios import Episode, make_episode
from aeromag_env.quick import add_quick_option

#: The first training seed of the search, and of the check of its choice on flights it did not
#: see (agents.evaluate.TEST_SEED_START is 100 000; training seeds are below it).
FIRST_SEED, CHECK_SEED = 1000, 1100
BASELINES = ("kf", "sage-husa", "ding")
#: A value listed later must beat every earlier one by more than this factor to be chosen.
TIE_RATIO = 1.005
#: Values scored but never chosen, and why.
INELIGIBLE = {
    ("vbakf-pr", "iterations", 1): "with one iteration the P⁻ estimate never enters the update "
    "(P⁻⁽¹⁾ = (τ P̃⁻ + P̃⁻) / (τ + 1) = P̃⁻): the filter is then an R-only estimator",
}
#: Where the results go: the committed file the settings cite, or (``--quick``) a scratch one.
OUT, QUICK_OUT = "docs/results/adaptive_defaults.json", "results/adaptive_defaults.json"
#: The tuned constants of the suite (agents/tuned_constants.json) as (log10 Q, log10 R) scales.
TUNED = {
    "nominal": (-10.0, -2.0),
    "paper": (-10.0, 3.0),
    "misspecified": (-1.0, -2.0),
    "nonstationary": (4.0, -2.0),
    "calibration_then_survey": (6.0, -1.0),
    "noise_bursts": (-1.0, 3.0),
    "degradation": (0.0, 3.0),
    "manoeuvre_heavy": (0.0, 3.0),
}


def _bank(*scales: tuple[float, float]) -> tuple[BankModel, ...]:
    """Models at Q(0), R(0) and at the given log10 (Q, R) scales."""
    models = [(0.0, 0.0), *dict.fromkeys(s for s in scales if s != (0.0, 0.0))]
    return tuple(BankModel(q_scale=10.0**q, r_scale=10.0**r) for q, r in models)


BANKS = {
    "own+R×0.1+R×10": _bank((0.0, -1.0), (0.0, 1.0)),
    "own+R×0.01+R×1000": _bank((0.0, -2.0), (0.0, 3.0)),
    "own+Q×1e4+Q×1e-4": _bank((4.0, 0.0), (-4.0, 0.0)),
    "own+nonstationary+noise_bursts": _bank(TUNED["nonstationary"], TUNED["noise_bursts"]),
    "own+R×0.01+R×1000+Q×1e4": _bank((0.0, -2.0), (0.0, 3.0), (4.0, 0.0)),
    "own+all tuned": _bank(*TUNED.values()),
    "3×3 grid Q 1e-4…1e4, R 1e-2…1e2": _bank(
        *((q, r) for q in (-4.0, 0.0, 4.0) for r in (-2.0, 0.0, 2.0))
    ),
}
#: The search of each method: its starting settings and the values tried, setting by setting.
SEARCHES: dict[str, tuple[Any, dict[str, list[Any]]]] = {
    "vbakf": (
        VbakfSettings(rho=0.99, iterations=2, prior_shape=1.0),
        {
            "rho": [0.99, 0.8, 0.9, 0.95, 0.995, 0.999],
            "prior_shape": [1.0, 10.0, "steady"],
            "iterations": [1, 2, 3, 5],
        },
    ),
    "vbakf-pr": (
        VbakfPrSettings(tau=3.0, rho=1.0 - math.exp(-4.0), iterations=10, prior_dof=21.0),
        {
            "tau": [3.0, 1.0, 10.0, 30.0, 100.0],
            "rho": [1.0 - math.exp(-4.0), 0.95, 0.99, 0.995, 0.999],
            "prior_dof": [21.0, 2.0, "steady"],
            "iterations": [1, 2, 3, 5, 10],
        },
    ),
    "imm": (
        ModelBank(models=BANKS["own+nonstationary+noise_bursts"], stay=0.99),
        {
            "models": list(BANKS),
            "stay": [0.99, 0.9, 0.999, 0.9999, 0.99999],
            "mixing": ["imm", "mmae"],
        },
    ),
}
FIELD = {"vbakf": "vbakf", "vbakf-pr": "vbakf_pr", "imm": "imm"}


def _resolve(settings: Any, name: str, value: Any) -> Any:
    """``settings`` with ``name`` set to ``value`` (``steady``: the prior as strong as the
    forgetting's memory, α∞ = ½ / (1 − ρ) or û∞ − m − 1 = 1 / (1 − ρ); a bank's name: its
    models)."""
    if value == "steady":
        memory = 1.0 / (1.0 - settings.rho)
        value = 0.5 * memory if name == "prior_shape" else memory
    elif name == "models":
        value = BANKS[value]
    return replace(settings, **{name: value})


def _rmse(ep: Episode, cfg: FilterConfig) -> float:
    comp = compensate_vector(ep.flight, cfg.method, filter_cfg=cfg, check_mount=False)
    value = score(ep.flight, comp)["compensation_rmse_nt"]
    return float(value) if value is not None and np.isfinite(value) else math.inf


def _evaluate(
    episodes: dict[tuple[str, int], Episode], method: str, settings: Any | None
) -> dict[str, list[float]]:
    """RMSE [nT] of ``method`` (with ``settings`` for its field) per scenario, one per seed."""
    out: dict[str, list[float]] = {}
    for (scenario, _), ep in episodes.items():
        cfg = replace(ep.filter_cfg, method=method)
        if settings is not None:
            cfg = replace(cfg, **{FIELD[method]: settings})
        out.setdefault(scenario, []).append(_rmse(ep, cfg))
    return out


def _log_ratio(rmse: dict[str, list[float]], kf: dict[str, list[float]]) -> float:
    """Mean over all flights of ln(RMSE / RMSE of kf) (a geometric mean ratio, in logs)."""
    logs = [math.log(a / b) for s in rmse for a, b in zip(rmse[s], kf[s], strict=True) if b > 0]
    return float(np.mean(logs))


def _search(
    method: str, episodes: dict[tuple[str, int], Episode], kf: dict[str, list[float]], quick: bool
) -> dict[str, Any]:
    """The one-setting-at-a-time search of ``method``: every step's values and the choice."""
    best, grid = SEARCHES[method]
    steps = []
    for name, values in grid.items():
        tried = []
        for value in values[:2] if quick else values:
            settings = _resolve(best, name, value)
            rmse = _evaluate(episodes, method, settings)
            tried.append(
                {
                    "value": value,
                    "settings": _jsonable(settings),
                    "geometric_mean_ratio_to_kf": math.exp(_log_ratio(rmse, kf)),
                    "mean_rmse_nt": {s: float(np.mean(v)) for s, v in rmse.items()},
                }
            )
            print(f"  {method} {name}={value}: ×{tried[-1]['geometric_mean_ratio_to_kf']:.3f}")
        chosen = _choose(method, name, tried)
        best = _resolve(best, name, chosen["value"])
        steps.append({"setting": name, "tried": tried, "chosen": chosen["value"]})
    return {"steps": steps, "chosen": _jsonable(best), "settings": best}


def _choose(method: str, name: str, tried: list[dict[str, Any]]) -> dict[str, Any]:
    """The value kept: the lowest ratio, unless an earlier-listed one is within TIE_RATIO of it;
    ineligible values marked and passed over."""
    eligible = []
    for t in tried:
        reason = INELIGIBLE.get((method, name, t["value"]))
        if reason:
            t["not_chosen_because"] = reason
        else:
            eligible.append(t)
    best = min(t["geometric_mean_ratio_to_kf"] for t in eligible)
    return next(t for t in eligible if t["geometric_mean_ratio_to_kf"] <= TIE_RATIO * best)


def _jsonable(settings: Any) -> dict[str, Any]:
    return to_dict(settings)


def _episodes(
    scenarios: Sequence[str], seeds: Sequence[int], duration_s: float | None
) -> dict[tuple[str, int], Episode]:
    return {(s, seed): make_episode(s, seed, duration_s) for s in scenarios for seed in seeds}


def run(
    scenarios: Sequence[str],
    seeds: Sequence[int],
    check_seeds: Sequence[int],
    duration_s: float | None,
    quick: bool,
) -> dict[str, Any]:
    """The searches on ``seeds`` and the check of their choices on ``check_seeds`` (a
    JSON-ready dict)."""
    episodes = _episodes(scenarios, seeds, duration_s)
    baselines = {m: _evaluate(episodes, m, None) for m in BASELINES}
    searches = {m: _search(m, episodes, baselines["kf"], quick) for m in SEARCHES}
    checks = _episodes(scenarios, check_seeds, duration_s)
    rmse = {m: _evaluate(checks, m, None) for m in BASELINES}
    for method, found in searches.items():
        rmse[method] = _evaluate(checks, method, found.pop("settings"))
    table: dict[str, Any] = {}
    for method, values in rmse.items():
        table[method] = {s: float(np.mean(v)) for s, v in values.items()}
        table[method]["geometric_mean_ratio_to_kf"] = math.exp(_log_ratio(values, rmse["kf"]))
    return {"searches": searches, "check_seeds": list(check_seeds), "check_mean_rmse_nt": table}


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_quick_option(parser, "two scenarios, 200 s, one seed")
    parser.add_argument("--seeds", type=int, default=4, help="training seeds per scenario")
    parser.add_argument("--out", default=None, help="the JSON written")
    args = parser.parse_args(argv)
    scenarios = ("nominal", "noise_bursts") if args.quick else SCENARIOS
    count = 1 if args.quick else args.seeds
    seeds, check_seeds = (
        range(FIRST_SEED, FIRST_SEED + count),
        range(CHECK_SEED, CHECK_SEED + count),
    )
    duration = 200.0 if args.quick else None
    default_out = QUICK_OUT if args.quick else OUT
    t0 = time.perf_counter()
    found = run(scenarios, seeds, check_seeds, duration, args.quick)
    document = {
        "command": "python experiments/choose_adaptive_defaults.py"
        + (" --quick" if args.quick else f" --seeds {args.seeds}"),
        "date": datetime.date.today().isoformat(),
        "package_version": aeromag_env.__version__,
        "scenarios": list(scenarios),
        "seeds": list(seeds),
        "duration_s": duration,
        "metric": "compensation_rmse_nt (second half of the flight) [nT]",
        "objective": "mean over flights of ln(RMSE / RMSE of kf); reported as its exp",
        "seconds": round(time.perf_counter() - t0, 1),
        **found,
    }
    out = Path(args.out or default_out)
    write_text(out, json.dumps(document, indent=2) + "\n")
    for method, row in found["check_mean_rmse_nt"].items():
        cells = " ".join(f"{s}={v:.3g}" for s, v in row.items())
        print(f"{method}: {cells}")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
