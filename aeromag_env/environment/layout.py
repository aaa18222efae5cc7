"""The layouts of the tuning environment's compiled state, each generated from one field list.

The compiled step (:mod:`aeromag_env.environment.kernels`) keeps an environment's running values
in a float vector ``run`` (:class:`Run`), reads its configuration's settings from a float vector
``par`` (:class:`StepPar`) and writes the step's outcome into a float vector ``outcome``
(:class:`Out`). Each NamedTuple class is the field list; the index tuples :data:`RUN`,
:data:`STEP_PAR`, :data:`OUT` and the sizes are generated from it (numba reads them as
compile-time constants), so counts and indices cannot drift. :class:`EnvArrays`,
:class:`EnvSettings` and :class:`BatchArrays` group the arrays the step takes; :class:`RewardForm`
codes the reward's forms. Light: no numba.
"""

from __future__ import annotations

import math
from enum import IntEnum
from itertools import accumulate
from typing import NamedTuple

import numpy as np


class Run(NamedTuple):
    """The running values of one environment (a float vector): each field's width in slots, in
    order (:data:`RUN` holds each field's first index). All are zero at a reset."""

    log_q: int = 1  #: ln of the cumulative Q scale (all 21 states, or with a T_p action A and B)
    log_r: int = 1  #: ln of the cumulative R scale
    sq_err: int = 1  #: sum of squared errors from score_start on [nT²]
    n_err: int = 1  #: their count
    log_qp: int = 1  #: ln of the cumulative Q scale of the permanent block T_p
    sq_flown: int = 1  #: sum of squared errors over every sample flown with an estimate [nT²]
    n_flown: int = 1  #: their count (the score of an episode that ends before score_start)
    # the running sums of the statistics (aeromag_env.environment.window_sums)
    win_r: int = 3  #: Σ r over the updates in the filter's statistics window, per axis [nT]
    win_rr: int = 1  #: Σ |r|² over them [nT²]
    white_rows: int = 1  #: finite innovation rows among the last M samples
    white_r: int = 3  #: Σ r over those rows, per axis [nT]
    white_rr: int = 1  #: Σ |r|² over them [nT²]
    white_link: int = 1  #: Σ r_k · r_prev over them, prev the finite row before k [nT²]
    white_last: int = 1  #: 1 + the last finite row summed so far (0: none)


class StepPar(NamedTuple):
    """The settings of one configuration the compiled step reads (a float vector, one slot per
    field; :data:`STEP_PAR` holds the indices; made by
    :func:`aeromag_env.environment.env.parameters`)."""

    k: int  #: decision window K [samples]
    recent: int  #: samples of the recent statistics [samples]
    log_s_max: int  #: ln s_max (relative mode)
    log_limit: int  #: ln scale_limit
    absolute: int  #: 1.0 in the absolute mode
    q_lo: int  #: absolute mode: log10 range of Q [decades]
    q_hi: int
    r_lo: int  #: of R
    r_hi: int
    qp_lo: int  #: of T_p's Q
    qp_hi: int
    split_q: int  #: 1.0 with a T_p action
    qp_gate: int  #: 1.0 when the T_p action is a switch
    reward_nt: int  #: the reward's error scale [nT]
    reward_form: int  #: the reward's form (RewardForm)
    penalty: int  #: the reward of a diverging step


class Out(NamedTuple):
    """The outcome of one step (a float vector, one slot per field; :data:`OUT` holds the
    indices)."""

    reward: int
    rmse: int  #: the window's RMS error [nT]
    ror: int  #: ROR at the end of the window
    qoq: int  #: QOQ at the end of the window
    q_scale: int  #: cumulative Q scale
    r_scale: int  #: cumulative R scale
    terminated: int  #: 1.0 when the filter diverged
    truncated: int  #: 1.0 at the end of the flight
    episode_rmse: int  #: the episode's RMSE so far [nT]
    qp_scale: int  #: cumulative Q scale of T_p


#: Index of each field (``run[RUN.log_q]``, ``run[RUN.win_r + i]``, ``par[STEP_PAR.k]``,
#: ``out[OUT.reward]``) and the vectors' sizes, generated from the field lists above.
RUN = Run(*list(accumulate(Run(), initial=0))[:-1])
STEP_PAR = StepPar(*range(len(StepPar._fields)))
OUT = Out(*range(len(Out._fields)))
N_RUN, N_STEP_PAR, N_OUT = sum(Run()), len(STEP_PAR), len(OUT)
#: ln 10, to turn the absolute mode's decades into the natural-log scales the step keeps.
LN10 = math.log(10.0)


class EnvArrays(NamedTuple):
    """One environment's arrays (the vector environment's: each with a leading environment axis)."""

    action: np.ndarray  #: (2 or 3,) float64 finite action (aeromag_env.environment.spaces.ACTIONS)
    run: np.ndarray  #: (N_RUN,) running values (RUN)
    truth: np.ndarray  #: (≥ n, 3) true interference [nT]
    obs: np.ndarray  #: (dim,) float32 observation (written)
    outcome: np.ndarray  #: (N_OUT,) outcome of the step (OUT, written)


class EnvSettings(NamedTuple):
    """What every environment of one configuration shares."""

    par: np.ndarray  #: (N_STEP_PAR,) parameters (STEP_PAR)
    obs_at: np.ndarray  #: int64 column of each observation or -1 (spaces.observation_positions)
    low: np.ndarray  #: (dim,) float32 lower bounds of the observation
    high: np.ndarray  #: (dim,) float32 upper bounds


class BatchArrays(NamedTuple):
    """The vector environment's per-environment arrays beside :class:`EnvArrays`, each (N,):
    what the batched step reads, and the step's bookkeeping it writes (so that one compiled
    call does a whole step: :func:`aeromag_env.environment.kernels.env_step_batch`)."""

    active: np.ndarray  #: bool: step environment i (False: it is restarting; its outcome zeroed)
    mode: np.ndarray  #: int64 filter method (FilterMode)
    n: np.ndarray  #: int64 flight length [samples]
    score_start: np.ndarray  #: int64 first scored sample
    steps: np.ndarray  #: int64 steps of the current episode (written)
    reward: np.ndarray  #: float64 reward of the step (written)
    terminated: np.ndarray  #: bool: the filter diverged (written)
    truncated: np.ndarray  #: bool: the flight's end, or the step limit (written)
    ended: np.ndarray  #: bool: terminated or truncated (written)


class RewardForm(IntEnum):
    """The reward's forms (:class:`aeromag_env.environment.config.RewardSpec`), as the compiled
    step reads them (``par[STEP_PAR.reward_form]``); their names, lower case, are the spec's
    values."""

    LOG = 0  #: −ln(1 + e)
    LINEAR = 1  #: −e
    SQUARED = 2  #: −e²
