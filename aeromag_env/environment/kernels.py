"""Compiled step of the tuning environment, shared by the single and the vector environment.

:func:`env_step` is one ``step`` of :class:`aeromag_env.environment.env.AeroMagCompensationEnv`
once the action has been checked: map the action to Q and R scale factors, rescale, advance the
filter (:func:`aeromag_env.compensation.kernels.advance`) over one decision window, score the
window against the true interference and write the observation. :func:`env_step_batch` runs it for
many environments at once, in compiled chunks spread over the cores (:mod:`aeromag_env.threads`;
used by :class:`aeromag_env.environment.vec_env.AeroMagCompensationVecEnv`). Both run the same
compiled code, so environment i of the vector environment is bitwise the single environment given
the same flight and actions (tested).

The action mapping, reward and observation are specified in the environment's docstring; the
action and observation layouts are named in :mod:`aeromag_env.environment.spaces`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from aeromag_env.compensation.arrays import FilterArrays, Packed, named, packed, row
from aeromag_env.compensation.kernel_layout import INT_DIV, INT_K, INT_WINDOW
from aeromag_env.compensation.kernels import advance
from aeromag_env.environment.spaces import (
    ACT_Q,
    ACT_QP,
    ACT_R,
    OBS_LIMIT,
    OBS_LOG_INNOVATION_BIAS,
    OBS_LOG_INNOVATION_POWER,
    OBS_LOG_MEAN_INNOVATION_POWER,
    OBS_LOG_Q_SCALE,
    OBS_LOG_QOQ,
    OBS_LOG_QP_SCALE,
    OBS_LOG_R_SCALE,
    OBS_LOG_RECENT_ROR,
    OBS_LOG_ROR,
    OBS_LOG_STEP_STATISTIC,
    OBS_LOG_TURN_RATE,
    OBS_PROGRESS,
    OBS_WHITENESS,
)
from aeromag_env.environment.statistics import (
    innovation_bias,
    log10_or_zero,
    recent_power,
    recent_ratio,
    step_statistic,
    turn_rate,
    whiteness,
)
from aeromag_env.numba_cache import njit
from aeromag_env.simulation.interference import INDUCED_START, PERMANENT_START
from aeromag_env.threads import run_chunks

# running values of one environment (float vector); RUN_LOG_Q is the Q of all 21 states, or with
# split_q of the coefficient blocks (A, B) only, and RUN_LOG_QP that of the permanent block T_p;
# RUN_SQ_ERR and RUN_N_ERR sum the squared errors from score_start on, RUN_SQ_FLOWN and
# RUN_N_FLOWN over every sample flown that has an estimate (the score of an episode that ends
# before score_start)
RUN_LOG_Q, RUN_LOG_R, RUN_SQ_ERR, RUN_N_ERR, RUN_LOG_QP, RUN_SQ_FLOWN, RUN_N_FLOWN = range(7)
N_RUN = 7
# environment parameters (float vector, see aeromag_env.environment.env.parameters)
(
    PAR_K,
    PAR_LOG_S_MAX,
    PAR_LOG_LIMIT,
    PAR_ABSOLUTE,
    PAR_Q_LO,
    PAR_Q_HI,
    PAR_R_LO,
    PAR_R_HI,
    PAR_REWARD_NT,
    PAR_PENALTY,
    PAR_LN10,
    PAR_SPLIT_Q,
    PAR_QP_LO,
    PAR_QP_HI,
    PAR_REWARD_FORM,
    PAR_QP_GATE,
    PAR_RECENT,
) = range(17)
N_PAR = 17
#: Reward forms of :class:`aeromag_env.environment.env.EnvConfig`, coded by their index in
#: PAR_REWARD_FORM.
REWARD_FORMS = ("log", "linear", "squared")
# outcome of one step (float vector)
(
    OUT_REWARD,
    OUT_RMSE,
    OUT_ROR,
    OUT_QOQ,
    OUT_Q_SCALE,
    OUT_R_SCALE,
    OUT_TERMINATED,
    OUT_TRUNCATED,
    OUT_EPISODE_RMSE,
    OUT_QP_SCALE,
) = range(10)
N_OUT = 10


class EnvArrays(NamedTuple):
    """One environment's arrays (the vector environment's: each with a leading environment axis)."""

    action: np.ndarray  #: (2 or 3,) float64 finite action (aeromag_env.environment.spaces.ACTIONS)
    run: np.ndarray  #: (N_RUN,) running values (RUN_*)
    truth: np.ndarray  #: (≥ n, 3) true interference [nT]
    obs: np.ndarray  #: (dim,) float32 observation (written)
    outcome: np.ndarray  #: (N_OUT,) outcome of the step (OUT_*, written)


class EnvSettings(NamedTuple):
    """What every environment of one configuration shares."""

    par: np.ndarray  #: (N_PAR,) parameters (PAR_*)
    obs_at: np.ndarray  #: int64 column of each observation or -1 (spaces.observation_positions)
    low: np.ndarray  #: (dim,) float32 lower bounds of the observation
    high: np.ndarray  #: (dim,) float32 upper bounds


@njit(cache=True, inline="always")  # as arrays.row
def _env_row(e: EnvArrays, i: int) -> EnvArrays:
    """Environment i of stacked environment arrays (views of its rows)."""
    return EnvArrays(e.action[i], e.run[i], e.truth[i], e.obs[i], e.outcome[i])


@njit(cache=True)
def _scale(a: float, slot: int, lo: float, hi: float, run: np.ndarray, par: np.ndarray) -> float:
    """One action → the factor that moves the cumulative log scale ``run[slot]`` to its new value.

    The action is clipped to [-1, 1]; absolute mode: ``log10(scale) = lo + (a + 1)/2 (hi − lo)``,
    relative mode: ``s = s_max ** a``; the log scale stays within ±log(scale_limit).
    """
    a = min(max(a, -1.0), 1.0)
    old, limit = run[slot], par[PAR_LOG_LIMIT]
    if par[PAR_ABSOLUTE] != 0.0:
        step = par[PAR_LN10] * (lo + 0.5 * (a + 1.0) * (hi - lo)) - old
    else:
        step = a * par[PAR_LOG_S_MAX]
    new = min(max(old + step, -limit), limit)
    run[slot] = new
    return math.exp(new - old)


@njit(cache=True)
def _window_error(
    k0: int, k1: int, truth: np.ndarray, est: np.ndarray, score_start: int, run: np.ndarray
) -> float:
    """RMS of true minus estimated interference over ``k0 ≤ k < k1`` [nT] (pooled over axes);
    the part from ``score_start`` on is added to the episode's sums, every sample with an
    estimate (a skipped one has none) to the sums of the part flown."""
    total, scored = 0.0, 0.0
    for k in range(k0, k1):
        row = 0.0
        for i in range(3):
            e2 = (truth[k, i] - est[k, i]) ** 2
            total += e2
            row += e2
            if k >= score_start:
                scored += e2
        if np.isfinite(row):
            run[RUN_SQ_FLOWN] += row
            run[RUN_N_FLOWN] += 3
    lo = max(k0, score_start)
    if lo < k1:
        run[RUN_SQ_ERR] += scored
        run[RUN_N_ERR] += 3 * (k1 - lo)
    return math.sqrt(total / (3 * (k1 - k0))) if k1 > k0 else np.nan


@njit(cache=True)
def _episode_rmse(run: np.ndarray, window_rmse: float) -> float:
    """The episode's RMSE so far [nT]: over the flight after ``score_from``; before it (an
    episode cut or diverged early) over the part flown, so that a score is never NaN; the
    window's when no sample has an estimate yet."""
    if run[RUN_N_ERR] > 0:
        return math.sqrt(run[RUN_SQ_ERR] / run[RUN_N_ERR])
    if run[RUN_N_FLOWN] > 0:
        return math.sqrt(run[RUN_SQ_FLOWN] / run[RUN_N_FLOWN])
    return window_rmse


@njit(cache=True)
def _observe(
    k0: int, k1: int, n: int, env: EnvArrays, settings: EnvSettings, f: FilterArrays
) -> None:
    """Write the observation at the end of the window ``k0 ≤ k < k1`` (float32, clipped to the
    bounds), each at its column (``settings.obs_at``)."""
    run, obs, par, at = env.run, env.obs, settings.par, settings.obs_at
    ints, r0, rbuf = f.state.ints, f.state.r0, f.window.rbuf
    k = k1 - 1
    obs[OBS_LOG_ROR] = log10_or_zero(f.outputs.ror[k])
    obs[OBS_LOG_QOQ] = log10_or_zero(f.outputs.qoq[k])
    if at[OBS_LOG_Q_SCALE] >= 0:  # the extras
        obs[OBS_LOG_Q_SCALE] = run[RUN_LOG_Q] / par[PAR_LN10]
        obs[OBS_LOG_R_SCALE] = run[RUN_LOG_R] / par[PAR_LN10]
        obs[OBS_WHITENESS] = whiteness(k1, ints[INT_WINDOW], f.outputs.innov)
        obs[OBS_PROGRESS] = k1 / n
        short = recent_ratio(int(par[PAR_RECENT]), ints, rbuf, f.window.sbuf)
        obs[OBS_LOG_RECENT_ROR] = log10_or_zero(max(short, 1e-8)) if short > 0.0 else 0.0
    if at[OBS_LOG_QP_SCALE] >= 0:
        obs[at[OBS_LOG_QP_SCALE]] = run[RUN_LOG_QP] / par[PAR_LN10]
    if at[OBS_LOG_INNOVATION_POWER] >= 0:  # over tr R(0): the noise level and a step, R aside
        tr_r0 = r0[0, 0] + r0[1, 1] + r0[2, 2]
        power = recent_power(ints[INT_WINDOW], ints, rbuf)[0]
        obs[at[OBS_LOG_INNOVATION_POWER]] = log10_or_zero(power / tr_r0)
        mean_power = recent_power(int(par[PAR_RECENT]), ints, rbuf)[1]
        obs[at[OBS_LOG_MEAN_INNOVATION_POWER]] = log10_or_zero(mean_power / tr_r0)
    if at[OBS_LOG_STEP_STATISTIC] >= 0:
        statistic = step_statistic(int(par[PAR_RECENT]), ints, rbuf)
        obs[at[OBS_LOG_STEP_STATISTIC]] = log10_or_zero(statistic)
    if at[OBS_LOG_TURN_RATE] >= 0:  # 0 (no turn seen) → the lower bound
        s = f.signals
        rate = turn_rate(k0, k1, s.t, s.td, s.valid)
        obs[at[OBS_LOG_TURN_RATE]] = math.log10(rate) if rate > 0.0 else -OBS_LIMIT
    if at[OBS_LOG_INNOVATION_BIAS] >= 0:
        obs[at[OBS_LOG_INNOVATION_BIAS]] = log10_or_zero(innovation_bias(ints, rbuf))
    for j in range(obs.shape[0]):
        obs[j] = min(max(obs[j], settings.low[j]), settings.high[j])


@njit(cache=True)
def _reward(e: float, form: float) -> float:
    """The reward of a window error ``e`` in units of ``reward_scale_nt``: ``−ln(1 + e)``
    (form 0, log), ``−e`` (1, linear) or ``−e²`` (2, squared)."""
    if form == 0.0:
        return -math.log1p(e)
    if form == 1.0:
        return -e
    return -e * e


@njit(cache=True)
def env_step(
    mode: int,
    n: int,
    score_start: int,
    env_arrays: EnvArrays | Packed,
    shared: EnvSettings | Packed,
    filter_arrays: FilterArrays | Packed,
) -> None:
    """One environment step for the finite action ``env.action``.

    ``mode`` is the filter's method, ``n`` the flight length, ``score_start`` the first scored
    sample; ``env_arrays`` this environment's arrays (the observation and outcome written),
    ``shared`` the settings of its configuration, ``filter_arrays`` the filter's (updated in
    place); each a NamedTuple or the same packed
    (:func:`aeromag_env.compensation.arrays.packed`).
    """
    env, settings, f = EnvArrays(*env_arrays), EnvSettings(*shared), named(filter_arrays)
    e, run, a, out = settings.par, env.run, env.action, env.outcome
    qd, rm, ints = f.state.qd, f.state.rm, f.state.ints
    s_q = _scale(a[ACT_Q], RUN_LOG_Q, e[PAR_Q_LO], e[PAR_Q_HI], run, e)
    s_r = _scale(a[ACT_R], RUN_LOG_R, e[PAR_R_LO], e[PAR_R_HI], run, e)
    if e[PAR_SPLIT_Q] != 0.0:  # T_p's Q on its own, the coefficient blocks' by s_q
        a_qp = a[ACT_QP] if e[PAR_QP_GATE] == 0.0 else (1.0 if a[ACT_QP] > 0.0 else -1.0)
        s_qp = _scale(a_qp, RUN_LOG_QP, e[PAR_QP_LO], e[PAR_QP_HI], run, e)
        qd[PERMANENT_START:INDUCED_START] *= s_qp
        qd[INDUCED_START:] *= s_q
    else:
        qd *= s_q  # eq. 21: Q ← s_a Q, R ← s_r R
    rm *= s_r
    k0, divergences = ints[INT_K], ints[INT_DIV]
    k1 = min(k0 + int(e[PAR_K]), n)
    if k1 > k0:
        advance(mode, k0, k1, f)
    ror, qoq = f.outputs.ror, f.outputs.qoq
    rmse = _window_error(k0, k1, env.truth, f.outputs.est, score_start, run)
    terminated = ints[INT_DIV] > divergences
    reward = _reward(rmse / e[PAR_REWARD_NT], e[PAR_REWARD_FORM])
    out[OUT_REWARD] = e[PAR_PENALTY] if terminated else reward
    out[OUT_RMSE] = rmse
    out[OUT_ROR], out[OUT_QOQ] = ror[k1 - 1], qoq[k1 - 1]
    out[OUT_Q_SCALE], out[OUT_R_SCALE] = math.exp(run[RUN_LOG_Q]), math.exp(run[RUN_LOG_R])
    out[OUT_QP_SCALE] = math.exp(run[RUN_LOG_QP])
    out[OUT_TERMINATED] = 1.0 if terminated else 0.0
    out[OUT_TRUNCATED] = 1.0 if k1 >= n and not terminated else 0.0
    out[OUT_EPISODE_RMSE] = _episode_rmse(run, rmse)
    _observe(k0, k1, n, env, settings, f)


@njit(cache=True, nogil=True)
def _env_step_range(
    lo: int,
    hi: int,
    active: np.ndarray,
    modes: np.ndarray,
    n: np.ndarray,
    score_start: np.ndarray,
    env_arrays: Packed,
    shared: Packed,
    filter_arrays: Packed,
) -> None:
    """Environments ``lo ≤ i < hi`` of :func:`env_step_batch`."""
    envs, settings, filters = EnvArrays(*env_arrays), EnvSettings(*shared), named(filter_arrays)
    for i in range(lo, hi):
        if active[i]:
            env = _env_row(envs, i)
            env_step(modes[i], n[i], score_start[i], env, settings, row(filters, i))


def env_step_batch(
    active: np.ndarray,
    modes: np.ndarray,
    n: np.ndarray,
    score_start: np.ndarray,
    envs: EnvArrays | Packed,
    settings: EnvSettings | Packed,
    filters: FilterArrays | Packed,
) -> None:
    """:func:`env_step` for every environment i with ``active[i]`` (N,) bool, on all cores.

    ``modes``, ``n``, ``score_start`` (N,) int64 and the arrays of ``envs`` and ``filters`` have
    a leading environment axis (the actions (N, 2 or 3) float64 finite); ``settings`` are
    shared. Each group as a NamedTuple or already :func:`~aeromag_env.compensation.arrays.packed`
    (a caller stepping the same arrays again and again packs them once).
    """
    run_chunks(
        _env_step_range,
        int(active.shape[0]),
        active,
        modes,
        n,
        score_start,
        _packed(envs),
        _packed(settings),
        _packed(filters),
    )


def _packed(arrays: tuple) -> Packed:
    """``arrays`` packed, unless they already are (a plain tuple, not a NamedTuple)."""
    return arrays if type(arrays) is tuple else packed(arrays)
