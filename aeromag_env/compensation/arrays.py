"""The arrays of a recursive compensator, grouped as the compiled loop takes them.

A filter is five groups of arrays (:class:`FilterArrays`): the input :class:`Signals`, the filter
:class:`State` (with its restart values, counters and settings), the innovation :class:`Window`,
the :class:`Outputs` and the :class:`Bank` of models (``imm``; zero models for every other
method, so that every method passes the same types to the one compiled loop).
:class:`~aeromag_env.compensation.kalman.FilterState` holds one filter's,
:class:`~aeromag_env.compensation.kalman_batch.BatchFilterState` N filters' stacked along a
leading flight axis, and :func:`row` takes flight i of the stacked arrays inside compiled code.
Calls from Python pass the groups :func:`packed` (plain tuples, which numba types faster), and
the compiled code names them again (:func:`named`).
The small vectors ``State.par`` (float settings), ``State.ints`` (counters) and ``Window.acc``
(running sums) are laid out in :mod:`aeromag_env.compensation.kernel_layout`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from aeromag_env.numba_cache import njit


class Signals(NamedTuple):
    """The inputs, one row per sample (n samples)."""

    y: np.ndarray  #: (n, 3) measurement ``T_m − T`` [nT] (0 where not finite)
    t: np.ndarray  #: (n, 3) model Earth field in body axes ``T`` [nT]
    td: np.ndarray  #: (n, 3) its rate ``Ṫ`` [nT/s]
    valid: np.ndarray  #: (n,) bool: all inputs finite (False → predict only)


class State(NamedTuple):
    """The filter, in normalised coordinates ``z = x / d``, updated in place."""

    d: np.ndarray  #: (21,) state normalisation
    z: np.ndarray  #: (21,) state
    p: np.ndarray  #: (21, 21) covariance P
    qd: np.ndarray  #: (21,) diagonal of Q
    rm: np.ndarray  #: (3, 3) R [nT²]
    z_good: np.ndarray  #: (21,) last healthy state (restart value)
    p0: np.ndarray  #: (21, 21) P(0) (restart value)
    q0: np.ndarray  #: (21,) Q(0) (restart value)
    r0: np.ndarray  #: (3, 3) R(0) (restart value)
    ints: np.ndarray  #: (N_INT,) int64 counters (kernel_layout.INTS)
    par: np.ndarray  #: (N_PAR,) float settings (kernel_layout.PAR)
    vb_shape: (
        np.ndarray
    )  #: (3,) shape of R's posterior: α per axis (vbakf), û − m − 1 (vbakf-pr, [0])


class Window(NamedTuple):
    """The last M innovations (a circular buffer) and their running sums."""

    rbuf: np.ndarray  #: (M, 3) innovations [nT]
    sbuf: np.ndarray  #: (M,) tr S of each [nT²]
    acc: np.ndarray  #: (N_ACC,) running sums (kernel_layout.ACC)


class Outputs(NamedTuple):
    """Written at row k when sample k is processed (n samples)."""

    est: np.ndarray  #: (n, 3) a-priori interference ``H(k) x(k|k−1)`` [nT]
    innov: np.ndarray  #: (n, 3) innovations [nT] (NaN where skipped)
    ror: np.ndarray  #: (n,) windowed ROR (eq. 22)
    qoq: np.ndarray  #: (n,) windowed QOQ
    q_scale: np.ndarray  #: (n,) tr Q / tr Q(0)
    r_scale: np.ndarray  #: (n,) tr R / tr R(0)
    states: np.ndarray  #: (n or 0, 21) posterior states [physical units]


class Bank(NamedTuple):
    """The m models of ``imm`` (m = 0 for the other methods), in normalised coordinates.

    Model j's Q and R are its scales times a base: the filter's current Q and R
    (``State.qd``, ``State.rm``, which an external controller may rescale) when it follows,
    else Q(0) and R(0). The filter's own ``State.z`` and ``State.p`` hold the combined
    estimate.
    """

    bank_z: np.ndarray  #: (m, 21) the models' states
    bank_p: np.ndarray  #: (m, 21, 21) their covariances
    bank_scale: np.ndarray  #: (m, 2) each model's Q and R scale over its base [-]
    bank_follow: np.ndarray  #: (m,) bool: the base is the current Q, R (else Q(0), R(0))
    bank_mu: np.ndarray  #: (m,) the models' probabilities
    bank_pi: np.ndarray  #: (m, m) switching matrix: (i, j) = P(model j at k | model i at k − 1)


class FilterArrays(NamedTuple):
    """Everything :func:`aeromag_env.compensation.kernels.advance` reads and writes."""

    signals: Signals
    state: State
    window: Window
    outputs: Outputs
    bank: Bank


#: The groups of :class:`FilterArrays`, in order.
GROUPS = (Signals, State, Window, Outputs, Bank)
#: Every array of a filter by name.
CORE_ARRAYS = tuple(name for group in GROUPS for name in group._fields)
#: The arrays whose first axis is the sample, and those whose first axis is the window.
TIME_ARRAYS = Signals._fields + Outputs._fields
WINDOW_ARRAYS = ("rbuf", "sbuf")
#: The bank's arrays and how many of their leading axes run over the models.
MODEL_AXES = {name: 2 if name == "bank_pi" else 1 for name in Bank._fields}


def filter_arrays(source: object) -> FilterArrays:
    """The arrays of ``source`` (an object with an attribute per name of :data:`CORE_ARRAYS`),
    grouped (the same arrays, not copies)."""

    def take(names: tuple[str, ...]) -> list[np.ndarray]:
        return [getattr(source, name) for name in names]

    return FilterArrays(
        Signals(*take(Signals._fields)),
        State(*take(State._fields)),
        Window(*take(Window._fields)),
        Outputs(*take(Outputs._fields)),
        Bank(*take(Bank._fields)),
    )


#: A NamedTuple of arrays (or of such NamedTuples) as plain tuples, see :func:`packed`.
Packed = tuple


def packed(arrays: tuple) -> Packed:
    """``arrays`` (a NamedTuple of arrays, or of such NamedTuples) as plain tuples of the same
    arrays, for a call from Python into compiled code: numba types a plain tuple argument ~0.6 µs
    faster per NamedTuple (an environment step passes seven); :func:`named` (or the NamedTuple
    class) gives the names back inside."""
    return tuple(packed(a) if isinstance(a, tuple) else a for a in arrays)


# named and row are inlined where they are called (numba IR): they only regroup views, and a
# call would count a reference to every array it passes (a single environment's step ~8% slower)
@njit(cache=True, inline="always")
def named(f: FilterArrays | Packed) -> FilterArrays:
    """The filter's arrays :func:`packed` (or already named) as :class:`FilterArrays`."""
    return FilterArrays(Signals(*f[0]), State(*f[1]), Window(*f[2]), Outputs(*f[3]), Bank(*f[4]))


@njit(cache=True, inline="always")
def row(f: FilterArrays, i: int) -> FilterArrays:
    """Flight i of stacked filter arrays (a leading flight axis): views of its rows, field for
    field as in the classes above."""
    g, s, w, o, b = f.signals, f.state, f.window, f.outputs, f.bank
    signals = Signals(g.y[i], g.t[i], g.td[i], g.valid[i])
    state = State(
        s.d[i],
        s.z[i],
        s.p[i],
        s.qd[i],
        s.rm[i],
        s.z_good[i],
        s.p0[i],
        s.q0[i],
        s.r0[i],
        s.ints[i],
        s.par[i],
        s.vb_shape[i],
    )
    window = Window(w.rbuf[i], w.sbuf[i], w.acc[i])
    outputs = Outputs(
        o.est[i], o.innov[i], o.ror[i], o.qoq[i], o.q_scale[i], o.r_scale[i], o.states[i]
    )
    bank = Bank(
        b.bank_z[i], b.bank_p[i], b.bank_scale[i], b.bank_follow[i], b.bank_mu[i], b.bank_pi[i]
    )
    return FilterArrays(signals, state, window, outputs, bank)
