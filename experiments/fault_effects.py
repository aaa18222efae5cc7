"""What a time gap, a spike and missing attitude do to each compensator (README, "Gaps, spikes
and NaN in compensation").

A nominal calibration box (seed 3, 900 s by default) is compensated clean and with one fault at a
time: 30 s of samples deleted at 400–430 s; +1e6 nT at sample 5000 of the scalar ``mag_1_uc``;
the same on the fluxgate axis ``flux_a_y``; NaN ``ins_pitch`` at samples 3000, 3001 and 6000.
Each cell is ``score(...)["compensation_rmse_nt"]`` (RMSE of the interference estimate against
the simulator's truth over the second half [nT]); the count of NaN outputs follows in brackets.

Usage::

    python experiments/fault_effects.py [--duration-s 900] [--methods tl,lsq,kf,fakf] [--quick]

``--quick``: the methods ``tl`` and ``kf`` only.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aeromag_env.compensation.compensate import compensate_scalar, compensate_vector, score
from aeromag_env.compensation.tolles_lawson import TollesLawson
from aeromag_env.flight.data import Flight
from aeromag_env.quick import add_quick_option
from aeromag_env.simulation.config import preset, with_overrides
from aeromag_env.simulation.simulate import simulate_flight

SEED = 3


def _edited(flight: Flight, keep: np.ndarray | None = None, **changes: tuple) -> Flight:
    """A copy of ``flight`` with ``changes`` (name → (index, value added)) and ``keep``."""
    fields = {k: v.copy() for k, v in flight.fields.items()}
    for name, (index, value) in changes.items():
        fields[name][index] += value
    if keep is not None:
        fields = {k: v[keep] for k, v in fields.items()}
    return Flight(fields, dict(flight.attrs))


def variants(duration_s: float) -> dict[str, Flight]:
    """The clean box and its four faulty copies (module docstring)."""
    cfg = with_overrides(
        preset("nominal"),
        {"trajectory.pattern": "calibration", "trajectory.duration_s": duration_s},
    )
    clean = simulate_flight(cfg, rng=SEED)
    nan_attitude = _edited(clean, ins_pitch=(np.array([3000, 3001, 6000]), np.nan))
    return {
        "clean": clean,
        "gap 30 s": _edited(clean, keep=(clean.tt < 400.0) | (clean.tt >= 430.0)),
        "scalar spike": _edited(clean, mag_1_uc=(5000, 1e6)),
        "fluxgate spike": _edited(clean, flux_a_y=(5000, 1e6)),
        "NaN attitude": nan_attitude,
    }


def cell(flight: Flight, method: str) -> str:
    """RMSE [nT] and the NaN outputs of one method on one flight."""
    if method == "tl":
        comp = compensate_scalar(flight, "flux_a", "mag_1_uc", TollesLawson())
    else:
        comp = compensate_vector(flight, method)
    rmse = score(flight, comp)["compensation_rmse_nt"]
    nan = int(np.sum(~np.isfinite(comp.total_after)))
    return f"{rmse:.4g} ({nan} NaN)"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration-s", type=float, default=900.0, help="box length [s]")
    parser.add_argument("--methods", default="tl,lsq,kf,fakf", help="comma-separated methods")
    add_quick_option(parser, "the methods tl and kf only")
    args = parser.parse_args(argv)
    methods = "tl,kf" if args.quick else args.methods
    flights = variants(args.duration_s)
    print("| method | " + " | ".join(flights) + " |")
    print("|---" * (len(flights) + 1) + "|")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the faults are warned about; here they are the point
        for method in methods.split(","):
            cells = [cell(f, method) for f in flights.values()]
            print(f"| {method} | " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
