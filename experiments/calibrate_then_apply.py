"""Calibrate on one flight, apply to the next: pairs of simulated flights of one aircraft.

``python experiments/calibrate_then_apply.py [--quick] [--pairs 12] [--out DIR]`` simulates,
for each pair, one aircraft (``AircraftConfig(seed=…)``) flying a calibration box at 3000 m
(flight seed 2i) and then a survey at 400 m (flight seed 2i + 1: another trajectory and noise),
once without and once over crustal geology (50 nT RMS at 400 m, the simulator's crust model), and
measures against the simulator's true interference of the aircraft:

* Tolles–Lawson calibrated on the box and applied to the survey, against Tolles–Lawson fitted on
  the survey itself. The survey fit is judged on the flight it was fitted on (in sample), so it
  is also fitted on each half of the survey and judged on the other half (out of sample). RMSE
  of the scalar interference [nT], means removed (a band-passed fit cannot see them): over the
  whole survey for the calibrated and the in-sample fits (the package's
  ``compensation_rmse_all_nt``), over each half with its own mean for the three together; and
  two references without sensor noise: the floor, the 18 terms fitted by least squares to the
  true interference itself over the survey (no band-pass), the best any Tolles–Lawson
  coefficients do there; and the terms fitted so to the box's true interference and applied to
  the survey (what calibrating on another flight costs without noise);
* the Kalman filter continued from the calibrated model, against one started cold (the
  package's prior), over the first minutes of the survey (RMSE of the vector interference) [nT];
* the recalibrate check on the same aircraft's surveys (without and over geology), another
  aircraft's (aircraft seed + 1000) and the same aircraft's after maintenance (permanent field
  shifted).

Every comparison is paired (the same survey): the mean difference with its 95 % t interval over
the pairs, and the count of pairs each way. Writes ``results.json`` (per pair and summary, with
the command, the date and the package version) in ``--out`` (default
``results/calibrate_then_apply``); the copy the documentation quotes is
``docs/howto/calibrate_then_apply.json``.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime as _dt
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import aeromag_env
from aeromag_env.atomic import write_text
from aeromag_env.compensation import metrics
from aeromag_env.compensation.compensate import (
    INTERFERENCE,
    compensate_scalar,
    compensate_vector,
    score,
)
from aeromag_env.compensation.model import FilterConfig
from aeromag_env.compensation.model_drift import drift_warning
from aeromag_env.compensation.model_fit import fit_model
from aeromag_env.compensation.tolles_lawson import TollesLawson
from aeromag_env.flight.data import vector_names
from aeromag_env.quick import add_quick_option
from aeromag_env.simulation.config import AircraftConfig, GeologyConfig, preset, with_overrides
from aeromag_env.simulation.simulate import simulate_flight
from aeromag_env.simulation.tolles_lawson_terms import design_matrix

#: The first minutes of the survey over which warm and cold filters are compared [s].
EARLY_S = (60.0, 300.0)
#: The maintenance of the changed aircraft: permanent-field shifts at the fluxgate and the
#: stinger [nT] (a magnetised part replaced near the cabin, felt faintly at the tail).
SHIFT_NT = ((60.0, -40.0, 30.0), (20.0, -15.0, 10.0))
#: The crust under the survey: the simulator's default, 50 nT RMS at 400 m (survey altitude).
GEOLOGY = GeologyConfig(rms_nt=50.0)
#: The surveys every pair flies, by name: (geology, aircraft changed, another aircraft).
SURVEYS = {
    "survey": (None, False, False),
    "survey_geology": (GEOLOGY, False, False),
    "other": (None, False, True),
    "changed": (None, True, False),
}


def flights(pair: int, survey_s: float) -> dict[str, Any]:
    """The pair's calibration flight and its surveys (:data:`SURVEYS`)."""
    base = preset("nominal")
    survey = with_overrides(
        base, {"trajectory.pattern": "survey", "trajectory.duration_s": survey_s}
    )
    plane = AircraftConfig(seed=100 + pair)
    made = {"calibration": simulate_flight(dataclasses.replace(base, aircraft=plane), 2 * pair)}
    for name, (geology, changed, other) in SURVEYS.items():
        aircraft = plane
        if changed:
            aircraft = dataclasses.replace(
                plane, permanent_shift_nt=SHIFT_NT[0], scalar_permanent_shift_nt=SHIFT_NT[1]
            )
        if other:
            aircraft = AircraftConfig(seed=1100 + pair)
        cfg = dataclasses.replace(survey, aircraft=aircraft, geology=geology)
        made[name] = simulate_flight(cfg, 2 * pair + 1)
    return made


def demeaned_rmse(truth: np.ndarray, est: np.ndarray, parts: Sequence[np.ndarray]) -> float:
    """RMSE of ``est`` against ``truth`` (n,) [nT] with each part's means removed, pooled over
    the parts (masks)."""
    squares = []
    for part in parts:
        ok = part & np.isfinite(truth) & np.isfinite(est)
        err = (truth[ok] - truth[ok].mean()) - (est[ok] - est[ok].mean())
        squares.append(np.mean(err**2))
    return float(np.sqrt(np.mean(squares)))


def truth_fit(flight: Any) -> np.ndarray:
    """The 18 Tolles–Lawson terms least-squares fitted to ``flight``'s true scalar interference
    (means removed, no band-pass: no sensor noise) [nT]."""
    a, truth = design_matrix(flight.vector("flux_a")), flight["truth_interf_mag_1"]
    ok = np.all(np.isfinite(a), axis=1) & np.isfinite(truth)
    return np.linalg.lstsq(a[ok] - a[ok].mean(axis=0), truth[ok] - truth[ok].mean(), rcond=None)[0]


def truth_rmse(flight: Any, coef: np.ndarray) -> float:
    """RMSE of the terms with ``coef`` against ``flight``'s true interference, means removed
    [nT]."""
    est = design_matrix(flight.vector("flux_a")) @ coef
    one = (np.ones(flight.n, dtype=bool),)
    return demeaned_rmse(flight["truth_interf_mag_1"], est, one)


def tl_figures(model: Any, survey: Any, box: Any) -> dict[str, float]:
    """Calibrated on the ``box`` against the survey's own fit, in and out of sample, and the
    references without noise [nT]."""
    truth = survey["truth_interf_mag_1"]
    applied = model.apply(survey)
    own = compensate_scalar(survey, "flux_a", "mag_1_uc", TollesLawson())
    first = np.arange(survey.n) < survey.n // 2
    halves = (first, ~first)
    crossed = np.full(survey.n, np.nan)
    for fitted_on in halves:
        c = compensate_scalar(survey, "flux_a", "mag_1_uc", TollesLawson(), calibration=fitted_on)
        crossed[~fitted_on] = (c.total_before - c.total_after)[~fitted_on]
    est = {
        "calibrated": applied.total_before - applied.total_after,
        "fitted_on_survey": own.total_before - own.total_after,
    }
    return {
        "calibrated": score(survey, applied)["compensation_rmse_all_nt"],
        "fitted_on_survey": score(survey, own)["compensation_rmse_all_nt"],
        "halves_calibrated": demeaned_rmse(truth, est["calibrated"], halves),
        "halves_fitted_on_survey": demeaned_rmse(truth, est["fitted_on_survey"], halves),
        "halves_fitted_on_other_half": demeaned_rmse(truth, crossed, halves),
        "floor": truth_rmse(survey, truth_fit(survey)),
        "noise_free_calibration": truth_rmse(survey, truth_fit(box)),
    }


def early_rmse(flight: Any, est: np.ndarray) -> dict[str, float]:
    """RMSE of the vector interference estimate over the first :data:`EARLY_S` seconds [nT]."""
    truth = flight.vector("truth_interf")
    t = flight.tt - flight.tt[0]
    return {
        f"first_{int(s)}_s": float(metrics.compensation_rmse(truth, est, t < s)) for s in EARLY_S
    }


def one_pair(pair: int, survey_s: float) -> dict[str, Any]:
    """Every figure of one pair."""
    f = flights(pair, survey_s)
    cal, survey = f["calibration"], f["survey"]
    tl_model, _ = fit_model(cal, "tl", flux="flux_a", scalar="mag_1_uc")
    kf_model, _ = fit_model(cal, "kf", flux="flux_a")
    warm = kf_model.apply(survey)
    cold = compensate_vector(survey, "kf", "flux_a", FilterConfig(method="kf"))
    est = {
        name: np.column_stack([c.fields[n] for n in vector_names(INTERFERENCE)])
        for name, c in (("warm", warm), ("cold", cold))
    }
    return {
        "pair": pair,
        "aircraft_seed": 100 + pair,
        "flight_seeds": [2 * pair, 2 * pair + 1],
        "tl_rmse_nt": tl_figures(tl_model, survey, cal),
        "tl_rmse_nt_geology": tl_figures(tl_model, f["survey_geology"], cal),
        "kf_rmse_nt": {
            "warm": early_rmse(survey, est["warm"]),
            "cold": early_rmse(survey, est["cold"]),
        },
        "recalibrate_warning": checks(tl_model, kf_model, f),
    }


def checks(tl_model: Any, kf_model: Any, f: dict[str, Any]) -> dict[str, dict[str, bool]]:
    """Whether the recalibrate check fires, per model and survey flight."""
    out: dict[str, dict[str, bool]] = {}
    for name, model in (("tl", tl_model), ("kf", kf_model)):
        cal = model.calibration["residual"]
        out[name] = {
            which: drift_warning(model.method, cal, model.apply(f[which]).settings["drift"])
            is not None
            for which in SURVEYS
        }
    return out


def paired(a: np.ndarray, b: np.ndarray) -> dict[str, Any]:
    """``a − b`` over the pairs: mean, its 95 % t interval, and the pairs with ``a ≤ b``."""
    from scipy import stats

    d = a - b
    half = float(stats.t.ppf(0.975, d.size - 1) * d.std(ddof=1) / np.sqrt(d.size))
    return {
        "mean_a": float(a.mean()),
        "mean_b": float(b.mean()),
        "mean_difference": float(d.mean()),
        "ci95": [float(d.mean() - half), float(d.mean() + half)],
        "pairs_a_at_most_b": int(np.sum(a <= b)),
        "pairs": int(d.size),
    }


def summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The paired comparisons (calibrated TL against the survey's own fits, without and over
    geology; the warm filter against the cold one) and the warning counts."""

    def col(*keys: str) -> np.ndarray:
        out = []
        for r in rows:
            v: Any = r
            for k in keys:
                v = v[k]
            out.append(v)
        return np.array(out, dtype=float)

    out: dict[str, Any] = {"pairs": len(rows)}
    for block in ("tl_rmse_nt", "tl_rmse_nt_geology"):
        out[block] = {
            "floor_mean": float(col(block, "floor").mean()),
            "noise_free_calibration_mean": float(col(block, "noise_free_calibration").mean()),
            "calibrated_minus_fitted_on_survey": paired(
                col(block, "calibrated"), col(block, "fitted_on_survey")
            ),
            "halves_calibrated_minus_fitted_on_other_half": paired(
                col(block, "halves_calibrated"), col(block, "halves_fitted_on_other_half")
            ),
            "halves_fitted_on_survey_minus_fitted_on_other_half": paired(
                col(block, "halves_fitted_on_survey"), col(block, "halves_fitted_on_other_half")
            ),
        }
    for s in EARLY_S:
        key = f"first_{int(s)}_s"
        out[f"kf_warm_minus_cold_{key}"] = paired(
            col("kf_rmse_nt", "warm", key), col("kf_rmse_nt", "cold", key)
        )
    out["recalibrate_warnings"] = {
        m: {w: int(sum(r["recalibrate_warning"][m][w] for r in rows)) for w in SURVEYS}
        for m in ("tl", "kf")
    }
    return out


#: The rows of the documentation's table: label, summary key, the comparison in it, digits.
TABLE_ROWS = (
    (
        "Tolles–Lawson, whole survey (survey fit in sample)",
        "tl_rmse_nt",
        "calibrated_minus_fitted_on_survey",
        4,
    ),
    (
        "Tolles–Lawson, each half (survey fit on the other half)",
        "tl_rmse_nt",
        "halves_calibrated_minus_fitted_on_other_half",
        4,
    ),
    (
        "over geology: whole survey (in sample)",
        "tl_rmse_nt_geology",
        "calibrated_minus_fitted_on_survey",
        3,
    ),
    (
        "over geology: each half (on the other half)",
        "tl_rmse_nt_geology",
        "halves_calibrated_minus_fitted_on_other_half",
        3,
    ),
    ("Kalman filter, first 60 s (warm / cold)", "kf_warm_minus_cold_first_60_s", None, 2),
    ("Kalman filter, first 300 s (warm / cold)", "kf_warm_minus_cold_first_300_s", None, 2),
)


def markdown_table(summary: dict[str, Any]) -> str:
    """The documentation's table of the paired comparisons (docs/howto/calibrate.md)."""
    lines = [
        "| RMSE against the true interference [nT], mean over the pairs | calibrated | fitted "
        "on the survey / started cold | difference, 95 % interval | pairs calibrated ≤ |",
        "|---|---|---|---|---|",
    ]
    for label, block, key, digits in TABLE_ROWS:
        c = summary[block] if key is None else summary[block][key]
        low, high = c["ci95"]
        lines.append(
            f"| {label} | {c['mean_a']:.{digits}f} | {c['mean_b']:.{digits}f} | "
            f"{c['mean_difference']:+.{digits}f} [{low:+.{digits}f}, {high:+.{digits}f}] | "
            f"{c['pairs_a_at_most_b']} of {c['pairs']} |"
        )
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_quick_option(parser, "3 pairs, 5-minute surveys (tests)")
    parser.add_argument("--pairs", type=int, default=12)
    parser.add_argument("--survey-s", type=float, default=1200.0, help="survey length [s]")
    parser.add_argument("--out", type=Path, default=Path("results/calibrate_then_apply"))
    parser.add_argument(
        "--table", type=Path, metavar="RESULTS", help="print the table of a results.json and stop"
    )
    args = parser.parse_args(argv)
    if args.table is not None:
        print(markdown_table(json.loads(args.table.read_text())["summary"]))
        return 0
    pairs, survey_s = (3, 300.0) if args.quick else (args.pairs, args.survey_s)
    rows = [one_pair(i, survey_s) for i in range(pairs)]
    result = {
        "command": "python experiments/calibrate_then_apply.py "
        + " ".join(sys.argv[1:] if argv is None else argv),
        "date": _dt.date.today().isoformat(),
        "package_version": aeromag_env.__version__,
        "survey_s": survey_s,
        "summary": summary(rows),
        "pairs": rows,
    }
    args.out.mkdir(parents=True, exist_ok=True)
    write_text(args.out / "results.json", json.dumps(result, indent=1) + "\n")
    print(json.dumps(result["summary"], indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
