"""The innovation window of the recursive compensators: its circular buffers and running sums.

The window holds the last M innovations ``r`` and ``tr S`` (``rbuf``, ``sbuf``) and keeps the
sums of ``|r|²``, ``tr S`` and ``r rᵀ`` (``acc[ACC.rr]``, ``acc[ACC.s]``, ``acc[ACC.c:]``) from
which the loop (:mod:`aeromag_env.compensation.kernels`) reads ROR and QOQ (eqs. 22–24). The
sums run (add the new term, subtract the one leaving) and are summed afresh once per lap, and
whenever the term leaving carried nearly all of a sum: the environment's actions may swing R by
tens of decades within a window, and subtracting a 1e50 term from a sum of 1e-50 ones leaves
rounding error, even a negative sum.
"""

from __future__ import annotations

from aeromag_env.compensation.kernel_layout import ACC, INTS, RESUM_RATIO
from aeromag_env.numba_cache import njit

#: Compiled as :data:`aeromag_env.compensation.kernels.per_sample` (no allocation, no copies).
per_sample = njit(cache=True, _nrt=False)  # type: ignore[call-overload]


@per_sample
def window_add(r, trs, rbuf, sbuf, acc, ints) -> None:
    """Push one innovation into the circular window and update the running sums; re-sum them
    when the term that left carried nearly all of a sum (:data:`RESUM_RATIO`: subtracting it
    would leave rounding error for a sum, negative or ~1e-80 after R swung by decades)."""
    m = ints[INTS.window]
    pos = ints[INTS.pos]
    old_rr, old_s = 0.0, 0.0
    if ints[INTS.updates] == m:
        old_rr, old_s = rbuf[pos, 0] ** 2 + rbuf[pos, 1] ** 2 + rbuf[pos, 2] ** 2, sbuf[pos]
        acc[ACC.rr] -= old_rr
        acc[ACC.s] -= old_s
        for i in range(3):
            for j in range(3):
                acc[ACC.c + 3 * i + j] -= rbuf[pos, i] * rbuf[pos, j]
    for i in range(3):
        rbuf[pos, i] = r[i]
    sbuf[pos] = trs
    acc[ACC.rr] += r[0] ** 2 + r[1] ** 2 + r[2] ** 2
    acc[ACC.s] += trs
    for i in range(3):
        for j in range(3):
            acc[ACC.c + 3 * i + j] += r[i] * r[j]
    ints[INTS.pos] = (pos + 1) % m
    ints[INTS.updates] = min(ints[INTS.updates] + 1, m)
    if ints[INTS.pos] == 0:  # re-sum once per lap: no drift of the running sums
        for a in range(acc.shape[0]):
            acc[a] = 0.0
        window_sums(rbuf, sbuf, acc, ints[INTS.updates])
        acc[ACC.ref] = acc[ACC.rr] / m  # the outlier gate's reference for the next lap
    elif old_rr > RESUM_RATIO * acc[ACC.rr] or old_s > RESUM_RATIO * acc[ACC.s]:
        window_sums(rbuf, sbuf, acc, ints[INTS.updates])


@per_sample
def window_sums(rbuf, sbuf, acc, count) -> None:
    """The window's sums of |r|², tr S and r rᵀ over its first ``count`` entries, afresh."""
    acc[ACC.rr] = 0.0
    acc[ACC.s] = 0.0
    for a in range(9):
        acc[ACC.c + a] = 0.0
    for w in range(count):
        acc[ACC.rr] += rbuf[w, 0] ** 2 + rbuf[w, 1] ** 2 + rbuf[w, 2] ** 2
        acc[ACC.s] += sbuf[w]
        for i in range(3):
            for j in range(3):
                acc[ACC.c + 3 * i + j] += rbuf[w, i] * rbuf[w, j]
