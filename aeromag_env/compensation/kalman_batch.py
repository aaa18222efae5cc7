"""Many flights' compensators advanced together by one compiled loop.

:class:`BatchFilterState` stacks the arrays of N
:class:`~aeromag_env.compensation.kalman.FilterState` objects along a leading flight axis;
:func:`advance_batch` runs the single-flight loop
:func:`aeromag_env.compensation.kernels.advance` on every flight, in compiled chunks spread over the
cores (:mod:`aeromag_env.threads`). Each flight goes through exactly the code a single flight
goes through, so the results are bitwise those of N separate filters (tested).

Flights may differ in length: the time axis is padded to the longest flight, a flight never
advances past its own length ``n[i]``, and the padding is never read. Banks of models (``imm``)
are padded alike to the largest bank; a flight's loop reads only its own models
(``ints[INTS.models]``). A flight slot can be
refilled with a new flight (an environment's reset) without touching the others.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from aeromag_env.compensation.arrays import (
    CORE_ARRAYS,
    MODEL_AXES,
    TIME_ARRAYS,
    WINDOW_ARRAYS,
    FilterArrays,
    Packed,
    filter_arrays,
    named,
    packed,
    row,
)
from aeromag_env.compensation.kalman import FilterResult, FilterState, _positive_finite
from aeromag_env.compensation.kernel_layout import INTS
from aeromag_env.compensation.kernels import advance
from aeromag_env.compensation.model import FilterConfig
from aeromag_env.errors import ConfigError
from aeromag_env.numba_cache import njit
from aeromag_env.threads import run_chunks


@njit(cache=True, nogil=True)
def _advance_range(
    lo: int, hi: int, modes: np.ndarray, k0: np.ndarray, k1: np.ndarray, arrays: Packed
) -> None:
    """Flights ``lo ≤ i < hi`` of :func:`advance_batch`."""
    f = named(arrays)
    for i in range(lo, hi):
        if k1[i] > k0[i]:
            advance(modes[i], k0[i], k1[i], row(f, i))


def advance_batch(
    modes: np.ndarray, k0: np.ndarray, k1: np.ndarray, f: FilterArrays | Packed
) -> None:
    """Advance flight i over samples ``k0[i] ≤ k < k1[i]``, for every i, on all cores.

    ``modes``, ``k0``, ``k1`` are (N,) int64; ``f`` holds the arrays of
    :func:`aeromag_env.compensation.kernels.advance` (or them :func:`packed`), each with a leading
    flight axis (N, ...); a caller advancing the same arrays again and again packs them once.
    """
    arrays = f if type(f) is tuple else packed(f)  # a plain tuple: packed already
    run_chunks(_advance_range, int(modes.shape[0]), modes, k0, k1, arrays)


class BatchFilterState:
    """The states of N recursive compensators, stacked (one flight per row).

    Parameters
    ----------
    states : N filter states (fresh or advanced); their arrays are copied in.

    Attributes
    ----------
    mode : (N,) int64 method per flight (:class:`aeromag_env.compensation.model.FilterMode`)
    n : (N,) int64 flight lengths [samples]
    every name of :data:`aeromag_env.compensation.arrays.CORE_ARRAYS` : that array with a
        leading axis N; time arrays are padded to ``n.max()`` samples, window buffers to the
        longest window, the bank's model axes to the largest bank.
    """

    y: np.ndarray
    t: np.ndarray
    td: np.ndarray
    valid: np.ndarray
    d: np.ndarray
    z: np.ndarray
    p: np.ndarray
    qd: np.ndarray
    rm: np.ndarray
    z_good: np.ndarray
    p0: np.ndarray
    q0: np.ndarray
    r0: np.ndarray
    rbuf: np.ndarray
    sbuf: np.ndarray
    acc: np.ndarray
    ints: np.ndarray
    par: np.ndarray
    est: np.ndarray
    innov: np.ndarray
    ror: np.ndarray
    qoq: np.ndarray
    q_scale: np.ndarray
    r_scale: np.ndarray
    states: np.ndarray
    vb_shape: np.ndarray
    bank_z: np.ndarray
    bank_p: np.ndarray
    bank_scale: np.ndarray
    bank_follow: np.ndarray
    bank_mu: np.ndarray
    bank_pi: np.ndarray

    def __init__(self, states: Sequence[FilterState]) -> None:
        if not states:
            raise ValueError("BatchFilterState needs at least one flight")
        self.mode = np.array([s.mode for s in states], dtype=np.int64)
        self.n = np.array([s.n for s in states], dtype=np.int64)
        self.cfgs = [s.cfg for s in states]
        self._arrays: FilterArrays | None = None
        first = states[0]
        for name in CORE_ARRAYS:
            shape = list(getattr(first, name).shape)
            if name in TIME_ARRAYS and shape[0] > 0:
                shape[0] = int(self.n.max())
            if name in WINDOW_ARRAYS:
                shape[0] = max(s.cfg.window for s in states)
            if name in MODEL_AXES:
                models = max(getattr(s, name).shape[0] for s in states)
                shape[: MODEL_AXES[name]] = [models] * MODEL_AXES[name]
            stacked = np.empty((len(states), *shape), dtype=getattr(first, name).dtype)
            setattr(self, name, stacked)
        for i, s in enumerate(states):
            self.load(i, s)

    @classmethod
    def from_flights(
        cls,
        cfgs: FilterConfig | Sequence[FilterConfig],
        y: Sequence[np.ndarray],
        t_b: Sequence[np.ndarray],
        tdot_b: Sequence[np.ndarray],
        store_states: bool = False,
    ) -> BatchFilterState:
        """Fresh filters for N flights: ``y[i]``, ``t_b[i]``, ``tdot_b[i]`` (n_i, 3) as in
        :class:`~aeromag_env.compensation.kalman.FilterState`; one config for all or one per
        flight."""
        per = [cfgs] * len(y) if isinstance(cfgs, FilterConfig) else list(cfgs)
        if not (len(per) == len(y) == len(t_b) == len(tdot_b)):
            raise ValueError("need as many configs (or one), y, t_b and tdot_b as flights")
        return cls([FilterState(*a, store_states) for a in zip(per, y, t_b, tdot_b, strict=True)])

    @property
    def num_flights(self) -> int:
        return int(self.n.size)

    @property
    def k(self) -> np.ndarray:
        """(N,) samples processed so far per flight."""
        return self.ints[:, INTS.k].copy()

    @property
    def divergences(self) -> np.ndarray:
        """(N,) restarts after a divergence so far per flight."""
        return self.ints[:, INTS.div].copy()

    @property
    def outliers_rejected(self) -> np.ndarray:
        """(N,) samples rejected by the outlier gate so far per flight."""
        return self.ints[:, INTS.out].copy()

    def load(self, i: int, state: FilterState) -> None:
        """Put ``state`` (a flight of any length) into slot ``i``, growing the padding if needed."""
        if state.n > self._capacity():
            self._grow(state.n)
        if state.cfg.window > self.rbuf.shape[1]:
            self._grow_window(state.cfg.window)
        if state.bank_z.shape[0] > self.bank_z.shape[1]:
            self._grow_bank(state.bank_z.shape[0])
        self.mode[i], self.n[i], self.cfgs[i] = state.mode, state.n, state.cfg
        for name in CORE_ARRAYS:
            src, dst = getattr(state, name), getattr(self, name)[i]
            if name in TIME_ARRAYS or name in WINDOW_ARRAYS:
                m = min(src.shape[0], dst.shape[0])  # a state history kept on one side only
                dst[:m] = src[:m]
                dst[m:] = _PAD[dst.dtype.kind]
            elif name in MODEL_AXES:  # the flight's models in the leading corner
                dst[...] = _PAD[dst.dtype.kind]
                dst[tuple(slice(0, size) for size in src.shape)] = src
            else:
                dst[...] = src

    def arrays(self) -> FilterArrays:
        """The stacked arrays, grouped as the compiled loop takes them."""
        if self._arrays is None:  # built once per allocation: an env step asks every time
            self._arrays = filter_arrays(self)
        return self._arrays

    def advance(self, k1: int | np.ndarray) -> None:
        """Run every flight from its current sample up to (not including) ``k1`` (scalar or
        (N,)), never past its own length."""
        target = np.minimum(np.broadcast_to(np.asarray(k1, dtype=np.int64), self.n.shape), self.n)
        advance_batch(self.mode, self.k, target, self.arrays())

    def scale_noise(self, s_q: float | np.ndarray, s_r: float | np.ndarray) -> None:
        """Multiply Q and R of flight i by ``s_q[i]`` and ``s_r[i]`` (scalars: all flights).

        Each factor must be a finite real number > 0, as for
        :meth:`~aeromag_env.compensation.kalman.FilterState.scale_noise`, and an array must hold
        one per flight: a one-line ConfigError otherwise, raised before any matrix changes.
        """
        q, r = self._factors("s_q", s_q), self._factors("s_r", s_r)
        self.qd *= q[:, None]
        self.rm *= r[:, None, None]

    def _factors(self, name: str, s: float | np.ndarray) -> np.ndarray:
        """``s`` as (N,) float64 factors, checked (see :meth:`scale_noise`)."""
        if np.ndim(s) == 0:
            value = s.item() if isinstance(s, np.ndarray) else s
            if not _positive_finite(value):
                raise ConfigError(f"scale_noise: {name} must be a finite number > 0, got {s!r}")
            return np.full(self.num_flights, float(value))
        a = np.asarray(s)
        if a.shape != (self.num_flights,) or a.dtype.kind not in "iuf":
            raise ConfigError(
                f"scale_noise: {name} must be a number or {self.num_flights} real numbers "
                f"(one per flight), got shape {a.shape} of {a.dtype}"
            )
        bad = np.flatnonzero(~(np.isfinite(a) & (a > 0)))
        if bad.size:
            i = int(bad[0])
            got = a[i].item()
            raise ConfigError(f"scale_noise: {name}[{i}] must be a finite number > 0, got {got!r}")
        return a.astype(np.float64)

    def result(self, i: int) -> FilterResult:
        """Outputs of flight ``i`` so far, in physical units (as :meth:`FilterState.result`)."""
        n, d = int(self.n[i]), self.d[i]
        return FilterResult(
            interference=self.est[i, :n],
            innovations=self.innov[i, :n],
            ror=self.ror[i, :n],
            qoq=self.qoq[i, :n],
            q_scale=self.q_scale[i, :n],
            r_scale=self.r_scale[i, :n],
            states=self.states[i, :n],
            final_state=self.z[i] * d,
            final_covariance=self.p[i] * np.outer(d, d),
            final_r=self.rm[i].copy(),
            final_q=self.qd[i] * d**2,
            divergences=int(self.ints[i, INTS.div]),
            skipped=int(self.ints[i, INTS.skip]),
            outliers_rejected=int(self.ints[i, INTS.out]),
        )

    def _capacity(self) -> int:
        return int(self.y.shape[1])

    def _grow(self, n: int) -> None:
        for name in TIME_ARRAYS:
            old = getattr(self, name)
            if old.shape[1] == 0:  # states not stored
                continue
            new = np.full((old.shape[0], n, *old.shape[2:]), _PAD[old.dtype.kind], old.dtype)
            new[:, : old.shape[1]] = old
            setattr(self, name, new)
        self._arrays = None

    def _grow_window(self, m: int) -> None:
        for name in WINDOW_ARRAYS:
            old = getattr(self, name)
            new = np.zeros((old.shape[0], m, *old.shape[2:]), old.dtype)
            new[:, : old.shape[1]] = old
            setattr(self, name, new)
        self._arrays = None

    def _grow_bank(self, m: int) -> None:
        for name, axes in MODEL_AXES.items():
            old = getattr(self, name)
            new = np.full((old.shape[0], *[m] * axes, *old.shape[1 + axes :]), _PAD[old.dtype.kind])
            new[tuple(slice(0, size) for size in old.shape)] = old
            setattr(self, name, new)
        self._arrays = None


#: Padding beyond a flight's end, by dtype kind: never read by the loop, NaN in outputs.
_PAD = {"f": np.nan, "b": False, "i": 0}
