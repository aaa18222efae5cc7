"""Compiled step of the tuning environment, shared by the single and the vector environment.

:func:`env_step` is one ``step`` of :class:`aeromag_env.environment.env.AeroMagCompensationEnv`
once the action has been checked: map the action to Q and R scale factors, rescale, advance the
filter (:func:`aeromag_env.compensation.kernels.advance`) over one decision window, score the
window against the true interference and write the observation. :func:`env_step_batch` runs it for
many environments at once, with the vector environment's bookkeeping of a step (the action check,
the episode's step count and limit, the end flags, the rewards: :class:`BatchArrays
<aeromag_env.environment.layout.BatchArrays>`), in one compiled call, or in compiled chunks
spread over the cores for many environments (:mod:`aeromag_env.threads`; used by
:class:`aeromag_env.environment.vec_env.AeroMagCompensationVecEnv`). Both run the same compiled
step, so environment i of the vector environment is bitwise the single environment given the same
flight and actions (tested).

The action mapping, reward and observation are specified in the environment's docstring; the
action and observation layouts are named in :mod:`aeromag_env.environment.spaces`, the
observations written by :mod:`aeromag_env.environment.observe`, and the vectors the step keeps
and writes laid out in :mod:`aeromag_env.environment.layout`.
"""

from __future__ import annotations

import math

import numpy as np

from aeromag_env.compensation.arrays import FilterArrays, Packed, named, row
from aeromag_env.compensation.kernel_layout import INTS
from aeromag_env.compensation.kernels import advance
from aeromag_env.environment.layout import (
    LN10,
    OUT,
    RUN,
    STEP_PAR,
    BatchArrays,
    EnvArrays,
    EnvSettings,
    RewardForm,
)
from aeromag_env.environment.observe import keep_sums, observe, take_leaving_updates
from aeromag_env.environment.spaces import ACT_Q, ACT_QP, ACT_R
from aeromag_env.environment.step_arrays import StepArrays
from aeromag_env.environment.window_sums import per_step, window_mark
from aeromag_env.numba_cache import njit
from aeromag_env.simulation.interference import INDUCED_START, PERMANENT_START
from aeromag_env.threads import MIN_CHUNK, run_chunks


@njit(cache=True, inline="always")  # as arrays.row
def _env_row(e: EnvArrays, i: int) -> EnvArrays:
    """Environment i of stacked environment arrays (views of its rows)."""
    return EnvArrays(e.action[i], e.run[i], e.truth[i], e.obs[i], e.outcome[i])


@per_step
def _scale(a: float, slot: int, lo: float, hi: float, run: np.ndarray, par: np.ndarray) -> float:
    """One action → the factor that moves the cumulative log scale ``run[slot]`` to its new value.

    The action is clipped to [-1, 1]; absolute mode: ``log10(scale) = lo + (a + 1)/2 (hi − lo)``,
    relative mode: ``s = s_max ** a``; the log scale stays within ±log(scale_limit).
    """
    a = min(max(a, -1.0), 1.0)
    old, limit = run[slot], par[STEP_PAR.log_limit]
    if par[STEP_PAR.absolute] != 0.0:
        step = LN10 * (lo + 0.5 * (a + 1.0) * (hi - lo)) - old
    else:
        step = a * par[STEP_PAR.log_s_max]
    new = min(max(old + step, -limit), limit)
    run[slot] = new
    return math.exp(new - old)


@per_step
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
            run[RUN.sq_flown] += row
            run[RUN.n_flown] += 3
    lo = max(k0, score_start)
    if lo < k1:
        run[RUN.sq_err] += scored
        run[RUN.n_err] += 3 * (k1 - lo)
    return math.sqrt(total / (3 * (k1 - k0))) if k1 > k0 else np.nan


@per_step
def _episode_rmse(run: np.ndarray, window_rmse: float) -> float:
    """The episode's RMSE so far [nT]: over the flight after ``score_from``; before it (an
    episode cut or diverged early) over the part flown, so that a score is never NaN; the
    window's when no sample has an estimate yet."""
    if run[RUN.n_err] > 0:
        return math.sqrt(run[RUN.sq_err] / run[RUN.n_err])
    if run[RUN.n_flown] > 0:
        return math.sqrt(run[RUN.sq_flown] / run[RUN.n_flown])
    return window_rmse


@per_step
def _reward(e: float, form: int) -> float:
    """The reward of a window error ``e`` in units of the reward's ``scale_nt`` by its
    :class:`~aeromag_env.environment.layout.RewardForm`: ``−ln(1 + e)``, ``−e`` or ``−e²``."""
    if form == RewardForm.LOG:
        return -math.log1p(e)
    if form == RewardForm.LINEAR:
        return -e
    return -e * e


@per_step
def _rescale(qd: np.ndarray, rm: np.ndarray, s_qp: float, s_q: float, s_r: float) -> None:
    """Eq. 21: ``Q ← s_a Q``, ``R ← s_r R``, with T_p's block of Q scaled by ``s_qp`` (``s_q``
    without a T_p action), element by element (a slice would need numba's runtime)."""
    for a in range(PERMANENT_START, INDUCED_START):
        qd[a] *= s_qp
    for a in range(INDUCED_START, qd.shape[0]):
        qd[a] *= s_q
    for i in range(3):
        for j in range(3):
            rm[i, j] *= s_r


@njit(cache=True, inline="always")
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
    s_q = _scale(a[ACT_Q], RUN.log_q, e[STEP_PAR.q_lo], e[STEP_PAR.q_hi], run, e)
    s_r = _scale(a[ACT_R], RUN.log_r, e[STEP_PAR.r_lo], e[STEP_PAR.r_hi], run, e)
    s_qp = s_q
    if e[STEP_PAR.split_q] != 0.0:  # T_p's Q on its own, the coefficient blocks' by s_q
        a_qp = a[ACT_QP] if e[STEP_PAR.qp_gate] == 0.0 else (1.0 if a[ACT_QP] > 0.0 else -1.0)
        s_qp = _scale(a_qp, RUN.log_qp, e[STEP_PAR.qp_lo], e[STEP_PAR.qp_hi], run, e)
    _rescale(qd, rm, s_qp, s_q, s_r)
    k0, divergences = ints[INTS.k], ints[INTS.div]
    k1 = min(k0 + int(e[STEP_PAR.k]), n)
    window = window_mark(ints)  # before the filter's updates
    taken = take_leaving_updates(k0, k1, env, settings, f)
    if k1 > k0:
        advance(mode, k0, k1, f)
    keep_sums(k0, k1, taken, window, env, settings, f)
    ror, qoq = f.outputs.ror, f.outputs.qoq
    rmse = _window_error(k0, k1, env.truth, f.outputs.est, score_start, run)
    terminated = ints[INTS.div] > divergences
    reward = _reward(rmse / e[STEP_PAR.reward_nt], int(e[STEP_PAR.reward_form]))
    out[OUT.reward] = e[STEP_PAR.penalty] if terminated else reward
    out[OUT.rmse] = rmse
    out[OUT.ror], out[OUT.qoq] = ror[k1 - 1], qoq[k1 - 1]
    out[OUT.q_scale], out[OUT.r_scale] = math.exp(run[RUN.log_q]), math.exp(run[RUN.log_r])
    out[OUT.qp_scale] = math.exp(run[RUN.log_qp])
    out[OUT.terminated] = 1.0 if terminated else 0.0
    out[OUT.truncated] = 1.0 if k1 >= n and not terminated else 0.0
    out[OUT.episode_rmse] = _episode_rmse(run, rmse)
    observe(k0, k1, n, env, settings, f)


@njit(cache=True, nogil=True)
def _env_step_range(lo: int, hi: int, limit: int, arrays: StepArrays) -> int:
    """Environments ``lo ≤ i < hi`` of :func:`env_step_batch` (their actions checked): step the
    active ones, zero the others' outcome, and write each one's step count, end flags and
    reward; the number of environments whose episode ended."""
    b, envs = BatchArrays(*arrays.batch), EnvArrays(*arrays.envs)
    settings, filters = EnvSettings(*arrays.settings), named(arrays.filters)
    ended = 0
    for i in range(lo, hi):
        out = envs.outcome[i]
        if b.active[i]:
            env = _env_row(envs, i)
            env_step(b.mode[i], b.n[i], b.score_start[i], env, settings, row(filters, i))
            b.steps[i] += 1
            if limit > 0 and b.steps[i] >= limit:  # a TimeLimit's cut, as gym.make's
                out[OUT.truncated] = 1.0
        else:
            out[:] = 0.0
        b.reward[i] = out[OUT.reward]
        b.terminated[i], b.truncated[i] = out[OUT.terminated] > 0.0, out[OUT.truncated] > 0.0
        b.ended[i] = b.terminated[i] or b.truncated[i]
        ended += b.ended[i]
    return ended


#: What :func:`env_step_batch` refuses (:func:`refusal`): an environment's action that is not
#: finite, a step of an environment whose episode ended and which was not reset, actions of
#: another shape than (N, the action's size).
NOT_FINITE, NOT_RESET, NOT_SHAPED = 0, 1, 2


@njit(cache=True, nogil=True)
def _refused(arrays: StepArrays, actions: np.ndarray) -> int:
    """0, or the refusal code of :func:`env_step_batch` (−1 − (kind · N + i), :func:`refusal`),
    in this order: an active environment i that ended and was not reset, ``actions`` not of
    the step's actions' shape, environment i's action not finite; ``actions`` are copied into
    the step's (float64) on the way, row by row."""
    b, step_actions = BatchArrays(*arrays.batch), EnvArrays(*arrays.envs).action
    n = b.active.shape[0]
    for i in range(n):
        if b.active[i] and b.ended[i]:
            return -1 - (NOT_RESET * n + i)
    if actions.shape != step_actions.shape:
        return -1 - NOT_SHAPED * n
    for i in range(n):
        for j in range(actions.shape[1]):
            step_actions[i, j] = actions[i, j]
        for j in range(actions.shape[1]):
            if not np.isfinite(step_actions[i, j]):
                return -1 - (NOT_FINITE * n + i)
    return 0


def refusal(code: int, n: int) -> tuple[int, int]:
    """:func:`env_step_batch`'s negative return ``code`` for N = ``n`` environments as (the
    kind: :data:`NOT_FINITE`, :data:`NOT_RESET` or :data:`NOT_SHAPED`, the environment)."""
    kind, i = divmod(-1 - code, n)
    return kind, i


@njit(cache=True, nogil=True)
def _env_step_all(limit: int, arrays: StepArrays, actions: np.ndarray) -> int:
    """:func:`env_step_batch` in one compiled call: the refusals first, then the step."""
    code = _refused(arrays, actions)
    if code < 0:
        return code
    n = BatchArrays(*arrays.batch).active.shape[0]
    return _env_step_range(0, n, limit, arrays)


@njit(cache=True)
def _count_ended(arrays: StepArrays) -> int:
    return int(np.count_nonzero(BatchArrays(*arrays.batch).ended))


def env_step_batch(arrays: StepArrays, actions: np.ndarray, num_envs: int, limit: int = 0) -> int:
    """One step of N = ``num_envs`` environments: ``actions`` (N, the action's size) of real
    numbers copied into the step's, :func:`env_step` for every environment i with
    ``batch.active[i]``, the others' outcome zeroed, and the step's bookkeeping of every one
    (:class:`~aeromag_env.environment.layout.BatchArrays`: step count, end flags, reward; the
    step count reaching ``limit`` > 0 truncates, as a ``TimeLimit``).

    ``arrays`` (:func:`~aeromag_env.environment.step_arrays.step_arrays`) holds the groups:
    ``batch`` and the arrays of ``envs`` and ``filters`` with a leading environment axis (the
    step's actions (N, 2 or 3) float64), the shared ``settings``. Returns the number of
    environments whose episode ended; or, before any environment moved, a negative code
    (:func:`refusal`) when an active environment's episode ended on an earlier step and it was
    not reset (``batch.ended`` still set), when ``actions`` have another shape, or when an
    action is not finite. A few environments are one compiled call; many are spread over the
    cores (:func:`aeromag_env.threads.run_chunks`).
    """
    if num_envs < 2 * MIN_CHUNK:  # one chunk anyway (run_chunks would run it in this thread)
        return int(_env_step_all(limit, arrays, actions))
    code = int(_refused(arrays, actions))
    if code < 0:
        return code
    run_chunks(_env_step_range, num_envs, limit, arrays)
    return int(_count_ended(arrays))
