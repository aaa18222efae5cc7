"""Faults in the data itself through each recursive filter: the README's table of what the
consistency checks (:mod:`aeromag_env.compensation.consistency`) do.

One 600-s nominal calibration flight (seed 7, 6000 samples at 10 Hz); ``y = T_m − T`` from its
``flux_a`` fed to the filter directly, as the environment does, with one fault added at the middle:
a 1e6 nT spike in one component, a 60-s burst of 1e3 nT RMS white noise on all three, a 1e4 nT
step (a permanent-field jump; the truth steps too) and 1e3 nT RMS noise over the whole flight.
Each cell is the RMS of the a-priori estimate minus the true interference over the second half
of the flight [nT] (from 60 s after the step for the step), then the filter's counters: outliers
rejected / divergences (restarts). Run at a commit without the counters it prints ``–``.

Usage::

    python experiments/filter_faults.py [--quick]

About 2 minutes on these 2-core machines under load (measured); ``--quick`` flies a 300-s flight
through ``kf`` and ``fakf`` only.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np

if __package__ in (None, ""):  # run by its path, from anywhere: this checkout's packages first
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from aeromag_env.compensation.compensate import earth_model
from aeromag_env.compensation.kalman import run_filter
from aeromag_env.compensation.model import METHODS, FilterConfig
from aeromag_env.quick import add_quick_option
from aeromag_env.simulation.config import preset, with_overrides
from aeromag_env.simulation.simulate import simulate_flight

SEED, DURATION_S = 7, 600.0
SPIKE_NT, NOISE_RMS_NT, BURST_SAMPLES, STEP_NT = 1e6, 1e3, 600, 1e4
#: Samples after the step before it is scored: the restart's convergence [samples].
AFTER_STEP = 600


def faults(y: np.ndarray, truth: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray, int]]:
    """Each fault: the faulty ``y``, the truth it should be tracked against, the first scored
    sample."""
    n, k = y.shape[0], y.shape[0] // 2
    noise = np.random.default_rng(1).standard_normal(y.shape) * NOISE_RMS_NT
    spike, burst, step, noisy = y.copy(), y.copy(), y.copy(), y + noise
    spike[k, 0] += SPIKE_NT
    burst[k : k + BURST_SAMPLES] += noise[:BURST_SAMPLES]
    step[k:, 0] += STEP_NT
    stepped = truth.copy()
    stepped[k:, 0] += STEP_NT
    return {
        "clean": (y, truth, k),
        "1e6 nT spike": (spike, truth, k),
        "60-s 1e3 nT noise burst": (burst, truth, k),
        "1e4 nT step": (step, stepped, min(k + AFTER_STEP, n - 1)),
        "1e3 nT noise, whole flight": (noisy, truth, k),
    }


#: ``--quick``'s flight [s] and methods.
QUICK_DURATION_S, QUICK_METHODS = 300.0, ("kf", "fakf")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    add_quick_option(parser, "a 300-s flight, kf and fakf")
    args = parser.parse_args(argv)
    duration_s, methods = (QUICK_DURATION_S, QUICK_METHODS) if args.quick else (DURATION_S, METHODS)
    cfg = with_overrides(preset("nominal"), {"trajectory.duration_s": duration_s})
    flight = simulate_flight(cfg, SEED)
    t_b, tdot_b = earth_model(flight, "backward")
    y, truth = flight.vector("flux_a") - t_b, flight.vector("truth_interf")
    cases = faults(y, truth)
    print("| fault | " + " | ".join(methods) + " |")
    print("|---|" + "---:|" * len(methods))
    for name, (y_f, truth_f, first) in cases.items():
        cells = []
        for method in methods:
            res = run_filter(replace(FilterConfig(), method=method), y_f, t_b, tdot_b)
            err = res.interference[first:] - truth_f[first:]
            rmse = float(np.sqrt(np.mean(err**2)))
            rejected = getattr(res, "outliers_rejected", None)
            counters = "–" if rejected is None else f"{rejected} / {res.divergences}"
            cells.append(f"{rmse:.3g} ({counters})")
        print(f"| {name} | " + " | ".join(cells) + " |")
    print(
        f"\nRMS error of the estimate over the second half [nT] (outliers rejected / "
        f"divergences); {duration_s:.0f}-s nominal flight, seed {SEED}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
