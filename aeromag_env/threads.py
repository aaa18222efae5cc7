"""Spread a compiled kernel over the cores: contiguous chunks of N flights, one Python thread each.

The batched kernels (:func:`aeromag_env.compensation.kalman_batch.advance_batch`,
:func:`aeromag_env.environment.kernels.env_step_batch`) are serial numba loops over a range of
flights compiled with ``nogil=True``; :func:`run_chunks` calls them on disjoint chunks from a small
thread pool, so they run in parallel. Why not numba's ``parallel=True`` / ``prange``: compiling
those kernels took 10–12 s each on a cold cache (the loop body is recompiled for the parallel
target), and the default OpenMP layer spin-waits between steps — with another process busy on
these 2-core machines a 64-environment step took 8 ms instead of 0.8 ms. Threads that block
instead of spinning cost ~20 µs per call.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import TypeVar

T = TypeVar("T")
R = TypeVar("R")

#: A thread gets at least this many flights (fewer: not worth the hand-over).
MIN_CHUNK = 8


def cores() -> int:
    """CPU cores this process may run on."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def run_chunks(kernel: Callable[..., object], n: int, *args: object) -> None:
    """``kernel(lo, hi, *args)`` for contiguous chunks ``[lo, hi)`` covering ``[0, n)``, on up
    to :func:`cores` threads (this one included); returns when all are done, re-raising the
    first error (what the kernel returns is dropped)."""
    # (cores() is a system call, skipped when there is one chunk anyway: a small batch's step)
    workers = 1 if n < 2 * MIN_CHUNK else min(cores(), n // MIN_CHUNK)
    if workers == 1:
        kernel(0, n, *args)
        return
    pool = _pool(workers - 1)
    bounds = [n * w // workers for w in range(workers + 1)]
    futures = [pool.submit(kernel, bounds[w], bounds[w + 1], *args) for w in range(1, workers)]
    kernel(bounds[0], bounds[1], *args)
    for f in futures:
        f.result()


def map_threads(fn: Callable[[T], R], items: Sequence[T]) -> list[R]:
    """``[fn(x) for x in items]``, the items spread over up to :func:`cores` threads (this one
    included), in order; for independent calls that spend their time in ``nogil`` kernels (the
    three axes of the discovery noise model). Re-raises the first error."""
    workers = max(1, min(cores(), len(items)))
    if workers == 1:
        return [fn(x) for x in items]
    pool = _pool(workers - 1)
    futures = [pool.submit(fn, x) for x in items[1:]]
    first = fn(items[0])
    return [first, *(f.result() for f in futures)]


@functools.cache
def _pool(size: int) -> ThreadPoolExecutor:
    return ThreadPoolExecutor(max_workers=size, thread_name_prefix="aeromag")
