"""The layout of the compiled filter's small state vectors, named once.

The compiled loop (:mod:`aeromag_env.compensation.kernels`) keeps its settings and counters in
flat arrays that numba passes cheaply: the float parameter vector ``par``, the integer state
``ints`` and the window accumulators ``acc``. Each is laid out by one field list (the
NamedTuples :class:`Par`, :class:`Ints`, :class:`Acc`); the indices (:data:`PAR`, :data:`INTS`,
:data:`ACC`) and sizes are generated from it, so they cannot drift apart. numba reads the index
tuples as compile-time constants.
"""

from __future__ import annotations

from itertools import accumulate
from typing import NamedTuple


class Par(NamedTuple):
    """The float parameter vector ``par``: one slot per field, in this order (the instance
    :data:`PAR` holds each field's index)."""

    eps: int  #: ε of the R rule
    eta: int  #: η of the Q rule
    zoom_r: int  #: zoom level b_r (exponent of the R factor)
    zoom_q: int  #: zoom level b_a (exponent of the Q factor)
    forget: int  #: forgetting factor (rls)
    sh_b: int  #: Sage–Husa fading factor b
    lo: int  #: lower bound of a per-step scale factor
    hi: int  #: upper bound of a per-step scale factor
    sh_q: int  #: 1.0 when Sage–Husa also estimates Q
    sh_innov: int  #: 1.0 for Sage–Husa's innovation form
    vb_rho: int  #: forgetting factor ρ of the variational filters
    vb_prior: int  #: their prior's weight: α₀ (vbakf) or û₀ − m − 1 (vbakf-pr)
    vb_tau: int  #: τ, the weight of the nominal P⁻ in vbakf-pr's prior
    mmae: int  #: 1.0 when the bank of imm runs as MMAE (no mixing)


class Ints(NamedTuple):
    """The integer state vector ``ints``: one slot per field (:data:`INTS` holds the indices)."""

    pos: int  #: next slot of the circular innovation window
    updates: int  #: updates in the window (≤ M)
    k: int  #: samples processed (the next sample)
    div: int  #: restarts after a divergence
    since: int  #: updates since the last adaptation
    skip: int  #: samples skipped (invalid inputs)
    window: int  #: M, the window's size
    interval: int  #: updates between two adaptations
    out: int  #: samples the outlier gate rejected
    run: int  #: the current run of consecutive rejections
    calm: int  #: samples accepted since the last rejection
    fell_back: int  #: 1 once an adaptive filter ran away and went on as the plain KF
    base: int  #: samples processed before row 0 of the arrays (a continued or streamed filter)
    iterations: int  #: fixed-point iterations per sample of the variational filters
    models: int  #: m, the models of imm's bank (0 for the other methods)


class Acc(NamedTuple):
    """The window accumulators ``acc``: each field's width in slots, in order (:data:`ACC`
    holds each field's first index)."""

    rr: int = 1  #: sum |r|² over the window
    s: int = 1  #: sum tr S over the window
    c: int = 9  #: sum r rᵀ over the window (row-major 3×3)
    ref: int = 1  #: mean |r|² of the window's last full lap (the outlier gate's reference)
    run: int = 3  #: sum r over a run of rejections
    run_rr: int = 1  #: sum |r|² over a run of rejections


#: Index of each field of ``par``, ``ints`` and ``acc`` (``par[PAR.eps]``, ``acc[ACC.c + j]``).
PAR = Par(*range(len(Par._fields)))
INTS = Ints(*range(len(Ints._fields)))
ACC = Acc(*list(accumulate(Acc(), initial=0))[:-1])
#: Sizes of the three vectors.
N_PAR, N_INT, N_ACC = len(PAR), len(INTS), sum(Acc())
#: The window's running sums are summed afresh when the term leaving carried more than
#: RESUM_RATIO times what is left (8 of 16 digits lost to the subtraction): actions that swing
#: R by decades within a window. Clean runs never come near it (their terms span < 1e4).
RESUM_RATIO = 1e8
#: A normalised state beyond this (1e8 typical magnitudes, e.g. T_p > 1e10 nT) is a divergence.
MAX_STATE = 1e8
#: Outlier gate (:mod:`aeromag_env.compensation.consistency`): a sample's innovation is rejected
#: when its normalised square ``rᵀ S⁻¹ r`` exceeds GATE_NIS (100 σ of the filter's own
#: prediction) and its power ``|r|²`` exceeds GATE_POWER times the recent mean (316× the recent
#: RMS innovation). Clean runs stay below 2e3 of the second (measured: every scenario, method
#: and preset on 4 flights each, the 7 policies of ``aeromag evaluate``); an interference step
#: of 5 σ on every axis in the quietest noise regime of ``nonstationary`` would reach ~2e4; 1e6
#: steps of hostile actions (tests/environment/test_faults_env.py's soak) never meet both.
GATE_NIS = 1e4
GATE_POWER = 1e5
#: Within a window after a rejection the power threshold is GATE_POWER_AFTER (10× the RMS): the
#: rest of a burst of noise is rejected too, not only its samples beyond GATE_POWER.
GATE_POWER_AFTER = 1e2
#: A whole window of consecutive rejections is a shift of the data (restart) when the power of
#: their mean is above SHIFT_FRACTION of their mean power (a step: ~1; zero-mean noise: ~1/M).
SHIFT_FRACTION = 0.5
#: An adaptive filter (fakf, ding, sage-husa, vbakf, vbakf-pr) whose innovations' power exceeds
#: RUNAWAY_POWER times the measurements' over a window (its estimate 2× farther from the data
#: than zero is) has run away: it restarts and goes on as the plain KF. Clean runs stay below
#: 0.3, and at the start (a zero estimate) the ratio is 1. Measured: under 1e3 nT RMS noise over
#: a flight fakf reaches 6.6 (2.5e3 nT off) and Sage–Husa more; ding and kf stay below 1 (the
#: noise level).
RUNAWAY_POWER = 4.0
