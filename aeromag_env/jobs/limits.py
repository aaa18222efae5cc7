"""The ranges of the jobs' numeric arguments, named once, each with why it is where it is.

Every job's request (:mod:`aeromag_env.jobs`) checks its arguments with these before any work
starts; each refusal is one :class:`~aeromag_env.errors.ArgumentError` naming the argument as
the library spells it, the allowed range and its unit (the command line says the same with its
option's name), so no value reaches the simulator, a filter or the trainer that would crash it,
make it divide by zero or run until the memory is gone. Ranges that depend on the file (a
band-pass edge against the file's Nyquist frequency, a trim against its length) are checked
where the file is known (:class:`~aeromag_env.compensation.tolles_lawson.TollesLawson`,
:mod:`aeromag_env.compensation.compensate`).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence

from aeromag_env.errors import ArgumentError

#: Seeds of every job, ``0 … 2³² − 1``: the range stable-baselines3 (``np.random.seed``)
#: accepts, kept for all jobs so that a seed valid for one is valid for every one.
SEED_RANGE = (0, 2**32 - 1)
#: Most training ``timesteps``: 333 times the shipped policies' 3·10⁶, already days of CPU
#: time at the few thousand steps per second of ``aeromag bench``.
MAX_TIMESTEPS = 10**9
#: Most search ``samples``: the best of 1 000 random samples is in the best 0.3 % of the search
#: space with 95 % probability (1 − 0.997¹⁰⁰⁰); more only costs time (a trial is a training run).
MAX_SAMPLES = 1_000
#: Most evaluation ``episodes``: the paired 95 % intervals narrow as 1/√n, so 10 000 flights
#: give intervals 22 times narrower than the default 20; more only costs time (about 0.1 s
#: per flight and policy).
MAX_EPISODES = 10_000
#: The most training runs one request may ask for (one per seed).
MAX_SEEDS = 1000
#: Range of a filter's measurement-noise std ``r_std_nt`` [nT]: from a cesium magnetometer's
#: noise floor (1 pT) to above the Earth's whole field (about 65 000 nT); the filters' products
#: of R stay within floating point there (1e-300 divides by zero, 1e300 overflows).
R_STD_RANGE_NT = (1e-3, 1e5)
#: Most Tolles–Lawson trim [samples] at each end of each run: 10⁶ samples is 28 hours at 10 Hz;
#: a trim beyond a run's length is refused where the file is known.
MAX_TL_TRIM = 10**6
#: Largest maintenance shift of an aircraft's permanent field, per axis [nT]: above the Earth's
#: whole field (about 65 000 nT); aircraft permanent fields are hundreds to a few thousand nT.
MAX_PERMANENT_SHIFT_NT = 1e5
#: Peak memory of ``simulate`` per field and sample [bytes]: measured 25 (HDF5, MAT) to 73
#: (CSV, XYZ, whose writers build the text rows) for a 10-hour flight; rounded up.
BYTES_PER_VALUE = 80


def check_seed(argument: str, value: int) -> None:
    """``argument`` (a seed) an integer within :data:`SEED_RANGE`."""
    lo, hi = SEED_RANGE
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise ArgumentError(argument, f"must be ≥ {lo} and ≤ {hi} (2³² − 1)", value)


def check_count(argument: str, value: int, low: int, high: int, unit: str, why: str = "") -> None:
    """``argument`` an integer in [low, high] ``unit``; ``why`` says where the bound comes from."""
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        reason = f" ({why})" if why else ""
        top = f"{high:.0e}" if high >= 10**8 and high % 10**8 == 0 else str(high)
        raise ArgumentError(argument, f"must be in [{low}, {top}] {unit}{reason}", value)


def check_number(
    argument: str, value: float, low: float, high: float, unit: str, why: str = ""
) -> None:
    """``argument`` a finite number in [low, high] ``unit``."""
    if not (isinstance(value, int | float) and math.isfinite(value) and low <= value <= high):
        reason = f" ({why})" if why else ""
        raise ArgumentError(argument, f"must be in [{low:g}, {high:g}] {unit}{reason}", value)


def check_vector(
    argument: str, values: Sequence[float], low: float, high: float, unit: str, why: str = ""
) -> None:
    """``argument`` three finite numbers, each in [low, high] ``unit``."""
    ok = len(values) == 3 and all(
        isinstance(v, int | float)
        and not isinstance(v, bool)
        and math.isfinite(v)
        and low <= v <= high
        for v in values
    )
    if not ok:
        reason = f" ({why})" if why else ""
        raise ArgumentError(
            argument, f"needs three numbers in [{low:g}, {high:g}] {unit}{reason}", tuple(values)
        )


def check_nonnegative(argument: str, value: float, unit: str) -> None:
    """``argument`` a finite number ≥ 0 ``unit``."""
    if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
        raise ArgumentError(argument, f"must be ≥ 0 and finite {unit}", value)


def check_window(argument: str, window: Sequence[float] | None) -> None:
    """``argument`` T0 T1 [s]: finite, T0 < T1 (or absent)."""
    if window is None:
        return
    if len(window) != 2:
        raise ArgumentError(argument, "needs two times T0 T1 [s]", tuple(window))
    t0, t1 = window
    if not (math.isfinite(t0) and math.isfinite(t1) and t0 < t1):
        raise ArgumentError(argument, "needs finite times T0 < T1 [s]", (t0, t1))


def check_bandpass(argument: str, band: Sequence[float] | None) -> None:
    """``argument`` LOW, HIGH [Hz]: finite, 0 ≤ LOW < HIGH (or absent: no band-pass). HIGH
    against the file's Nyquist frequency is checked where the file is known."""
    if band is None:
        return
    if (
        len(band) != 2
        or not all(isinstance(v, int | float) and math.isfinite(v) for v in band)
        or not 0 <= band[0] < band[1]
    ):
        raise ArgumentError(argument, "needs 0 ≤ LOW < HIGH [Hz], both finite", tuple(band))


def check_lines(argument: str, lines: Sequence[float] | None) -> None:
    """``argument`` (flight line ids): at least one, all finite (or absent)."""
    if lines is None:
        return
    if len(lines) == 0 or not all(isinstance(v, int | float) and math.isfinite(v) for v in lines):
        raise ArgumentError(argument, "needs one or more finite line ids", tuple(lines))


def check_calibration_line(argument: str, line: str | None) -> None:
    """``argument``: ``auto``, a finite line id (as text, e.g. ``"1001"``) or None."""
    if line is None or line == "auto":
        return
    try:
        ok = math.isfinite(float(line))
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ArgumentError(argument, "takes one finite line id, or auto", line)


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
