"""The hidden-effect suite's statistics: Wilson intervals against scipy's, rates and the power
table from rows made up to a known answer."""

from __future__ import annotations

import math

import pytest
from scipy.stats import binomtest

from aeromag_env.discovery.power import detected, rate, summarise, wilson
from aeromag_env.discovery.suite import SINGLE


@pytest.mark.parametrize(("k", "n"), [(0, 10), (3, 10), (10, 10), (57, 120)])
def test_wilson_interval_is_scipys(k: int, n: int) -> None:
    ci = binomtest(k, n).proportion_ci(confidence_level=0.95, method="wilson")
    lo, hi = wilson(k, n)
    assert lo == pytest.approx(ci.low, abs=1e-4) and hi == pytest.approx(ci.high, abs=1e-4)
    assert all(math.isnan(v) for v in wilson(0, 0))


def _row(kind: str, effect: str | None, snr: float, named: list[list[str]]) -> dict:
    truth = [[effect, "cur_x"]] if effect else []
    return {
        "kind": kind,
        "effects": [effect] if effect else [],
        "snr": snr,
        "truth": truth,
        "named": named,
        "exact": named == truth,
        "shrink": 3.0 if named else 1.0,
        "absorbed_named": [],
        "decoy_named": [],
        "duration_s": None,
    }


def test_summary_counts_detections_and_false_alarms() -> None:
    effect = SINGLE[0]
    others = [_row("single", e, 2.0, [[e, "cur_x"]]) for e in SINGLE[1:]]  # every one found
    rows = [
        _row("single", effect, 2.0, [[effect, "cur_x"]]),
        _row("single", effect, 2.0, []),
        *others,
        _row("null", None, 0.0, [[effect, "cur_x"]]),
        _row("null", None, 0.0, []),
        _row("null", None, 0.0, []),
    ]
    assert detected(rows[0]) and not detected(rows[1])
    assert rate([True, False, False])["rate"] == pytest.approx(1 / 3)
    s = summarise(rows)
    assert s["single_snr_ge_2"]["exact_set"]["k"] == 1 + len(others)
    assert s["single_snr_ge_2"]["exact_set"]["n"] == 2 + len(others)
    assert s["single_snr_ge_2"]["per_effect"][effect]["exact"]["rate"] == 0.5
    assert s["false_alarm"]["null"]["k"] == 1 and s["false_alarm"]["null"]["n"] == 3
    assert s["power"][effect]["2.0"] == {**rate([True, False]), "ci95": list(wilson(1, 2))}
    assert s["confusion"]["null"][effect] == 1 and s["confusion"]["null"]["nothing"] == 2
