"""The adaptive filters' benchmark (:mod:`agents.comparison.adaptive`): its tables from flights
whose verdicts are known by construction, its refusals, and a resumed run that flies only what
is new."""

from __future__ import annotations

import numpy as np
import pytest

from aeromag_env.errors import AeromagError
from agents.comparison.adaptive import best_filter, fly, summarize

FLIGHTS = 20


def _flights(rmse: dict[str, np.ndarray], diverged: dict[str, int] | None = None) -> dict:
    out = {}
    for name, r in rmse.items():
        div = np.zeros(r.size)
        div[: (diverged or {}).get(name, 0)] = 1
        out[name] = {
            "rmse_nt": list(r),
            "divergences": list(div),
            "outliers_rejected": [0.0] * r.size,
        }
    return {"noise_bursts": out}


def test_the_tables_give_the_verdicts_built_into_the_flights():
    """``vbakf`` 0.5 nT below ``tuned_constant`` on every flight (better), ``imm`` equal to it
    but for noise (within), ``constant`` 2 nT above (worse); the worst 10 % is the mean of the 2
    largest of 20; the score is 0 at tuned_constant and 1 at privileged."""
    rng = np.random.default_rng(0)
    base = rng.uniform(2.0, 4.0, FLIGHTS)
    rmse = {
        "constant": base + 2.0,
        "vbakf": base - 0.5,
        "imm": base + rng.normal(0.0, 0.01, FLIGHTS),
        "tuned_constant": base,
        "privileged": base - 1.0,
        "general": base - 0.2,
    }
    rows = summarize(_flights(rmse, {"constant": 3}))["noise_bursts"]["policies"]
    assert rows["vbakf"]["vs_tuned_constant"] == "better"
    assert rows["imm"]["vs_tuned_constant"] == "same"
    assert rows["constant"]["vs_tuned_constant"] == "worse"
    assert rows["vbakf"]["vs_general"] == "better" and rows["constant"]["vs_general"] == "worse"
    assert rows["vbakf"]["diff_vs_constant_nt_mean"] == pytest.approx(-2.5, abs=1e-12)
    assert rows["constant"]["worst10_rmse_nt"] == pytest.approx(np.sort(base)[-2:].mean() + 2.0)
    assert rows["constant"]["worst_flights"] == 2
    assert rows["tuned_constant"]["normalized_score"] == pytest.approx(0.0, abs=1e-12)
    assert rows["privileged"]["normalized_score"] == pytest.approx(1.0)
    assert rows["vbakf"]["normalized_score"] == pytest.approx(0.5)
    lo, hi = rows["vbakf"]["normalized_score_ci95"]
    assert lo <= 0.5 <= hi
    assert rows["constant"]["diverged_flights"] == 3 and rows["vbakf"]["diverged_flights"] == 0
    assert best_filter({"policies": rows}) == "vbakf"


def test_the_benchmark_refuses_what_it_cannot_table():
    with pytest.raises(AeromagError, match="test seeds must be ≥ 100000"):
        fly(["nominal"], ["constant"], [5, 6])
    with pytest.raises(AeromagError, match="at least 2 flights"):
        fly(["nominal"], ["constant"], [400_000])
    with pytest.raises(AeromagError, match="unknown policies bogus"):
        fly(["nominal"], ["bogus"], [400_000, 400_001])


def test_a_resumed_benchmark_flies_only_the_new_pairs():
    seeds = [400_000, 400_001]
    flown: list[tuple[str, str]] = []
    first = fly(["nominal"], ["constant"], seeds, progress=lambda s, p, t: flown.append((s, p)))
    both = fly(
        ["nominal"], ["constant", "vbakf"], seeds, first, lambda s, p, t: flown.append((s, p))
    )
    assert flown == [("nominal", "constant"), ("nominal", "vbakf")]
    assert both["nominal"]["constant"] == first["nominal"]["constant"]
    assert len(both["nominal"]["vbakf"]["rmse_nt"]) == 2
