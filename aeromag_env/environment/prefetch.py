"""Flights simulated ahead, in a worker process, for the vector environment's resets.

A reset simulates a flight (:func:`aeromag_env.environment.scenarios.make_episode`): 30–45 ms, as
long as hundreds of batched environment steps, and during training the learner leaves the second
core idle. So the vector environment names each environment's next flight as soon as the current one
starts (:meth:`FlightPrefetcher.expect`), a worker process simulates it meanwhile, and the reset
takes it (:meth:`FlightPrefetcher.take`). ``make_episode`` is deterministic, so a prepared
flight is exactly the one the reset would have simulated; a flight that is not ready yet is
simulated in the calling process instead of waited for (the worker's copy is dropped when it
comes), one that is no longer wanted (a reset with another seed) is ignored, and if the worker
fails the flight is simulated in the calling process.

The worker runs at its parent's priority. A flight it has not delivered when the reset comes is
simulated by the parent itself (and by the worker all the same), so a worker that a lower
priority lets other processes starve on a busy machine costs the learner the most: inside PPO's
training at 8 environments on a 2-core machine with a load of 8–11, the resets took 13.5–15.9 µs
per environment step with the worker at ``nice`` +10 and 1.8 µs at the parent's priority
(:data:`WORKER_NICENESS`). On an idle machine it has a core of its own either way.

The worker is a plain Python child (:func:`worker_main`) exchanging pickles over its stdin and
stdout: unlike ``multiprocessing``'s spawn it never re-imports the caller's main script, so a
script without an ``if __name__ == "__main__"`` guard is safe. It exits when its stdin closes.
It runs in a session of its own, so a Ctrl-C at the terminal (SIGINT to the foreground process
group) interrupts the caller only, which then closes the worker's stdin: the worker never prints
a ``KeyboardInterrupt`` traceback of its own.
"""

from __future__ import annotations

import contextlib
import os
import pickle
import signal
import subprocess
import sys
import threading
import weakref
from concurrent.futures import Future
from typing import IO, NamedTuple

import numpy as np

from aeromag_env.compensation.model import FilterConfig
from aeromag_env.environment.scenarios import make_episode

#: How much lower the worker's scheduling priority is than its parent's (POSIX ``nice``; 0: the
#: same, see the module docstring).
WORKER_NICENESS = 0


class FlightKey(NamedTuple):
    """What determines a flight: scenario, flight seed and length override [s]."""

    scenario: str
    flight_seed: int
    duration_s: float | None


class FlightArrays(NamedTuple):
    """The parts of an episode the vector environment keeps (see
    :class:`aeromag_env.environment.scenarios.Episode`): (n, 3) arrays [nT], [nT/s]."""

    filter_cfg: FilterConfig
    y: np.ndarray
    t_b: np.ndarray
    tdot_b: np.ndarray
    truth_interf: np.ndarray


def simulate(key: FlightKey) -> FlightArrays:
    """Simulate the flight of ``key`` (in whichever process calls it)."""
    ep = make_episode(key.scenario, key.flight_seed, key.duration_s)
    return FlightArrays(ep.filter_cfg, ep.y, ep.t_b, ep.tdot_b, ep.truth_interf)


class FlightPrefetcher:
    """One worker process simulating, in order, the flights the environments will need next."""

    def __init__(self) -> None:
        self._proc = subprocess.Popen(
            [sys.executable, "-c", f"from {__name__} import worker_main; worker_main()"],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            start_new_session=True,  # out of the terminal's process group: Ctrl-C is the caller's
        )
        self._lock = threading.Lock()
        self._queue: list[Future[FlightArrays]] = []  # requests sent, results not yet read
        self._pending: dict[int, tuple[FlightKey, Future[FlightArrays]]] = {}
        assert self._proc.stdout is not None
        threading.Thread(
            target=_read_results, args=(self._proc.stdout, self._queue, self._lock), daemon=True
        ).start()
        self._finalizer = weakref.finalize(self, _stop, self._proc)

    def expect(self, slot: int, key: FlightKey) -> None:
        """Slot ``slot`` will next need the flight ``key``: have it simulated."""
        old = self._pending.get(slot)
        if old is not None and old[0] == key:
            return
        future: Future[FlightArrays] = Future()
        try:
            with self._lock:
                assert self._proc.stdin is not None
                pickle.dump(key, self._proc.stdin)
                self._proc.stdin.flush()
                self._queue.append(future)
        except (OSError, ValueError):  # the worker is gone (or closed): take() simulates here
            future.set_exception(RuntimeError("prefetch worker stopped"))
        self._pending[slot] = (key, future)

    def take(self, slot: int, key: FlightKey) -> FlightArrays:
        """The flight ``key`` for slot ``slot``: the prepared one if that is what was expected
        and the worker has delivered it, else simulated here."""
        pending = self._pending.pop(slot, None)
        if pending is not None and pending[0] == key and pending[1].done():
            try:
                return pending[1].result()
            except Exception:  # worker gone or failed: simulate here (raises the same error)
                pass
        return simulate(key)

    def close(self) -> None:
        """Stop the worker (flights not yet taken are dropped)."""
        self._pending.clear()
        self._finalizer()


def _read_results(stream: IO[bytes], queue: list[Future], lock: threading.Lock) -> None:
    """Resolve the futures in request order as the worker's results arrive."""
    while True:
        try:
            result = pickle.load(stream)  # our own child's output: trusted
        except (EOFError, OSError, pickle.UnpicklingError):
            with lock:
                for future in queue:
                    future.set_exception(RuntimeError("prefetch worker stopped"))
                queue.clear()
            return
        with lock:
            future = queue.pop(0)
        if isinstance(result, BaseException):
            future.set_exception(result)
        else:
            future.set_result(result)


def _stop(proc: subprocess.Popen) -> None:
    if proc.stdin is not None:
        with contextlib.suppress(OSError):
            proc.stdin.close()
    try:
        proc.wait(timeout=5)
    except subprocess.TimeoutExpired:
        proc.kill()


def worker_main() -> None:
    """The worker: simulate each flight key read from stdin, write the flight (or the
    exception) to stdout; anything printed on the way goes to stderr. It ends quietly when its
    caller is gone (stdin closed, or its answer's pipe broken) and ignores SIGINT: an interrupt
    is the caller's to handle."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    results = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)
    requests = sys.stdin.buffer
    if WORKER_NICENESS and hasattr(os, "nice"):
        os.nice(WORKER_NICENESS)
    simulate(FlightKey("nominal", 0, 10.0))  # load what the first flight would (~1 s) now
    while True:
        try:
            key = pickle.load(requests)
        except (EOFError, pickle.UnpicklingError):  # stdin closed (or cut short): the end
            return
        try:
            out: object = simulate(key)
        except Exception as e:  # reported to the caller, which simulates it itself
            out = e
        try:
            pickle.dump(out, results)
            results.flush()
        except (BrokenPipeError, ValueError):  # the caller is gone: no one to answer
            os._exit(0)  # not exit(): its final flush of the broken pipe would print an error
