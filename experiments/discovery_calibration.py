"""The calibration of discovery's joint-test penalty (``evidence.JOINT_PENALTY``).

Runs ``discover`` on development flights (seeds the hidden-effect suite and the plain-flight
experiment never use) and prints, for every slow group the joint noise-model test re-tested, its
likelihood ratio per degree of freedom: on null flights (the suite's nominal noise and its
coloured noises) for the spurious groups that passed Holm, and on flights with a weak true effect
(a temperature drift at SNR 0.5 and 1, an external field at SNR 1, the nominal preset's own
external variation) for the true group. The penalty goes between the two.

Run: ``python experiments/discovery_calibration.py [--jobs 2] [--quick]`` (68 flights, about
2 minutes on these 2-core machines; ``--quick``: 3 of them). It prints; it writes nothing.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from multiprocessing import Pool
from pathlib import Path
from typing import Any

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aeromag_env.discovery.suite import COLOURED_NOISE, Case, build_case
from aeromag_env.discovery.workflow import discover
from aeromag_env.quick import add_quick_option
from aeromag_env.simulation.config import preset, with_overrides
from aeromag_env.simulation.simulate import simulate_flight

#: (kind, seed, effect, SNR) of the development flights.
FLIGHTS = (
    [("null", 90_000 + s, None, None) for s in range(30)]
    + [("coloured", 90_600 + s, None, None) for s in range(16)]
    + [("single", 92_000 + s, "permanent_field_drift", 1.0) for s in range(6)]
    + [("single", 92_100 + s, "external_field_variation", 1.0) for s in range(6)]
    + [("single", 92_200 + s, "permanent_field_drift", 0.5) for s in range(4)]
    + [("nominal", 50_000 + s, None, None) for s in (0, 1, 4, 5, 8, 9)]
)


def run(spec: tuple[str, int, str | None, float | None]) -> dict[str, Any]:
    kind, seed, effect, snr = spec
    if kind == "nominal":  # its external variation across the main field is the true effect
        cfg = with_overrides(
            preset("nominal"),
            {"trajectory.pattern": "calibration+survey", "trajectory.duration_s": 2100.0},
        )
        truth = ["external_field_variation"]
    else:
        noise = COLOURED_NOISE[seed % len(COLOURED_NOISE)] if kind == "coloured" else None
        case_kind = "single" if effect else ("coloured_null" if noise else "null")
        cfg, _ = build_case(Case(case_kind, seed, (effect,) if effect else (), snr, noise=noise))
        truth = [effect] if effect else []
    report = discover(simulate_flight(cfg, seed)).report
    joint = [
        {
            "family": fam,
            "lr_per_dof": t["lr_statistic"] / t["dof"],
            "passes_holm": t["p_value"] < step["holm_threshold"],
            "true": fam.split("[")[0] in truth,
        }
        for step in report["selection"]["steps"]
        for fam, t in step["tests"].items()
        if t.get("test") == "joint noise model"
    ]
    return {"kind": kind, "seed": seed, "effect": effect, "snr": snr, "joint": joint}


#: ``--quick``'s flights: the first null, coloured-noise and weak-effect flights.
QUICK = (FLIGHTS[0], FLIGHTS[30], FLIGHTS[46])


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--jobs", type=int, default=2, help="processes")
    add_quick_option(ap, f"{len(QUICK)} flights")
    args = ap.parse_args(argv)
    with Pool(args.jobs) as pool:
        rows = pool.map(run, QUICK if args.quick else FLIGHTS, chunksize=1)
    spurious = sorted(
        t["lr_per_dof"]
        for r in rows
        if r["kind"] in ("null", "coloured")
        for t in r["joint"]
        if t["passes_holm"]
    )
    nulls = sum(r["kind"] in ("null", "coloured") for r in rows)
    print(
        f"null flights: {nulls}; spurious slow groups passing Holm, LR/dof: "
        + ", ".join(f"{v:.1f}" for v in spurious)
    )
    true = [
        max((t["lr_per_dof"] for t in r["joint"] if t["true"]), default=float("nan"))
        for r in rows
        if r["kind"] in ("single", "nominal")
    ]
    print(f"weak true effects: {len(true)}; their LR/dof: {min(true):.1f}–{max(true):.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
