"""Compiled step of the tuning environment, shared by the single and the vector environment.

:func:`env_step` is one ``step`` of :class:`aeromag_env.environment.env.AeroMagCompensationEnv`
once the action has been checked: map the action to Q and R scale factors, rescale, advance the
filter (:func:`aeromag_env.compensation.kernels.advance`) over one decision window, score the
window against the true interference and write the observation. :func:`env_step_batch` runs it for
many environments at once, in compiled chunks spread over the cores (:mod:`aeromag_env.threads`;
used by :class:`aeromag_env.environment.vec_env.AeroMagCompensationVecEnv`). Both run the same
compiled code, so environment i of the vector environment is bitwise the single environment given
the same flight and actions (tested).

The action mapping, reward and observation are specified in the environment's docstring.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from aeromag_env.compensation.kernel_layout import INT_COUNT, INT_DIV, INT_K, INT_POS, INT_WINDOW
from aeromag_env.compensation.kernels import advance
from aeromag_env.threads import run_chunks

if TYPE_CHECKING:
    from aeromag_env.environment.env import EnvConfig

# running values of one environment (float vector); RUN_LOG_Q is the Q of all 21 states, or with
# split_q of the coefficient blocks (A, B) only, and RUN_LOG_QP that of the permanent block T_p
RUN_LOG_Q, RUN_LOG_R, RUN_SQ_ERR, RUN_N_ERR, RUN_LOG_QP = range(5)
N_RUN = 5
# environment parameters (float vector, see parameters())
(PAR_K, PAR_LOG_S_MAX, PAR_LOG_LIMIT, PAR_ABSOLUTE, PAR_Q_LO, PAR_Q_HI, PAR_R_LO, PAR_R_HI,
 PAR_REWARD_NT, PAR_PENALTY, PAR_EXTRAS, PAR_LN10, PAR_SPLIT_Q, PAR_QP_LO,
 PAR_QP_HI, PAR_POWER, PAR_STEP_STAT, PAR_REWARD_FORM, PAR_QP_GATE) = range(19)  # fmt: skip
N_PAR = 19
#: Reward forms of :class:`aeromag_env.environment.env.EnvConfig`, coded by their index in
#: PAR_REWARD_FORM.
REWARD_FORMS = ("log", "linear", "squared")
#: States of the permanent-field block T_p (the first block of the 21-state vector).
N_PERMANENT = 3
# outcome of one step (float vector)
(OUT_REWARD, OUT_RMSE, OUT_ROR, OUT_QOQ, OUT_Q_SCALE, OUT_R_SCALE, OUT_TERMINATED,
 OUT_TRUNCATED, OUT_EPISODE_RMSE, OUT_QP_SCALE) = range(10)  # fmt: skip
N_OUT = 10


def parameters(config: EnvConfig) -> np.ndarray:
    """The settings of ``config`` the compiled step reads, as a float vector (N_PAR,)."""
    par = np.zeros(N_PAR)
    par[PAR_K] = config.decision_window
    par[PAR_LOG_S_MAX] = math.log(config.s_max)
    par[PAR_LOG_LIMIT] = math.log(config.scale_limit)
    par[PAR_ABSOLUTE] = float(config.action_mode == "absolute")
    par[PAR_Q_LO], par[PAR_Q_HI] = config.absolute_q_log10
    par[PAR_R_LO], par[PAR_R_HI] = config.absolute_r_log10
    par[PAR_REWARD_NT] = config.reward_scale_nt
    par[PAR_PENALTY] = config.divergence_penalty
    par[PAR_EXTRAS] = float(config.extras)
    par[PAR_LN10] = math.log(10.0)
    par[PAR_SPLIT_Q] = float(config.split_q)
    par[PAR_QP_LO], par[PAR_QP_HI] = config.absolute_qp_log10
    par[PAR_POWER] = float(config.innovation_power)
    par[PAR_STEP_STAT] = float(config.step_statistic)
    par[PAR_REWARD_FORM] = REWARD_FORMS.index(config.reward_form)
    par[PAR_QP_GATE] = float(config.qp_gate)
    return par


def action_size(config: EnvConfig) -> int:
    """Entries of one action: ``[a_q, a_r]``, or with ``split_q`` ``[a_q, a_r, a_qp]``."""
    return 3 if config.split_q else 2


def check_actions(actions: object, num_envs: int | None = None, size: int = 2) -> np.ndarray:
    """The action of one environment as float64 (size,), or with ``num_envs`` the actions of a
    vector environment (num_envs, size); a one-line ValueError when the size is wrong or a value
    is not finite (values outside [-1, 1] are clipped later, not refused)."""
    try:
        a = np.asarray(actions, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"actions must be numbers in [-1, 1], got {actions!r}") from None
    if num_envs is None:
        if a.size != size or not np.all(np.isfinite(a)):
            raise ValueError(f"action must be {size} finite numbers in [-1, 1], got {actions!r}")
        return a.reshape(size)
    if a.shape != (num_envs, size):
        raise ValueError(
            f"actions must have shape ({num_envs}, {size}) (one action per environment), "
            f"got shape {a.shape}"
        )
    finite = np.isfinite(a)
    if not finite.all():
        i = int(np.flatnonzero(~finite.all(axis=1))[0])
        raise ValueError(f"actions must be finite; environment {i} got {a[i].tolist()}")
    return a


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
    the part from ``score_start`` on is added to the episode's sums."""
    total, scored = 0.0, 0.0
    for k in range(k0, k1):
        for i in range(3):
            e2 = (truth[k, i] - est[k, i]) ** 2
            total += e2
            if k >= score_start:
                scored += e2
    lo = max(k0, score_start)
    if lo < k1:
        run[RUN_SQ_ERR] += scored
        run[RUN_N_ERR] += 3 * (k1 - lo)
    return math.sqrt(total / (3 * (k1 - k0))) if k1 > k0 else np.nan


@njit(cache=True)
def _finite_row(x: np.ndarray, k: int) -> bool:
    return np.isfinite(x[k, 0]) and np.isfinite(x[k, 1]) and np.isfinite(x[k, 2])


@njit(cache=True)
def _whiteness(k1: int, window: int, innov: np.ndarray) -> float:
    """Lag-1 autocorrelation of the innovations of the last ``window`` samples (finite rows,
    per-axis mean removed, pooled over axes); 0 with fewer than 3 rows or no variance."""
    lo = max(0, k1 - window)
    rows = 0
    for k in range(lo, k1):
        rows += _finite_row(innov, k)
    if rows < 3:
        return 0.0
    num, den = 0.0, 0.0
    for i in range(3):
        mean = 0.0
        for k in range(lo, k1):
            if _finite_row(innov, k):
                mean += innov[k, i]
        mean /= rows
        prev, first = 0.0, True
        for k in range(lo, k1):
            if _finite_row(innov, k):
                c = innov[k, i] - mean
                den += c * c
                if not first:
                    num += c * prev
                prev, first = c, False
    return num / den if den > 0.0 else 0.0


@njit(cache=True)
def _recent_ratio(m: int, ints: np.ndarray, rbuf: np.ndarray, sbuf: np.ndarray) -> float:
    """ROR over the last ``m`` updates only: ``Σ|r|² / Σ tr S`` (NaN before any update)."""
    m = min(m, ints[INT_COUNT])
    num, den = 0.0, 0.0
    for j in range(m):
        w = (ints[INT_POS] - 1 - j) % ints[INT_WINDOW]
        num += rbuf[w, 0] ** 2 + rbuf[w, 1] ** 2 + rbuf[w, 2] ** 2
        den += sbuf[w]
    return num / den if den > 0.0 else np.nan


@njit(cache=True)
def _recent_power(m: int, ints: np.ndarray, rbuf: np.ndarray) -> tuple[float, float]:
    """Over the last ``m`` updates: the mean innovation power ``mean |r|²`` and the power of
    the mean innovation ``|mean r|²`` [nT²] (NaN before any update). Noise averages out of the
    second, a step does not."""
    m = min(m, ints[INT_COUNT])
    if m == 0:
        return np.nan, np.nan
    power, s0, s1, s2 = 0.0, 0.0, 0.0, 0.0
    for j in range(m):
        w = (ints[INT_POS] - 1 - j) % ints[INT_WINDOW]
        power += rbuf[w, 0] ** 2 + rbuf[w, 1] ** 2 + rbuf[w, 2] ** 2
        s0, s1, s2 = s0 + rbuf[w, 0], s1 + rbuf[w, 1], s2 + rbuf[w, 2]
    return power / m, (s0 * s0 + s1 * s1 + s2 * s2) / (m * m)


@njit(cache=True)
def _step_statistic(m: int, ints: np.ndarray, rbuf: np.ndarray) -> float:
    """Two-window change statistic ``m |mean₁ r − mean₀ r|² / tr C₀``: the mean innovation of
    the last ``m`` updates against that of the earlier updates in the statistics window, over
    the earlier ones' innovation covariance trace. About 1 + m/(M − m) without a change,
    whatever the noise level or R; an interference step raises it by m |step|² / tr C₀. NaN
    with fewer than 3 earlier updates."""
    count = ints[INT_COUNT]
    m = min(m, count)
    earlier = count - m
    if m < 1 or earlier < 3:
        return np.nan
    size = ints[INT_WINDOW]
    recent, before, sq = np.zeros(3), np.zeros(3), np.zeros(3)
    for j in range(count):
        w = (ints[INT_POS] - 1 - j) % size
        for i in range(3):
            if j < m:
                recent[i] += rbuf[w, i]
            else:
                before[i] += rbuf[w, i]
    recent /= m
    before /= earlier
    for j in range(m, count):
        w = (ints[INT_POS] - 1 - j) % size
        for i in range(3):
            sq[i] += (rbuf[w, i] - before[i]) ** 2
    tr_c = sq.sum() / (earlier - 1)
    if not tr_c > 0.0:
        return np.nan
    return m * ((recent - before) ** 2).sum() / tr_c


@njit(cache=True)
def _log10_or_zero(v: float) -> float:
    return math.log10(v) if v > 0.0 and np.isfinite(v) else 0.0


@njit(cache=True)
def _observe(
    k1: int, n: int, run: np.ndarray, par: np.ndarray, ror: np.ndarray, qoq: np.ndarray,
    innov: np.ndarray, rbuf: np.ndarray, sbuf: np.ndarray, ints: np.ndarray, r0: np.ndarray,
    low: np.ndarray, high: np.ndarray, obs: np.ndarray,
) -> None:  # fmt: skip
    """Write the observation at the end of the window (float32, clipped to the bounds)."""
    k = k1 - 1
    obs[0] = _log10_or_zero(ror[k])
    obs[1] = _log10_or_zero(qoq[k])
    if par[PAR_EXTRAS] != 0.0:
        obs[2] = run[RUN_LOG_Q] / par[PAR_LN10]
        obs[3] = run[RUN_LOG_R] / par[PAR_LN10]
        obs[4] = _whiteness(k1, ints[INT_WINDOW], innov)
        obs[5] = k1 / n
        short = _recent_ratio(int(par[PAR_K]), ints, rbuf, sbuf)
        obs[6] = _log10_or_zero(max(short, 1e-8)) if short > 0.0 else 0.0
        j = 7
        if par[PAR_SPLIT_Q] != 0.0:
            obs[j] = run[RUN_LOG_QP] / par[PAR_LN10]
            j += 1
        if par[PAR_POWER] != 0.0:  # over tr R(0): the noise level and a step, R aside
            tr_r0 = r0[0, 0] + r0[1, 1] + r0[2, 2]
            obs[j] = _log10_or_zero(_recent_power(ints[INT_WINDOW], ints, rbuf)[0] / tr_r0)
            obs[j + 1] = _log10_or_zero(_recent_power(int(par[PAR_K]), ints, rbuf)[1] / tr_r0)
            j += 2
        if par[PAR_STEP_STAT] != 0.0:
            obs[j] = _log10_or_zero(_step_statistic(int(par[PAR_K]), ints, rbuf))
    for j in range(obs.shape[0]):
        obs[j] = min(max(obs[j], low[j]), high[j])


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
    a: np.ndarray, run: np.ndarray, env_par: np.ndarray, score_start: int, n: int,
    truth: np.ndarray, low: np.ndarray, high: np.ndarray, obs: np.ndarray, out: np.ndarray,
    mode: int, y: np.ndarray, t: np.ndarray, td: np.ndarray, valid: np.ndarray, d: np.ndarray,
    z: np.ndarray, p: np.ndarray, qd: np.ndarray, rm: np.ndarray, z_good: np.ndarray,
    p0: np.ndarray, q0: np.ndarray, r0: np.ndarray, rbuf: np.ndarray, sbuf: np.ndarray,
    acc: np.ndarray, ints: np.ndarray, par: np.ndarray, est: np.ndarray, innov: np.ndarray,
    ror: np.ndarray, qoq: np.ndarray, q_scale: np.ndarray, r_scale: np.ndarray,
    states: np.ndarray,
) -> None:  # fmt: skip
    """One environment step for the finite action ``a`` (2,) or, with ``split_q``, (3,).

    ``run`` (N_RUN,) running values, ``env_par`` (N_PAR,) from :func:`parameters`,
    ``score_start`` first scored sample, ``n`` flight length, ``truth`` (≥ n, 3) true
    interference [nT], ``low``/``high``/``obs`` (dim,) float32 bounds and observation (written),
    ``out`` (N_OUT,) outcome (written); then the filter's ``mode`` and arrays in the order of
    :data:`aeromag_env.compensation.kalman.CORE_ARRAYS` (updated in place).
    """
    e = env_par
    s_q = _scale(a[0], RUN_LOG_Q, e[PAR_Q_LO], e[PAR_Q_HI], run, e)
    s_r = _scale(a[1], RUN_LOG_R, e[PAR_R_LO], e[PAR_R_HI], run, e)
    if e[PAR_SPLIT_Q] != 0.0:  # T_p's Q on its own, the coefficient blocks' by s_q
        a_qp = a[2] if e[PAR_QP_GATE] == 0.0 else (1.0 if a[2] > 0.0 else -1.0)
        qd[:N_PERMANENT] *= _scale(a_qp, RUN_LOG_QP, e[PAR_QP_LO], e[PAR_QP_HI], run, e)
        qd[N_PERMANENT:] *= s_q
    else:
        qd *= s_q  # eq. 21: Q ← s_a Q, R ← s_r R
    rm *= s_r
    k0, divergences = ints[INT_K], ints[INT_DIV]
    k1 = min(k0 + int(env_par[PAR_K]), n)
    if k1 > k0:
        advance(mode, k0, k1, y, t, td, valid, d, z, p, qd, rm, z_good, p0, q0, r0, rbuf, sbuf,
                acc, ints, par, est, innov, ror, qoq, q_scale, r_scale, states)  # fmt: skip
    rmse = _window_error(k0, k1, truth, est, score_start, run)
    terminated = ints[INT_DIV] > divergences
    reward = _reward(rmse / env_par[PAR_REWARD_NT], env_par[PAR_REWARD_FORM])
    out[OUT_REWARD] = env_par[PAR_PENALTY] if terminated else reward
    out[OUT_RMSE] = rmse
    out[OUT_ROR], out[OUT_QOQ] = ror[k1 - 1], qoq[k1 - 1]
    out[OUT_Q_SCALE], out[OUT_R_SCALE] = math.exp(run[RUN_LOG_Q]), math.exp(run[RUN_LOG_R])
    out[OUT_QP_SCALE] = math.exp(run[RUN_LOG_QP])
    out[OUT_TERMINATED] = 1.0 if terminated else 0.0
    out[OUT_TRUNCATED] = 1.0 if k1 >= n and not terminated else 0.0
    n_err = run[RUN_N_ERR]
    out[OUT_EPISODE_RMSE] = math.sqrt(run[RUN_SQ_ERR] / n_err) if n_err > 0 else np.nan
    _observe(k1, n, run, env_par, ror, qoq, innov, rbuf, sbuf, ints, r0, low, high, obs)


@njit(cache=True, nogil=True)
def _env_step_range(
    lo: int, hi: int, active: np.ndarray, actions: np.ndarray, run: np.ndarray,
    env_par: np.ndarray, score_start: np.ndarray, n: np.ndarray, truth: np.ndarray,
    low: np.ndarray, high: np.ndarray, obs: np.ndarray, out: np.ndarray, modes: np.ndarray,
    y: np.ndarray, t: np.ndarray, td: np.ndarray, valid: np.ndarray, d: np.ndarray,
    z: np.ndarray, p: np.ndarray, qd: np.ndarray, rm: np.ndarray, z_good: np.ndarray,
    p0: np.ndarray, q0: np.ndarray, r0: np.ndarray, rbuf: np.ndarray, sbuf: np.ndarray,
    acc: np.ndarray, ints: np.ndarray, par: np.ndarray, est: np.ndarray, innov: np.ndarray,
    ror: np.ndarray, qoq: np.ndarray, q_scale: np.ndarray, r_scale: np.ndarray,
    states: np.ndarray,
) -> None:  # fmt: skip
    """Environments ``lo ≤ i < hi`` of :func:`env_step_batch`."""
    for i in range(lo, hi):
        if active[i]:
            env_step(
                actions[i], run[i], env_par, score_start[i], n[i], truth[i],
                low, high, obs[i], out[i], modes[i], y[i], t[i], td[i], valid[i], d[i], z[i],
                p[i], qd[i], rm[i], z_good[i], p0[i], q0[i], r0[i], rbuf[i], sbuf[i], acc[i],
                ints[i], par[i], est[i], innov[i], ror[i], qoq[i], q_scale[i], r_scale[i],
                states[i],
            )  # fmt: skip


def env_step_batch(
    active: np.ndarray, actions: np.ndarray, run: np.ndarray, env_par: np.ndarray,
    score_start: np.ndarray, n: np.ndarray, truth: np.ndarray, low: np.ndarray,
    high: np.ndarray, obs: np.ndarray, out: np.ndarray, modes: np.ndarray, *arrays: np.ndarray,
) -> None:  # fmt: skip
    """:func:`env_step` for every environment i with ``active[i]`` (N,) bool, on all cores.

    ``actions`` (N, 2 or 3) float64 finite; ``arrays`` the filters' arrays in the order of
    :data:`aeromag_env.compensation.kalman.CORE_ARRAYS`; every array has a leading environment axis
    except ``env_par``, ``low`` and ``high`` (shared).
    """
    run_chunks(_env_step_range, int(active.shape[0]), active, actions, run, env_par,
               score_start, n, truth, low, high, obs, out, modes, *arrays)  # fmt: skip
