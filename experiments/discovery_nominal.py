"""False alarms of ``aeromag discover`` on plain simulated flights (issue 22).

Flights of the simulator's presets as a user makes them (``aeromag simulate --pattern
calibration+survey``), of several seeds and durations, with nothing injected. Two kinds of
flight:

* ``paper`` and ``noise_free``: everything in them is in the base model; any named effect is a
  false alarm.
* ``nominal``: its external (diurnal) variation is a vector fixed in the navigation frame, and the
  file's ``diurnal`` channel, like a scalar base station, records only its projection on the
  main field. The rest — the component across the main field — is in the flight and not in the
  base model: a real ``external_field_variation``. The script measures it (its RMS outside the
  base span, ``identifiable_rms_nt``, and that over the fluxgate noise std, ``snr``), counts
  naming it as a detection, and any *other* named effect as a false alarm.

Run: ``.venv/bin/python -m experiments.discovery_nominal [--flights 48] [--jobs 2]`` (seeds
60000+; 50000+ were the development seeds). Writes ``OUT/nominal.json`` and
``OUT/nominal.md`` (default ``docs/discovery``).
"""

from __future__ import annotations

import argparse
import json
import math
import time
from multiprocessing import Pool
from pathlib import Path
from typing import Any

import numpy as np

from aeromag_env.atomic import write_text
from aeromag_env.discovery.base_model import BaseSpan, base_columns
from aeromag_env.discovery.power import wilson
from aeromag_env.discovery.workflow import discover
from aeromag_env.flight.data import Flight
from aeromag_env.geo.earth import igrf_ned_along_track
from aeromag_env.geo.frames import dcm_from_euler, nav_to_body, time_derivative
from aeromag_env.simulation.config import preset, with_overrides
from aeromag_env.simulation.simulate import simulate_flight

PRESETS = ("nominal", "nominal", "paper", "noise_free")  # half the flights nominal
DURATIONS_S = (1500.0, 2100.0, 3000.0)
SEED0 = 60_000
#: The effect a nominal flight really carries (its external variation across the main field).
PRESENT_IN_NOMINAL = "external_field_variation"


def unmodelled_external(flight: Flight) -> np.ndarray:
    """(n, 3) body-frame field the base model lacks: the true Earth field minus IGRF along the
    track plus ``diurnal`` along the main field (the workflow's model Earth field) [nT]."""
    lat, lon, alt = flight.position_rad()
    earth_n = igrf_ned_along_track(flight.tt, lat, lon, np.asarray(alt, float), flight.date(), 10.0)
    unit = earth_n / np.linalg.norm(earth_n, axis=1, keepdims=True)
    diurnal = flight["diurnal"] if "diurnal" in flight else np.zeros(flight.n)
    model = nav_to_body(dcm_from_euler(*flight.attitude_rad()), earth_n + unit * diurnal[:, None])
    return flight.vector("truth_earth") - model


def run(case: tuple[str, int, float]) -> dict[str, Any]:
    name, seed, duration = case
    cfg = with_overrides(
        preset(name),
        {"trajectory.pattern": "calibration+survey", "trajectory.duration_s": duration},
    )
    flight = simulate_flight(cfg, seed)
    t_b = flight.vector("truth_earth")
    span = BaseSpan(
        base_columns(t_b, time_derivative(t_b, flight.tt, "central")), np.ones(flight.n, bool)
    )
    extra = unmodelled_external(flight)
    rms = float(np.sqrt(np.mean(span.perp(extra[:, :, None]) ** 2)))
    sigma = math.hypot(cfg.fluxgate_noise.white_std_nt, cfg.fluxgate_noise.fogm_std_nt)
    start = time.perf_counter()
    try:
        found = discover(flight).report
    except Exception as exc:  # a refusal is recorded, not a crash of the experiment
        return {"preset": name, "seed": seed, "duration_s": duration, "error": str(exc)}
    named = [e["name"] for e in found["missing_effects"]]
    return {
        "preset": name,
        "seed": seed,
        "duration_s": duration,
        "identifiable_rms_nt": rms,
        "snr": rms / sigma if sigma > 0 else math.inf,
        "named": named,
        "seconds": time.perf_counter() - start,
        "false_alarm": any(n != PRESENT_IN_NOMINAL or name != "nominal" for n in named),
        "gap_before_nt": found["gap"]["rms_before_nt"],
        "gap_after_nt": found["gap"]["rms_after_nt"],
    }


def summary(rows: list[dict[str, Any]]) -> str:
    ok = [r for r in rows if "error" not in r]
    k = sum(r["false_alarm"] for r in ok)
    lo, hi = wilson(k, len(ok))
    counts = ", ".join(f"{p} {sum(r['preset'] == p for r in rows)}" for p in dict.fromkeys(PRESETS))
    lines = [
        f"flights: {len(rows)} ({counts}); refused: {len(rows) - len(ok)}",
        f"false alarms (an effect the flight does not carry): {k}/{len(ok)} = "
        f"{k / max(len(ok), 1):.0%} (95 % CI {lo:.0%}–{hi:.0%})",
        f"any effect named: {sum(bool(r['named']) for r in ok)}/{len(ok)}",
    ]
    nominal = [r for r in ok if r["preset"] == "nominal"]
    for lo_snr, hi_snr in ((0.0, 1.0), (1.0, 2.0), (2.0, math.inf)):
        cell = [r for r in nominal if lo_snr <= r["snr"] < hi_snr]
        hits = sum(PRESENT_IN_NOMINAL in r["named"] for r in cell)
        lines.append(
            f"nominal, external across the main field at SNR {lo_snr:g}–{hi_snr:g}: "
            f"named {hits}/{len(cell)}"
        )
    secs = [r["seconds"] / r["duration_s"] * 3600.0 for r in ok]
    lines.append(
        f"discover: median {np.median(secs):.1f} s per flight-hour (workflow only, no figures)"
    )
    return "\n".join(f"* {line}" for line in lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--flights", type=int, default=48)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", type=Path, default=Path("docs/discovery"))
    args = ap.parse_args()
    cases = [
        (PRESETS[i % len(PRESETS)], SEED0 + i, DURATIONS_S[(i // len(PRESETS)) % 3])
        for i in range(args.flights)
    ]
    with Pool(args.jobs) as pool:
        rows = pool.map(run, cases, chunksize=1)
    args.out.mkdir(parents=True, exist_ok=True)
    write_text(args.out / "nominal.json", json.dumps(rows, indent=1))
    text = summary(rows)
    write_text(args.out / "nominal.md", text)
    print(text)


if __name__ == "__main__":
    main()
