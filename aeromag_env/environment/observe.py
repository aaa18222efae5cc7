"""The compiled writers of the observations, one per entry of the registry.

Each writer computes one observation of :data:`aeromag_env.environment.observations.REGISTRY`
at the end of the decision window ``k0 ≤ k < k1`` of a flight of ``n`` samples, from the
environment's and the filter's arrays; :func:`observe` writes those the configuration chooses
at their columns (``settings.obs_at``, by registry id) and clips them to their bounds. The
statistics themselves are in :mod:`aeromag_env.environment.statistics`; the running sums that
some of them read are kept around the filter's advance by :func:`take_leaving_updates` and
:func:`keep_sums`, only for the observations the configuration chooses.
"""

from __future__ import annotations

import math

from aeromag_env.compensation.arrays import FilterArrays
from aeromag_env.compensation.kernel_layout import INTS
from aeromag_env.environment.layout import LN10, RUN, STEP_PAR, EnvArrays, EnvSettings
from aeromag_env.environment.observations import OBS_LIMIT, observation_id
from aeromag_env.environment.statistics import (
    innovation_bias_running,
    log10_or_zero,
    power_of_mean,
    recent_ratio,
    step_statistic_running,
    turn_rate,
    whiteness_running,
    window_power,
)
from aeromag_env.environment.window_sums import (
    Taken,
    WindowMark,
    per_step,
    put_updates,
    slide_samples,
    take_leaving,
)

# Each observation's registry id (an unknown name fails here, at import).
LOG_ROR = observation_id("log_ror")
LOG_QOQ = observation_id("log_qoq")
LOG_Q_SCALE = observation_id("log_q_scale")
LOG_R_SCALE = observation_id("log_r_scale")
WHITENESS = observation_id("whiteness")
PROGRESS = observation_id("progress")
LOG_RECENT_ROR = observation_id("log_recent_ror")
LOG_QP_SCALE = observation_id("log_qp_scale")
LOG_INNOVATION_POWER = observation_id("log_innovation_power")
LOG_MEAN_INNOVATION_POWER = observation_id("log_mean_innovation_power")
LOG_STEP_STATISTIC = observation_id("log_step_statistic")
LOG_TURN_RATE = observation_id("log_turn_rate")
LOG_INNOVATION_BIAS = observation_id("log_innovation_bias")


@per_step
def _log_ror(k0: int, k1: int, n: int, env: EnvArrays, s: EnvSettings, f: FilterArrays) -> float:
    return log10_or_zero(f.outputs.ror[k1 - 1])


@per_step
def _log_qoq(k0: int, k1: int, n: int, env: EnvArrays, s: EnvSettings, f: FilterArrays) -> float:
    return log10_or_zero(f.outputs.qoq[k1 - 1])


@per_step
def _log_q_scale(
    k0: int, k1: int, n: int, env: EnvArrays, s: EnvSettings, f: FilterArrays
) -> float:
    return env.run[RUN.log_q] / LN10


@per_step
def _log_r_scale(
    k0: int, k1: int, n: int, env: EnvArrays, s: EnvSettings, f: FilterArrays
) -> float:
    return env.run[RUN.log_r] / LN10


@per_step
def _whiteness(k0: int, k1: int, n: int, env: EnvArrays, s: EnvSettings, f: FilterArrays) -> float:
    return whiteness_running(k1, f.state.ints[INTS.window], f.outputs.innov, env.run)


@per_step
def _progress(k0: int, k1: int, n: int, env: EnvArrays, s: EnvSettings, f: FilterArrays) -> float:
    return k1 / n


@per_step
def _log_recent_ror(
    k0: int, k1: int, n: int, env: EnvArrays, s: EnvSettings, f: FilterArrays
) -> float:
    short = recent_ratio(int(s.par[STEP_PAR.recent]), f.state.ints, f.window.rbuf, f.window.sbuf)
    return log10_or_zero(max(short, 1e-8)) if short > 0.0 else 0.0


@per_step
def _log_qp_scale(
    k0: int, k1: int, n: int, env: EnvArrays, s: EnvSettings, f: FilterArrays
) -> float:
    return env.run[RUN.log_qp] / LN10


@per_step
def _log_innovation_power(
    k0: int, k1: int, n: int, env: EnvArrays, s: EnvSettings, f: FilterArrays
) -> float:
    """Over tr R(0): the noise level, whatever R is."""
    r0 = f.state.r0
    power = window_power(f.state.ints, f.window.acc)
    return log10_or_zero(power / (r0[0, 0] + r0[1, 1] + r0[2, 2]))


@per_step
def _log_mean_innovation_power(
    k0: int, k1: int, n: int, env: EnvArrays, s: EnvSettings, f: FilterArrays
) -> float:
    """Over tr R(0): a step, whatever R is."""
    r0 = f.state.r0
    mean_power = power_of_mean(int(s.par[STEP_PAR.recent]), f.state.ints, f.window.rbuf)
    return log10_or_zero(mean_power / (r0[0, 0] + r0[1, 1] + r0[2, 2]))


@per_step
def _log_step_statistic(
    k0: int, k1: int, n: int, env: EnvArrays, s: EnvSettings, f: FilterArrays
) -> float:
    m = int(s.par[STEP_PAR.recent])
    return log10_or_zero(step_statistic_running(m, f.state.ints, f.window.rbuf, env.run))


@per_step
def _log_turn_rate(
    k0: int, k1: int, n: int, env: EnvArrays, s: EnvSettings, f: FilterArrays
) -> float:
    """0 (no turn seen) → the lower bound."""
    g = f.signals
    rate = turn_rate(k0, k1, g.t, g.td, g.valid)
    return math.log10(rate) if rate > 0.0 else -OBS_LIMIT


@per_step
def _log_innovation_bias(
    k0: int, k1: int, n: int, env: EnvArrays, s: EnvSettings, f: FilterArrays
) -> float:
    return log10_or_zero(innovation_bias_running(f.state.ints, f.window.rbuf, env.run))


@per_step
def _update_sums_read(s: EnvSettings) -> bool:
    """An observation reads the running sums over the window's updates."""
    return s.obs_at[LOG_STEP_STATISTIC] >= 0 or s.obs_at[LOG_INNOVATION_BIAS] >= 0


@per_step
def take_leaving_updates(
    k0: int, k1: int, env: EnvArrays, s: EnvSettings, f: FilterArrays
) -> Taken:
    """Before the filter advances over ``k0 ≤ k < k1``: what
    :func:`aeromag_env.environment.window_sums.take_leaving` takes out of the running sums over
    the window's updates, when an observation reads them (else nothing)."""
    if not _update_sums_read(s):
        return Taken(0, 0.0)
    return take_leaving(k1 - k0, f.state.ints, f.window.rbuf, env.run)


@per_step
def keep_sums(
    k0: int,
    k1: int,
    taken: Taken,
    before: WindowMark,
    env: EnvArrays,
    s: EnvSettings,
    f: FilterArrays,
) -> None:
    """After the filter advanced over ``k0 ≤ k < k1`` from the window ``before``, ``taken``
    what :func:`take_leaving_updates` took out: bring the running sums the chosen observations
    read up to date (:mod:`aeromag_env.environment.window_sums`)."""
    ints = f.state.ints
    if _update_sums_read(s):
        put_updates(taken, before, ints, f.window.rbuf, env.run)
    if s.obs_at[WHITENESS] >= 0:
        slide_samples(k0, k1, ints[INTS.window], f.outputs.innov, env.run)


@per_step
def observe(k0: int, k1: int, n: int, env: EnvArrays, s: EnvSettings, f: FilterArrays) -> None:
    """Write the observation at the end of the window ``k0 ≤ k < k1`` (float32, clipped to the
    bounds): each chosen registry entry at its column ``s.obs_at[id]``."""
    obs, at = env.obs, s.obs_at
    if at[LOG_ROR] >= 0:
        obs[at[LOG_ROR]] = _log_ror(k0, k1, n, env, s, f)
    if at[LOG_QOQ] >= 0:
        obs[at[LOG_QOQ]] = _log_qoq(k0, k1, n, env, s, f)
    if at[LOG_Q_SCALE] >= 0:
        obs[at[LOG_Q_SCALE]] = _log_q_scale(k0, k1, n, env, s, f)
    if at[LOG_R_SCALE] >= 0:
        obs[at[LOG_R_SCALE]] = _log_r_scale(k0, k1, n, env, s, f)
    if at[WHITENESS] >= 0:
        obs[at[WHITENESS]] = _whiteness(k0, k1, n, env, s, f)
    if at[PROGRESS] >= 0:
        obs[at[PROGRESS]] = _progress(k0, k1, n, env, s, f)
    if at[LOG_RECENT_ROR] >= 0:
        obs[at[LOG_RECENT_ROR]] = _log_recent_ror(k0, k1, n, env, s, f)
    if at[LOG_QP_SCALE] >= 0:
        obs[at[LOG_QP_SCALE]] = _log_qp_scale(k0, k1, n, env, s, f)
    if at[LOG_INNOVATION_POWER] >= 0:
        obs[at[LOG_INNOVATION_POWER]] = _log_innovation_power(k0, k1, n, env, s, f)
    if at[LOG_MEAN_INNOVATION_POWER] >= 0:
        obs[at[LOG_MEAN_INNOVATION_POWER]] = _log_mean_innovation_power(k0, k1, n, env, s, f)
    if at[LOG_STEP_STATISTIC] >= 0:
        obs[at[LOG_STEP_STATISTIC]] = _log_step_statistic(k0, k1, n, env, s, f)
    if at[LOG_TURN_RATE] >= 0:
        obs[at[LOG_TURN_RATE]] = _log_turn_rate(k0, k1, n, env, s, f)
    if at[LOG_INNOVATION_BIAS] >= 0:
        obs[at[LOG_INNOVATION_BIAS]] = _log_innovation_bias(k0, k1, n, env, s, f)
    for j in range(obs.shape[0]):
        obs[j] = min(max(obs[j], s.low[j]), s.high[j])
