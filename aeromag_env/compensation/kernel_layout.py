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
# indices of the integer state vector
INT_POS, INT_COUNT, INT_K, INT_DIV, INT_SINCE, INT_SKIP, INT_WINDOW, INT_INTERVAL = range(8)
N_INT = 8
# accumulators: sum |r|², sum tr S, sum r rᵀ (9)
ACC_RR, ACC_S, ACC_C = 0, 1, 2
N_ACC = 11
#: A normalised state beyond this (1e8 typical magnitudes, e.g. T_p > 1e10 nT) is a divergence.
MAX_STATE = 1e8
