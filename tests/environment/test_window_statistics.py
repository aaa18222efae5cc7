"""The observation statistics read from running sums, against the plain-numpy reference.

The compiled statistics over the filter's window of M read sums kept in O(K) a step
(:mod:`aeromag_env.environment.window_sums`); :mod:`aeromag_env.environment.statistics_reference`
computes each from its definition, afresh, in two passes. The sums are driven here through what
the filter does to its window (updates skipped, rejected, a restart that empties it, a
restart that keeps it, innovations that swing by 100 decades), the sample window over gaps of
skipped samples, and the environment over whole episodes under random and hostile actions.

Tolerances: a running sum loses at most 4 digits to a subtraction before it is summed afresh
(SUM_RATIO = 1e4), over at most a lap of M = 50 terms: relative error below 1e4 · 50 · 1.1e-16
≈ 6e-11 (1e-10 below). A statistic centred from running sums loses at most 4 digits more
(CENTRED_RATIO = 1e4): 1e-6 relative at the very worst; in the episodes below, clean and hostile,
below 1e-9. The observations are float32 log10 of the statistics (whiteness: the value in
[-1, 1]): within one float32 unit in the last place of the reference's, whiteness within 1e-8
absolute (its rounding error is relative to the innovations' spread, not to its value, which
may be near 0).
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import aeromag_env  # noqa: F401  (registers the environment)
from aeromag_env.compensation.kernel_layout import INTS, N_ACC, N_INT
from aeromag_env.compensation.window import window_add
from aeromag_env.environment import statistics as compiled
from aeromag_env.environment import statistics_reference as ref
from aeromag_env.environment.layout import N_RUN, RUN
from aeromag_env.environment.observations import OBS_LIMIT
from aeromag_env.environment.spaces import observation_index
from aeromag_env.environment.window_sums import (
    Taken,
    WindowMark,
    put_updates,
    sample_sums,
    slide_samples,
    take_leaving,
    window_mark,
)

M = 50
#: Relative error of a running sum against fsum of the window (see the module docstring).
SUM_RTOL = 1e-10


def _levels(rng: np.random.Generator, size: int) -> np.ndarray:
    """Per-sample scales [nT] in runs of 1–20 samples, each run at 1e-25, 1, 1e25 or 1..1e3
    (squares 50 decades apart, and a mild spread)."""
    out = np.empty(size)
    k = 0
    while k < size:
        run = int(rng.integers(1, 21))
        kind = rng.integers(4)
        scale = (1e-25, 1.0, 1e25)[kind] if kind < 3 else 10.0 ** rng.uniform(0, 3)
        out[k : k + run] = scale
        k += run
    return out


def _assert_update_sums(ints: np.ndarray, rbuf: np.ndarray, run: np.ndarray, where: str) -> None:
    r = ref.window_updates(ints, rbuf)
    total = math.fsum((r * r).sum(axis=1)) if len(r) else 0.0
    assert run[RUN.win_rr] == pytest.approx(total, rel=SUM_RTOL, abs=0.0), where
    scale = math.sqrt(len(r) * total)  # the sum's own scale: |Σ r| ≤ sqrt(n Σ |r|²)
    for i in range(3):
        want = math.fsum(r[:, i]) if len(r) else 0.0
        assert run[RUN.win_r + i] == pytest.approx(want, rel=SUM_RTOL, abs=SUM_RTOL * scale), where


@pytest.mark.parametrize("seed", range(3))
def test_update_sums_follow_the_filters_window(seed):
    """Σ r and Σ |r|² over the window's updates, kept around steps of K = 1..60 samples of which
    some add no update (skipped or rejected), some steps restart the filter (half of them
    emptying the window), the terms 50 decades apart: within SUM_RTOL of math.fsum at every
    step."""
    from aeromag_env.compensation.consistency import clear_window

    rng = np.random.default_rng(seed)
    rbuf, sbuf = np.zeros((M, 3)), np.zeros(M)
    acc, ints, run = np.zeros(N_ACC), np.zeros(N_INT, np.int64), np.zeros(N_RUN)
    ints[INTS.window] = M
    scales = _levels(rng, 20_000)
    k = 0
    for step in range(600):
        samples = int(rng.choice([1, 5, 10, 10, 10, 49, 60]))
        before = window_mark(ints)
        taken = take_leaving(samples, ints, rbuf, run)
        for _ in range(samples):
            if rng.random() < 0.1:  # skipped or rejected: no update
                continue
            r = rng.standard_normal(3) * scales[k % scales.size]
            window_add(r, 1.0, rbuf, sbuf, acc, ints)
            k += 1
            if rng.random() < 0.003:  # a divergence: restart, the window emptied or kept
                ints[INTS.div] += 1
                if rng.random() < 0.5:
                    clear_window(acc, ints)
        put_updates(taken, before, ints, rbuf, run)
        _assert_update_sums(ints, rbuf, run, f"step {step}")
    assert ints[INTS.div] > 0


def _innovations(rng: np.random.Generator, n: int) -> np.ndarray:
    """(n, 3) innovations at swinging scales, correlated, with skipped samples (NaN rows):
    single ones, short runs and two gaps longer than the window; and a stretch whose mean is
    1e5 times its spread (a step the filter has not absorbed)."""
    r = np.cumsum(rng.standard_normal((n, 3)), axis=0) * 0.3 + rng.standard_normal((n, 3))
    r *= _levels(rng, n)[:, None]
    r[1500:1700] = 1e5 + rng.standard_normal((200, 3))
    r[rng.random(n) < 0.03] = np.nan
    for start in rng.integers(0, n - 200, 6):
        r[start : start + int(rng.integers(2, 8))] = np.nan
    r[1000:1080] = np.nan  # longer than the window
    r[2400:2475] = np.nan
    return r


def _whiteness_sums(innov: np.ndarray, lo: int, k1: int) -> tuple[float, ...]:
    rows = innov[lo:k1]
    rows = rows[np.all(np.isfinite(rows), axis=1)]
    links = math.fsum((rows[1:] * rows[:-1]).ravel()) if len(rows) > 1 else 0.0
    return len(rows), math.fsum((rows * rows).ravel()), links


@pytest.mark.parametrize("seed", range(3))
def test_whiteness_sums_slide_over_gaps_and_swings(seed):
    """The sample window's sums slid by K = 1..60 samples over skipped samples (single ones,
    runs, gaps longer than the window) and innovations 50 decades apart: the row count exact,
    Σ |r|² and the links within SUM_RTOL of math.fsum, and the whiteness within 1e-9 of the
    numpy reference (absolute: it is a ratio in [-1, 1])."""
    rng = np.random.default_rng(seed)
    innov = _innovations(rng, 3000)
    run = np.zeros(N_RUN)
    k0 = 0
    while k0 < innov.shape[0]:
        k1 = min(k0 + int(rng.choice([1, 3, 10, 10, 10, 49, 50, 60])), innov.shape[0])
        slide_samples(k0, k1, M, innov, run)
        lo = max(0, k1 - M)
        rows, total, links = _whiteness_sums(innov, lo, k1)
        assert run[RUN.white_rows] == rows, k1
        assert run[RUN.white_rr] == pytest.approx(total, rel=SUM_RTOL, abs=0.0), k1
        assert run[RUN.white_link] == pytest.approx(links, rel=SUM_RTOL, abs=SUM_RTOL * total), k1
        got = compiled.whiteness_running(k1, M, innov, run)
        assert got == pytest.approx(ref.whiteness(innov, k1, M), abs=1e-9), k1
        k0 = k1


@pytest.mark.parametrize("offset", [0.0, 30.0, 1e3, 1e6])
def test_centred_statistics_from_the_sums_or_afresh(offset):
    """The bias and two-window statistics of a full, wrapped window whose mean is ``offset``
    times the innovations' spread, from the running sums: within 1e-9 of the numpy reference
    at every offset (beyond CENTRED_RATIO's 4 digits the two-pass loop computes them: at 1e6
    the centred sums from the running sums would keep 4 of 16 digits; the difference of two
    means 1e6 times the spread keeps 10 in either)."""
    rng = np.random.default_rng(1)
    ints, run = np.zeros(N_INT, np.int64), np.zeros(N_RUN)
    ints[INTS.window], ints[INTS.updates], ints[INTS.pos] = M, M, 17
    rbuf = rng.standard_normal((M, 3)) + offset
    rbuf[[(17 - 1 - j) % M for j in range(10)]] += 3.0  # a step in the last 10 updates
    put_updates(Taken(-1, 0.0), WindowMark(0, 0, 0), ints, rbuf, run)  # summed afresh
    assert compiled.innovation_bias_running(ints, rbuf, run) == pytest.approx(
        ref.innovation_bias(ints, rbuf), rel=1e-9
    )
    assert compiled.step_statistic_running(10, ints, rbuf, run) == pytest.approx(
        ref.step_statistic(ints, rbuf, 10), rel=1e-9
    )


def test_whiteness_sums_afresh_equal_the_slid_ones_on_a_clean_window():
    """Summed afresh or slid there, the sums over the same samples agree (to rounding)."""
    rng = np.random.default_rng(7)
    innov = rng.standard_normal((430, 3))
    slid, fresh = np.zeros(N_RUN), np.zeros(N_RUN)
    for k0 in range(0, 430, 10):  # the last lap's sums afresh at 400, slid since
        slide_samples(k0, k0 + 10, M, innov, slid)
    sample_sums(430 - M, 430, innov, fresh)
    np.testing.assert_allclose(slid, fresh, rtol=1e-13, atol=1e-12)


#: Episodes of the environment: (configuration, reset seed, actions).
EPISODES = [
    ({"preset": "general", "scenario": "nonstationary"}, 100_003, "random"),
    ({"preset": "general", "scenario": "noise_bursts", "recent_samples": 20}, 5, "random"),
    ({"preset": "general", "scenario": "misspecified", "decision_window": 7}, 11, "random"),
    (
        {
            "preset": "general",
            "scenario": "calibration_then_survey",
            "action": {"q_log10": (-30.0, 30.0), "r_log10": (-100.0, 100.0), "scale_limit": 1e100},
        },
        24,
        "swing",
    ),
]
#: The window statistics and the compiled running form of each (f: the filter, run: the env's
#: running values, m: recent_samples); the reference's the same way.
STATISTICS = {
    "log_innovation_power": (
        lambda f, run, m: compiled.window_power(f.ints, f.acc),
        lambda f, m: ref.window_power(f.ints, f.rbuf),
    ),
    "log_mean_innovation_power": (
        lambda f, run, m: compiled.power_of_mean(m, f.ints, f.rbuf),
        lambda f, m: ref.power_of_mean(f.ints, f.rbuf, m),
    ),
    "log_recent_ror": (
        lambda f, run, m: compiled.recent_ratio(m, f.ints, f.rbuf, f.sbuf),
        lambda f, m: ref.recent_ratio(f.ints, f.rbuf, f.sbuf, m),
    ),
    "log_step_statistic": (
        lambda f, run, m: compiled.step_statistic_running(m, f.ints, f.rbuf, run),
        lambda f, m: ref.step_statistic(f.ints, f.rbuf, m),
    ),
    "log_innovation_bias": (
        lambda f, run, m: compiled.innovation_bias_running(f.ints, f.rbuf, run),
        lambda f, m: ref.innovation_bias(f.ints, f.rbuf),
    ),
}


def _as_observation(name: str, value: float, f) -> np.float32:
    """The reference statistic as the observation writes it (log10, 0 when not positive or
    finite, clipped to ±OBS_LIMIT)."""
    if name in ("log_innovation_power", "log_mean_innovation_power"):
        value /= float(np.trace(f.r0))
    if name == "log_recent_ror" and value > 0.0:
        value = max(value, 1e-8)
    v = math.log10(value) if value > 0.0 and math.isfinite(value) else 0.0
    return np.float32(min(max(v, -OBS_LIMIT), OBS_LIMIT))


def _actions(kind: str, rng: np.random.Generator) -> np.ndarray:
    if kind == "random":
        return rng.uniform(-1.2, 1.2, 3)
    return rng.choice([-1.0, 1.0, 0.0, 0.4], 3)  # absolute mode: tens of decades a step


@pytest.mark.parametrize(("config", "seed", "kind"), EPISODES)
def test_observations_follow_the_numpy_reference(config, seed, kind):
    """At every step of 400, every window statistic from the running sums within 1e-9 of the
    numpy reference (relative), its observation within one float32 ulp of the reference's, and
    the whiteness observation within 1e-8."""
    env = gym.make("AeroMagCompensation-v0", config=config)
    env.reset(seed=seed)
    u = env.unwrapped
    f, run = u.filter, u._run
    m = int(u.config.recent_samples or u.config.decision_window)
    column = {name: observation_index(u.config, name) for name in (*STATISTICS, "whiteness")}
    rng = np.random.default_rng(seed)
    for step in range(400):
        obs, _, _, truncated, _ = env.step(_actions(kind, rng))
        where = f"step {step}"
        for name, (running, reference) in STATISTICS.items():
            got, want = running(f, run, m), reference(f, m)
            assert got == pytest.approx(want, rel=1e-9, nan_ok=True), f"{name} {where}"
            np.testing.assert_array_max_ulp(obs[column[name]], _as_observation(name, want, f), 1)
        white = ref.whiteness(f.innov, f.k, f.cfg.window)
        assert obs[column["whiteness"]] == pytest.approx(white, abs=1e-8), where
        if truncated:
            break
