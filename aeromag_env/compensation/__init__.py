"""Compensation: estimate the aircraft's interference and score the estimate.

:mod:`.model` (the 21-state measurement model, filter configuration and modes), :mod:`.kernels`
(the compiled per-sample loop), :mod:`.kalman` (the stateful filter over it), :mod:`.kalman_batch`
(many flights in one compiled call), :mod:`.kalman_reference` (plain numpy, for the tests),
:mod:`.fuzzy` (the paper's FIS), :mod:`.least_squares` (the batch optimum), :mod:`.tolles_lawson`,
:mod:`.dsp`, :mod:`.metrics`, :mod:`.compensate` (one method on one flight) and :mod:`.paper`
(the paper's §4 reproduced).
"""
