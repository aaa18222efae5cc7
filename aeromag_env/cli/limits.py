"""The ranges of ``aeromag``'s numeric options, named once, each with why it is where it is.

The handlers of :mod:`aeromag_env.cli.commands` call one ``check_*`` per subcommand before any
work starts; each refusal is a one-line :class:`~aeromag_env.errors.AeromagError` naming the
option, the allowed range and its unit, so no value reaches the simulator, a filter or the
trainer that would crash it, make it divide by zero or run until the memory is gone. Ranges
that depend on the file (a band-pass edge against the file's Nyquist frequency, a trim against
its length) are checked where the file is known (:class:`~aeromag_env.compensation.
tolles_lawson.TollesLawson`, :mod:`aeromag_env.compensation.compensate`).
"""

from __future__ import annotations

import argparse
import math
import os
from collections.abc import Sequence

from aeromag_env.errors import AeromagError
from aeromag_env.simulation.config import SimulationConfig, with_overrides

#: Seeds of every command, ``0 … 2³² − 1``: the range stable-baselines3 (``np.random.seed``)
#: accepts, kept for all commands so that a seed valid for one is valid for every one.
SEED_RANGE = (0, 2**32 - 1)
#: Most ``train --timesteps``: 333 times the shipped policies' 3·10⁶, already days of CPU
#: time at the few thousand steps per second of ``aeromag bench``.
MAX_TIMESTEPS = 10**9
#: Most ``tune --samples``: the best of 1 000 random samples is in the best 0.3 % of the search
#: space with 95 % probability (1 − 0.997¹⁰⁰⁰); more only costs time (a trial is a training run).
MAX_SAMPLES = 1_000
#: Most ``evaluate --episodes``: the paired 95 % intervals narrow as 1/√n, so 10 000 flights
#: give intervals 22 times narrower than the default 20; more only costs time (about 0.1 s
#: per flight and policy).
MAX_EPISODES = 10_000
#: Range of ``compensate --r-std-nt`` [nT]: from a cesium magnetometer's noise floor (1 pT) to
#: above the Earth's whole field (about 65 000 nT); the filters' products of R stay within
#: floating point there (1e-300 divides by zero, 1e300 overflows).
R_STD_RANGE_NT = (1e-3, 1e5)
#: Peak memory of ``simulate`` per field and sample [bytes]: measured 25 (HDF5, MAT) to 73
#: (CSV, XYZ, whose writers build the text rows) for a 10-hour flight; rounded up.
BYTES_PER_VALUE = 80


def check_seed(option: str, value: int) -> None:
    """``option`` (a seed) within :data:`SEED_RANGE`."""
    lo, hi = SEED_RANGE
    if not lo <= value <= hi:
        raise AeromagError(f"{option} must be ≥ {lo} and ≤ {hi} (2³² − 1), got {value}")


def check_window(option: str, window: Sequence[float] | None) -> None:
    """``option`` T0 T1 [s]: finite, T0 < T1 (or absent)."""
    if window is None:
        return
    t0, t1 = window
    if not (math.isfinite(t0) and math.isfinite(t1) and t0 < t1):
        raise AeromagError(f"{option} needs finite times T0 < T1 [s], got {t0:g} {t1:g}")


def check_compensate(args: argparse.Namespace) -> None:
    """``compensate``'s filter noise, TL ridge and trim, and calibration window."""
    lo, hi = R_STD_RANGE_NT
    r = args.r_std_nt
    if r is not None and not (math.isfinite(r) and lo <= r <= hi):
        raise AeromagError(
            f"--r-std-nt must be in [{lo:g}, {hi:g}] nT (a magnetometer's noise floor to above "
            f"the Earth's field), got {r:g}"
        )
    if not (math.isfinite(args.tl_ridge) and args.tl_ridge >= 0):
        raise AeromagError(
            f"--tl-ridge must be ≥ 0 and finite (λ, unitless), got {args.tl_ridge:g}"
        )
    if args.tl_trim < 0:
        raise AeromagError(f"--tl-trim must be ≥ 0 samples, got {args.tl_trim}")
    check_window("--calibration-window", args.calibration_window)


def check_train(args: argparse.Namespace) -> None:
    """``train``'s seed and timesteps."""
    check_seed("--seed", args.seed)
    if args.timesteps is not None and not 1 <= args.timesteps <= MAX_TIMESTEPS:
        raise AeromagError(
            f"--timesteps must be in [1, {MAX_TIMESTEPS:.0e}] environment steps (10⁹ is 333× "
            f"the shipped policies' 3e6 and days of CPU time), got {args.timesteps}"
        )


def check_tune(args: argparse.Namespace) -> None:
    """``tune``'s seed, timesteps per trial and samples."""
    check_train(args)
    if args.samples is not None and not 1 <= args.samples <= MAX_SAMPLES:
        raise AeromagError(
            f"--samples must be in [1, {MAX_SAMPLES}] trials (the best of 1000 random samples "
            f"is in the best 0.3 % of the space with 95 % probability), got {args.samples}"
        )


def check_evaluate(args: argparse.Namespace) -> None:
    """``evaluate``'s episode count and first seed (its seeds stay within :data:`SEED_RANGE`)."""
    if not 1 <= args.episodes <= MAX_EPISODES:
        raise AeromagError(
            f"--episodes must be in [1, {MAX_EPISODES}] flights (the 95 % intervals narrow as "
            f"1/√n; more only costs time), got {args.episodes}"
        )
    from agents.evaluate import TEST_SEED_START  # lazily: agents only when the command runs

    hi = SEED_RANGE[1] - args.episodes + 1
    if not TEST_SEED_START <= args.seed_start <= hi:
        raise AeromagError(
            f"--seed-start must be in [{TEST_SEED_START}, {hi}] with --episodes "
            f"{args.episodes} (training and validation use the seeds below {TEST_SEED_START}; "
            f"seeds end at 2³² − 1), got {args.seed_start}"
        )


def check_simulation(cfg: SimulationConfig, replay: bool) -> None:
    """Refuse a simulated flight that would not fit in the memory available now.

    The peak is :data:`BYTES_PER_VALUE` per field and sample; the field count comes from a
    two-sample simulation of the same configuration. A replayed flight has the replayed
    file's length (already read), and a pattern without ``duration_s`` its own (minutes).
    """
    traj = cfg.trajectory
    if replay or traj.duration_s is None:
        return
    available = available_memory_bytes()
    if available is None:
        return
    from aeromag_env.simulation.simulate import simulate_flight

    probe = with_overrides(cfg, {"trajectory.duration_s": 2.0 / traj.sample_rate_hz})
    per_sample = BYTES_PER_VALUE * len(simulate_flight(probe, 0).names)
    samples = round(traj.duration_s * traj.sample_rate_hz)
    if samples * per_sample > available:
        largest = available // per_sample / traj.sample_rate_hz
        raise AeromagError(
            f"--duration-s {traj.duration_s:g} s needs about {samples * per_sample / 1e9:.3g} GB "
            f"({samples} samples × {per_sample} bytes) but {available / 1e9:.3g} GB of memory is "
            f"available: the largest duration here is {largest:.0f} s"
        )


def available_memory_bytes() -> int | None:
    """Memory available to a new allocation now [bytes] (Linux ``MemAvailable``, else free
    physical pages), or None where the system does not say."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, ValueError, OSError):
        return None
