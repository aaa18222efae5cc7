"""The layout of the compiled filter's small state vectors, named once.

The compiled loop (:mod:`aeromag_env.compensation.kernels`) keeps its settings and counters in
flat arrays that numba passes cheaply: the float parameter vector ``par`` (``PAR_*``), the
integer state ``ints`` (``INT_*``) and the window accumulators ``acc`` (``ACC_*``). The
environment's compiled step reads the same names.
"""

from __future__ import annotations

# indices of the float parameter vector
PAR_EPS, PAR_ETA, PAR_ZOOM_R, PAR_ZOOM_Q, PAR_FORGET, PAR_SH_B, PAR_LO, PAR_HI = range(8)
PAR_SH_Q, PAR_SH_INNOV = 8, 9
N_PAR = 10
# indices of the integer state vector; INT_OUT counts the samples the outlier gate rejected,
# INT_RUN the current run of consecutive ones, INT_CALM the samples accepted since the last
# rejection, INT_FELL_BACK 1 once an adaptive filter ran away and went on as the plain KF
INT_POS, INT_COUNT, INT_K, INT_DIV, INT_SINCE, INT_SKIP, INT_WINDOW, INT_INTERVAL = range(8)
INT_OUT, INT_RUN, INT_CALM, INT_FELL_BACK = 8, 9, 10, 11
N_INT = 12
# accumulators: sum |r|², sum tr S, sum r rᵀ (9) over the window; the mean |r|² of its last
# full lap (the outlier gate's reference); sum r (3) and sum |r|² over a run of rejections
ACC_RR, ACC_S, ACC_C = 0, 1, 2
ACC_REF, ACC_RUN, ACC_RUN_RR = 11, 12, 15
N_ACC = 16
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
#: steps of hostile actions (tests/test_faults_env.py's soak) never meet both.
GATE_NIS = 1e4
GATE_POWER = 1e5
#: Within a window after a rejection the power threshold is GATE_POWER_AFTER (10× the RMS): the
#: rest of a burst of noise is rejected too, not only its samples beyond GATE_POWER.
GATE_POWER_AFTER = 1e2
#: A whole window of consecutive rejections is a shift of the data (restart) when the power of
#: their mean is above SHIFT_FRACTION of their mean power (a step: ~1; zero-mean noise: ~1/M).
SHIFT_FRACTION = 0.5
#: An adaptive filter (fakf, ding, sage-husa) whose innovations' power exceeds RUNAWAY_POWER
#: times the measurements' over a window (its estimate 2× farther from the data than zero is)
#: has run away: it restarts and goes on as the plain KF. Clean runs stay below 0.3, and at the
#: start (a zero estimate) the ratio is 1. Measured: under 1e3 nT RMS noise over a flight fakf
#: reaches 6.6 (2.5e3 nT off) and Sage–Husa more; ding and kf stay below 1 (the noise level).
RUNAWAY_POWER = 4.0
