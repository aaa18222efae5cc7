"""The statistics of the hidden-effect suite (:mod:`aeromag_env.discovery.suite`): detection
rates with Wilson intervals, the power per effect, SNR and flight duration, false alarms, the
confusion between effects, from the rows the suite's cases give (one per flight). The
documentation's discovery pages are made from their output
(``python -m experiments.hidden_effects``)."""

from __future__ import annotations

import math
from collections import Counter
from typing import Any

import numpy as np

from aeromag_env.discovery.suite import DURATION_SNRS, DURATIONS_S, SINGLE, SNRS

#: Case kinds without an injected effect: an ``--effects`` subset keeps them.
NULL_KINDS = ("null", "coloured_null")


def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """Wilson score 95 % interval of a binomial proportion."""
    if n == 0:
        return (float("nan"), float("nan"))
    p = k / n
    den = 1 + z * z / n
    mid = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return (mid - half, mid + half)


def rate(flags: list[bool]) -> dict[str, Any]:
    """``k`` of ``n`` flags true: the rate with its Wilson 95 % interval (NaN for none)."""
    k, n = sum(flags), len(flags)
    lo, hi = wilson(k, n)
    return {"k": k, "n": n, "rate": k / n if n else float("nan"), "ci95": [lo, hi]}


def detected(r: dict[str, Any]) -> bool:
    """The injected single effect is among the named ones, with its channel (extras allowed)."""
    return [r["effects"][0], r["truth"][0][1]] in r["named"]


def duration_power(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Detection rate of the ``duration`` cases per SNR, effect and duration [s], and the decoy
    channels named on those flights."""
    dur = [r for r in rows if r["kind"] == "duration"]
    power = {
        str(snr): {
            nm: {
                str(int(d)): rate(
                    [
                        detected(r)
                        for r in dur
                        if r["effects"] == [nm] and r["snr"] == snr and r["duration_s"] == d
                    ]
                )
                for d in DURATIONS_S
            }
            for nm in SINGLE
        }
        for snr in DURATION_SNRS
    }
    return {
        "detection": "the effect with its channel among the named ones (as `power`)",
        "power": power,
        "decoy_named": sum(len(r["decoy_named"]) for r in dur),
        "flights": len(dur),
    }


def summarise(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The README's claims on the SNR kinds; the ``duration`` kind has its own section."""
    duration, cases = duration_power(rows), Counter(r["kind"] for r in rows)
    rows = [r for r in rows if r["kind"] != "duration"]
    singles = [r for r in rows if r["kind"] == "single"]
    strong = [r for r in singles if r["snr"] >= 2]
    nulls = [r for r in rows if r["kind"] in ("null", "coloured_null")]
    top1 = [bool(r["named"]) and tuple(r["named"][0]) == tuple(r["truth"][0]) for r in strong]
    per_effect = {}
    for nm in SINGLE:
        sub = [r for r in strong if r["effects"] == [nm]]
        per_effect[nm] = {
            "exact": rate([r["exact"] for r in sub]),
            "median_shrink": float(np.median([r["shrink"] for r in sub])),
            "shrink_at_least_2": rate([r["shrink"] >= 2 for r in sub]),
        }
    power = {
        nm: {
            str(s): rate([detected(r) for r in singles if r["effects"] == [nm] and r["snr"] == s])
            for s in SNRS
        }
        for nm in SINGLE
    }
    labels = [*SINGLE, "nothing"]
    confusion: dict[str, Counter[str]] = {t: Counter() for t in [*SINGLE, "null"]}
    for r in singles + nulls:
        if r["kind"] == "single" and r["snr"] < 2:
            continue
        t = r["effects"][0] if r["kind"] == "single" else "null"
        names = [n for n, _ in r["named"]] or ["nothing"]
        confusion[t].update(names)
    return {
        "single_snr_ge_2": {
            "exact_set": rate([r["exact"] for r in strong]),
            "top1": rate(top1),
            "median_shrink": float(np.median([r["shrink"] for r in strong])),
            "shrink_at_least_2": rate([r["shrink"] >= 2 for r in strong]),
            "per_effect": per_effect,
        },
        "false_alarm": {
            "all_nulls": rate([bool(r["named"]) for r in nulls]),
            "null": rate([bool(r["named"]) for r in nulls if r["kind"] == "null"]),
            "coloured_null": rate(
                [bool(r["named"]) for r in nulls if r["kind"] == "coloured_null"]
            ),
        },
        "absorbed": {
            "absorbed_effect_named": sum(len(r["absorbed_named"]) for r in rows),
            "anything_named_on_absorbed_cases": rate(
                [bool(r["named"]) for r in rows if r["kind"] == "absorbed"]
            ),
        },
        "decoy_named": sum(len(r["decoy_named"]) for r in rows),
        "cases_with_decoys": len(rows),
        "pairs_exact_set": rate([r["exact"] for r in rows if r["kind"] == "pair"]),
        "power": power,
        "power_duration": duration,
        "confusion": {t: {c: confusion[t].get(c, 0) for c in labels} for t in confusion},
        "cases": cases,
    }
