"""How fast and how lean ``aeromag stream`` is: latency per sample and memory over a long stream.

:func:`bench_stream` feeds the stream job (:func:`aeromag_env.jobs.stream.stream`) of a
calibrated model with CSV lines of a simulated survey flight repeated (times shifted) for
``hours`` of flight at its sample rate, generated on the fly (nothing of the stream's length is
held), once with a Tolles–Lawson model and once with a Kalman filter's, and measures:

* the latency per sample: the wall time from handing a line to the stream to the answer that
  line releases being written, median, 99th percentile and largest over every sample [µs]; and
  the processor time of the same span (``cpu_us``: the stream's own work, without the time the
  machine gave other processes, which on a loaded machine makes most of the wall time's tail).
  In real time an answer also waits for the samples after it that its checks read: two sample
  intervals for Tolles–Lawson (0.2 s at 10 Hz), one for a filter (``lookahead_samples``);
* the garbage collector's full (generation 2) collections during the stream and the longest
  [ms] (a full collection walks every object of the process: the stream's tail if any);
* the resident set size of the process every simulated hour [MiB]: flat when the stream's
  memory per sample is bounded (``growth_mib``: last hour's minus the first's).

The figures are ``stream_<method>_…`` in ``bench.json``; :func:`stream_rows` gives the table's
rows.
"""

from __future__ import annotations

import dataclasses
import gc
import io
import os
import time
from collections.abc import Iterator
from typing import Any

import numpy as np

from aeromag_env.compensation.model_fit import fit_model
from aeromag_env.flight.data import Flight
from aeromag_env.jobs.bench.table import Row
from aeromag_env.jobs.stream import stream
from aeromag_env.simulation.config import AircraftConfig, preset, with_overrides
from aeromag_env.simulation.simulate import simulate_flight

#: Hours of samples a full run streams per model (quick: :data:`QUICK_HOURS`).
HOURS = 10.0
QUICK_HOURS = 0.05
#: The models streamed, and the samples each holds back before it answers one.
METHODS = {"tl": 2, "kf": 1}


class _TimedOut(io.StringIO):
    """An output that records, per line written, the wall and processor time since the last line
    was handed to the stream, into arrays allocated up front, and drops the text (nothing
    grows)."""

    def __init__(self, lines: int) -> None:
        super().__init__()
        # written now: untouched pages would join the RSS as the stream fills them
        self.wall_s = np.full(lines, np.nan)
        self.cpu_s = np.full(lines, np.nan)
        self.count = 0
        self.sent = 0.0
        self.sent_cpu = 0.0

    def hand_over(self) -> None:
        """A line is handed to the stream now."""
        self.sent, self.sent_cpu = time.perf_counter(), time.thread_time()

    def write(self, s: str) -> int:
        self.wall_s[self.count] = time.perf_counter() - self.sent
        self.cpu_s[self.count] = time.thread_time() - self.sent_cpu
        self.count += 1
        return len(s)


class _FullCollections:
    """The garbage collector's generation-2 collections while it is installed, and their
    longest [s]."""

    def __init__(self) -> None:
        self.count, self.longest_s, self._start = 0, 0.0, 0.0

    def __call__(self, phase: str, info: dict[str, Any]) -> None:
        if info.get("generation") != 2:
            return
        if phase == "start":
            self._start = time.perf_counter()
        else:
            self.count += 1
            self.longest_s = max(self.longest_s, time.perf_counter() - self._start)


def rss_mib() -> float:
    """The process's resident set size [MiB] (Linux ``/proc``; NaN elsewhere)."""
    try:
        with open("/proc/self/statm") as fh:
            pages = int(fh.read().split()[1])
    except (OSError, ValueError, IndexError):
        return float("nan")
    return pages * os.sysconf("SC_PAGE_SIZE") / 2**20


def bench_stream(hours: float = HOURS, seed: int = 0) -> dict[str, Any]:
    """Latency per sample and memory of the stream job over ``hours`` of 10 Hz samples, for a
    Tolles–Lawson and a Kalman filter model calibrated on one aircraft's box.

    Returns
    -------
    dict
        Per method ``m`` of :data:`METHODS`: ``stream_m_samples``, ``stream_m_latency_us``
        (``median``, ``p99``, ``max``), ``stream_m_rss_mib`` (one per hour),
        ``stream_m_growth_mib``, ``stream_m_lookahead_samples``; and ``stream_hours``.
    """
    base = preset("nominal")
    plane = AircraftConfig(seed=seed)
    cal = simulate_flight(dataclasses.replace(base, aircraft=plane), 2 * seed)
    survey_cfg = with_overrides(
        base, {"trajectory.pattern": "survey", "trajectory.duration_s": 600}
    )
    survey = simulate_flight(dataclasses.replace(survey_cfg, aircraft=plane), 2 * seed + 1)
    figures: dict[str, Any] = {"stream_hours": hours}
    for method, lookahead in METHODS.items():
        scalar = "mag_1_uc" if method == "tl" else None
        model, _ = fit_model(cal, method, flux="flux_a", scalar=scalar)
        figures |= _one(model, survey, hours, f"stream_{method}")
        figures[f"stream_{method}_lookahead_samples"] = lookahead
    return figures


def _one(model: Any, survey: Flight, hours: float, prefix: str) -> dict[str, Any]:
    """The figures of one model's stream."""
    columns = model.stream(header=survey.names).columns
    n_total = round(hours * 3600 * survey.sample_rate_hz)
    out = _TimedOut(n_total + 1)
    rss: list[float] = []
    lines = _lines(survey, columns, n_total, out, rss)
    full = _FullCollections()
    gc.callbacks.append(full)
    try:
        stream(model, lines, out, date=survey.date().isoformat(), warn=lambda _m: None)
    finally:
        gc.callbacks.remove(full)
    wall, cpu = (a[1 : out.count] * 1e6 for a in (out.wall_s, out.cpu_s))  # write 0: the header
    return {
        f"{prefix}_samples": n_total,
        f"{prefix}_answered": int(out.count - 1),
        f"{prefix}_latency_us": _spread(wall),
        f"{prefix}_cpu_us": _spread(cpu),
        f"{prefix}_full_collections": full.count,
        f"{prefix}_longest_full_collection_ms": 1e3 * full.longest_s,
        f"{prefix}_rss_mib": rss,
        f"{prefix}_growth_mib": float(rss[-1] - rss[0]) if rss else None,
    }


def _spread(x: np.ndarray) -> dict[str, float]:
    """Median, 99th percentile and largest of ``x``."""
    return {
        "median": float(np.median(x)),
        "p99": float(np.percentile(x, 99)),
        "max": float(x.max()),
    }


def _lines(
    survey: Flight, columns: tuple[str, ...], n_total: int, out: _TimedOut, rss: list[float]
) -> Iterator[str]:
    """The header, then ``n_total`` sample lines of ``survey`` repeated with shifted times,
    telling ``out`` when each is handed over, and the RSS every hour."""
    tt = survey.tt
    table = np.column_stack([survey[c] for c in columns[1:]])
    n, dt = tt.size, float(np.median(np.diff(tt)))
    per_hour = round(3600 / dt)
    yield ",".join(columns) + "\n"
    for k in range(n_total):
        if k % per_hour == 0:
            rss.append(rss_mib())
        row = ",".join(map(repr, (float(tt[0] + k * dt), *table[k % n].tolist())))
        out.hand_over()
        yield row + "\n"
    rss.append(rss_mib())


def stream_rows(f: dict[str, Any]) -> list[Row]:
    """The table's rows: per model, the latency (median, with its 99th percentile, the
    processor time's and the waits) and the memory growth over the stream, with their targets
    (the 99th percentile within one 10 Hz sample interval: the stream keeps up; memory flat
    within 1 MiB)."""
    out: list[Row] = []
    hours = f.get("stream_hours")
    for method in METHODS:
        lat = f.get(f"stream_{method}_latency_us")
        if lat is None:
            continue
        cpu, growth = f[f"stream_{method}_cpu_us"], f[f"stream_{method}_growth_mib"]
        out.append(
            (
                f"stream {method}, latency per sample",
                f"{lat['median']:,.0f} µs",
                f"p99 {lat['p99']:,.0f} µs (processor {cpu['p99']:,.0f} µs), max "
                f"{lat['max']:,.0f} µs; answers wait {f[f'stream_{method}_lookahead_samples']} "
                "sample(s)",
                "p99 < 100 000 µs",
                lat["p99"] < 100_000,
            )
        )
        out.append(
            (
                f"stream {method}, memory over {hours:g} h",
                f"{growth:+.1f} MiB",
                f"RSS {f[f'stream_{method}_rss_mib'][0]:.0f} MiB at the start; "
                f"{f[f'stream_{method}_full_collections']} full GC collections",
                "flat (±1 MiB)",
                abs(growth) <= 1.0,
            )
        )
    return out
