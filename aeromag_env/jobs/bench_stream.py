"""How fast and how lean ``aeromag stream`` is: latency per sample and memory over a long stream.

:func:`bench_stream` feeds a calibrated Tolles–Lawson model's stream
(:func:`aeromag_env.jobs.stream.stream`) with CSV lines of a simulated survey flight repeated
(times shifted) for ``hours`` of flight at its sample rate, generated on the fly (nothing of
the stream's length is held), and measures:

* the latency per sample: the wall time from handing a line to the stream to the answer that
  line releases (a Tolles–Lawson stream answers sample k when k + 2 arrives: in real time the
  answer comes those two sample intervals, 0.2 s at 10 Hz, after the sample), median and 99th
  percentile over every sample [µs];
* the resident set size of the process every simulated hour [MiB]: flat when the stream's
  memory per sample is bounded.

This is the function ``aeromag bench`` calls for its streaming row.
"""

from __future__ import annotations

import dataclasses
import io
import time
from collections.abc import Iterator
from typing import Any

import numpy as np

from aeromag_env.compensation.model_fit import fit_model
from aeromag_env.jobs.stream import stream
from aeromag_env.simulation.config import AircraftConfig, preset, with_overrides
from aeromag_env.simulation.simulate import simulate_flight


class _TimedOut(io.StringIO):
    """An output that records when each line is written, into an array allocated up front,
    and drops the text (nothing grows while the stream runs)."""

    def __init__(self, lines: int) -> None:
        super().__init__()
        self.stamps = np.full(lines, np.nan)
        self.count = 0

    def write(self, s: str) -> int:
        self.stamps[self.count] = time.perf_counter()
        self.count += 1
        return len(s)


def _rss_mib() -> float:
    """The process's resident set size [MiB] (Linux ``/proc``; NaN elsewhere)."""
    try:
        with open("/proc/self/statm") as fh:
            pages = int(fh.read().split()[1])
    except (OSError, ValueError, IndexError):
        return float("nan")
    import os

    return pages * os.sysconf("SC_PAGE_SIZE") / 2**20


def bench_stream(hours: float = 10.0, seed: int = 0) -> dict[str, Any]:
    """Latency per sample and memory of a Tolles–Lawson stream over ``hours`` of 10 Hz samples.

    Returns
    -------
    dict
        ``samples``, ``latency_us`` (``median``, ``p99``), ``rss_mib`` (one per hour, and
        ``growth_mib`` from the first hour to the last), ``hours``.
    """
    base = preset("nominal")
    plane = AircraftConfig(seed=seed)
    cal = simulate_flight(dataclasses.replace(base, aircraft=plane), 2 * seed)
    survey_cfg = with_overrides(
        base, {"trajectory.pattern": "survey", "trajectory.duration_s": 600}
    )
    survey = simulate_flight(dataclasses.replace(survey_cfg, aircraft=plane), 2 * seed + 1)
    model, _ = fit_model(cal, "tl", flux="flux_a", scalar="mag_1_uc")
    n_total = int(hours * 3600 * survey.sample_rate_hz)
    sent = np.full(n_total, np.nan)  # touched now: its pages do not grow the RSS later
    rss: list[float] = []
    lines = _lines(survey, n_total, sent, rss)
    out = _TimedOut(n_total + 1)
    stream(model, lines, out, lambda _m: None)
    # write 0 is the header; write j + 1 answers sample j, released by sample j + 2
    released = out.stamps[1 : n_total - 1]
    latency = (released - sent[2:n_total]) * 1e6
    return {
        "hours": hours,
        "samples": int(n_total),
        "latency_us": {
            "median": float(np.median(latency)),
            "p99": float(np.percentile(latency, 99)),
        },
        "rss_mib": rss,
        "growth_mib": float(rss[-1] - rss[0]) if rss else None,
    }


def _lines(survey: Any, n_total: int, sent: np.ndarray, rss: list[float]) -> Iterator[str]:
    """The header, then ``n_total`` sample lines of ``survey`` repeated with shifted times,
    recording when each is handed over (``sent``) and the RSS every hour."""
    tt, flux, scalar = survey.tt, survey.vector("flux_a"), survey["mag_1_uc"]
    n, dt = tt.size, float(np.median(np.diff(tt)))
    per_hour = round(3600 / dt)
    yield "tt,flux_a_x,flux_a_y,flux_a_z,mag_1_uc\n"
    for k in range(n_total):
        i = k % n
        t = tt[0] + k * dt
        if k % per_hour == 0:
            rss.append(_rss_mib())
        sent[k] = time.perf_counter()
        # the answer to sample k comes when k + 2 is handed over: its latency runs from then
        row = (float(t), *map(float, flux[i]), float(scalar[i]))
        yield ",".join(map(repr, row)) + "\n"
    rss.append(_rss_mib())
