"""The layouts of the tuning environment's compiled state, each generated from one field list.

The compiled step (:mod:`aeromag_env.environment.kernels`) keeps an environment's running values
in a float vector ``run`` (:class:`Run`), reads its configuration's settings from a float vector
``par`` (:class:`StepPar`) and writes the step's outcome into a float vector ``outcome``
(:class:`Out`). Each NamedTuple class is the field list; the index tuples :data:`RUN`,
:data:`STEP_PAR`, :data:`OUT` and the sizes are generated from it (numba reads them as
compile-time constants), so counts and indices cannot drift. :class:`EnvArrays` and
:class:`EnvSettings` group the arrays the step takes. Light: no numba.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np


class Run(NamedTuple):
    """The running values of one environment (a float vector, one slot per field; :data:`RUN`
    holds the indices)."""

    log_q: int  #: ln of the cumulative Q scale (all 21 states, or with a T_p action A and B)
    log_r: int  #: ln of the cumulative R scale
    sq_err: int  #: sum of squared errors from score_start on [nT²]
    n_err: int  #: their count
    log_qp: int  #: ln of the cumulative Q scale of the permanent block T_p
    sq_flown: int  #: sum of squared errors over every sample flown with an estimate [nT²]
    n_flown: int  #: their count (the score of an episode that ends before score_start)


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
    reward_form: int  #: index of the reward form in REWARD_FORMS
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


#: Index of each field (``run[RUN.log_q]``, ``par[STEP_PAR.k]``, ``out[OUT.reward]``) and the
#: vectors' sizes, generated from the field lists above.
RUN = Run(*range(len(Run._fields)))
STEP_PAR = StepPar(*range(len(StepPar._fields)))
OUT = Out(*range(len(Out._fields)))
N_RUN, N_STEP_PAR, N_OUT = len(RUN), len(STEP_PAR), len(OUT)
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
