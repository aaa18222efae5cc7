"""One object holding every array of a vector environment's step, taken by the compiled step as
one argument.

numba unboxes every array argument of a call from Python, and the vector environment's step
passes about forty (the environments' arrays, their settings, the stacked filters' and the
step's bookkeeping: :class:`~aeromag_env.environment.layout.BatchArrays`): ~8 µs a call on these
machines, as much as two environments' statistics and bookkeeping. :class:`StepArrays`, a numba
StructRef holding the four groups (each :func:`~aeromag_env.compensation.arrays.packed`), is
unboxed in ~2.5 µs whatever it holds. The vector environment builds it once per allocation of
its arrays (a reset may grow them) and passes it to
:func:`aeromag_env.environment.kernels.env_step_batch` at every step; it holds the arrays
themselves (references, not copies), so they live as long as it does.
"""

from __future__ import annotations

from typing import Any

from numba import types
from numba.experimental import structref

from aeromag_env.compensation.arrays import Packed
from aeromag_env.numba_cache import njit


@structref.register
class StepArraysType(types.StructRef):
    """numba's type of :class:`StepArrays` (its fields' types as given, literals widened)."""

    def preprocess_fields(self, fields: Any) -> tuple:
        return tuple((name, types.unliteral(typ)) for name, typ in fields)


class StepArrays(structref.StructRefProxy):
    """The packed groups of a vector environment's step: ``batch``
    (:class:`~aeromag_env.environment.layout.BatchArrays`), ``envs``
    (:class:`~aeromag_env.environment.layout.EnvArrays`), ``settings``
    (:class:`~aeromag_env.environment.layout.EnvSettings`) and ``filters``
    (:class:`~aeromag_env.compensation.arrays.FilterArrays`); build it with :func:`step_arrays`."""

    # its fields, for the type checker: compiled code reads them (Python does not)
    batch: Packed
    envs: Packed
    settings: Packed
    filters: Packed


structref.define_proxy(StepArrays, StepArraysType, ["batch", "envs", "settings", "filters"])


@njit(cache=True)
def _new(batch: Packed, envs: Packed, settings: Packed, filters: Packed) -> StepArrays:
    return StepArrays(batch, envs, settings, filters)


def step_arrays(batch: Packed, envs: Packed, settings: Packed, filters: Packed) -> StepArrays:
    """The :class:`StepArrays` of the packed groups (built by compiled code, which numba caches:
    the proxy's own constructor would be compiled again in every process)."""
    return _new(batch, envs, settings, filters)
