"""Calibrate on one flight, apply to the next: pairs of simulated flights of one aircraft.

``python experiments/calibrate_then_apply.py [--quick] [--pairs 10] [--out DIR]`` simulates,
for each pair, one aircraft (``AircraftConfig(seed=…)``) flying a calibration box (flight seed
2i) and then a survey (flight seed 2i + 1, another trajectory and noise), and measures against
the simulator's true interference:

* Tolles–Lawson calibrated on the box and applied to the survey, against Tolles–Lawson fitted on
  the survey itself (RMSE of the scalar interference over the whole survey, means removed as
  the band-passed fit cannot see them) [nT];
* the Kalman filter started from the calibrated state, against one started cold (the package's
  prior), over the first minutes of the survey (RMSE of the vector interference) [nT];
* the recalibrate check on the same aircraft's survey, another aircraft's (aircraft seed
  + 1000) and the same aircraft after maintenance (permanent field shifted).

Writes ``results.json`` (per pair and summary, with the command, the date and the package
version) in ``--out`` (default ``results/calibrate_then_apply``); the copy the documentation
quotes is ``docs/howto/calibrate_then_apply.json``.
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
from aeromag_env.compensation.model_fit import apply_model, fit_model
from aeromag_env.compensation.tolles_lawson import TollesLawson
from aeromag_env.flight.data import vector_names
from aeromag_env.simulation.config import AircraftConfig, preset, with_overrides
from aeromag_env.simulation.simulate import simulate_flight

#: The first minutes of the survey over which warm and cold filters are compared [s].
EARLY_S = (60.0, 300.0)
#: The maintenance of the changed aircraft: permanent-field shifts at the fluxgate and the
#: stinger [nT] (a magnetised part replaced near the cabin, felt faintly at the tail).
SHIFT_NT = ((60.0, -40.0, 30.0), (20.0, -15.0, 10.0))


def flights(pair: int, survey_s: float) -> dict[str, Any]:
    """The pair's calibration and survey flights, and the survey of another aircraft and of the
    same aircraft after maintenance."""
    base = preset("nominal")
    survey = with_overrides(
        base, {"trajectory.pattern": "survey", "trajectory.duration_s": survey_s}
    )
    plane = AircraftConfig(seed=100 + pair)
    other = AircraftConfig(seed=1100 + pair)
    changed = dataclasses.replace(
        plane, permanent_shift_nt=SHIFT_NT[0], scalar_permanent_shift_nt=SHIFT_NT[1]
    )
    return {
        "calibration": simulate_flight(dataclasses.replace(base, aircraft=plane), 2 * pair),
        "survey": simulate_flight(dataclasses.replace(survey, aircraft=plane), 2 * pair + 1),
        "other": simulate_flight(dataclasses.replace(survey, aircraft=other), 2 * pair + 1),
        "changed": simulate_flight(dataclasses.replace(survey, aircraft=changed), 2 * pair + 1),
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
    applied = apply_model(tl_model, survey)
    own = compensate_scalar(survey, "flux_a", "mag_1_uc", TollesLawson())
    kf_model, _ = fit_model(cal, "kf", flux="flux_a")
    warm = apply_model(kf_model, survey)
    cold = compensate_vector(survey, "kf", "flux_a", FilterConfig(method="kf"))
    est = {
        name: np.column_stack([c.fields[n] for n in vector_names(INTERFERENCE)])
        for name, c in (("warm", warm), ("cold", cold))
    }
    return {
        "pair": pair,
        "aircraft_seed": 100 + pair,
        "flight_seeds": [2 * pair, 2 * pair + 1],
        "tl_rmse_nt": {
            "calibrated": score(survey, applied)["compensation_rmse_all_nt"],
            "fitted_on_survey": score(survey, own)["compensation_rmse_all_nt"],
        },
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
            which: drift_warning(model.method, cal, apply_model(model, f[which]).settings["drift"])
            is not None
            for which in ("survey", "other", "changed")
        }
    return out


def summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Means over pairs, the pairs where calibrated TL is at least as good as the survey fit,
    where the warm filter beats the cold one, and the warning counts."""

    def col(get: Any) -> np.ndarray:
        return np.array([get(r) for r in rows], dtype=float)

    tl_cal = col(lambda r: r["tl_rmse_nt"]["calibrated"])
    tl_own = col(lambda r: r["tl_rmse_nt"]["fitted_on_survey"])
    out: dict[str, Any] = {
        "pairs": len(rows),
        "tl_rmse_nt_mean": {
            "calibrated": float(tl_cal.mean()),
            "fitted_on_survey": float(tl_own.mean()),
        },
        "tl_calibrated_at_least_as_good": int(np.sum(tl_cal <= tl_own)),
    }
    for s in EARLY_S:
        key = f"first_{int(s)}_s"
        warm = col(lambda r, k=key: r["kf_rmse_nt"]["warm"][k])
        cold = col(lambda r, k=key: r["kf_rmse_nt"]["cold"][k])
        out[f"kf_rmse_nt_mean_{key}"] = {"warm": float(warm.mean()), "cold": float(cold.mean())}
        out[f"kf_warm_better_{key}"] = int(np.sum(warm < cold))
    out["recalibrate_warnings"] = {
        m: {
            w: int(sum(r["recalibrate_warning"][m][w] for r in rows))
            for w in ("survey", "other", "changed")
        }
        for m in ("tl", "kf")
    }
    return out


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="2 pairs, 5-minute surveys (tests)")
    parser.add_argument("--pairs", type=int, default=10)
    parser.add_argument("--survey-s", type=float, default=1200.0, help="survey length [s]")
    parser.add_argument("--out", type=Path, default=Path("results/calibrate_then_apply"))
    args = parser.parse_args(argv)
    pairs, survey_s = (2, 300.0) if args.quick else (args.pairs, args.survey_s)
    rows = [one_pair(i, survey_s) for i in range(pairs)]
    result = {
        "command": "python experiments/calibrate_then_apply.py " + " ".join(argv or sys.argv[1:]),
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
