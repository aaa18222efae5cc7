import numpy as np
import pytest

from aeromag_env.threads import MIN_CHUNK, cores, run_chunks


def test_chunks_cover_every_index_once():
    for n in (1, MIN_CHUNK - 1, 2 * MIN_CHUNK, 64, 101):
        seen = np.zeros(n, int)

        def kernel(lo, hi, out):
            out[lo:hi] += 1

        run_chunks(kernel, n, seen)
        np.testing.assert_array_equal(seen, 1)
    assert cores() >= 1


def test_one_core_runs_a_large_batch_as_one_chunk(monkeypatch):
    from aeromag_env import threads

    monkeypatch.setattr(threads, "cores", lambda: 1)
    chunks = []
    run_chunks(lambda lo, hi: chunks.append((lo, hi)), 64)
    assert chunks == [(0, 64)]


def test_an_error_in_any_chunk_is_raised():
    def kernel(lo, hi):
        if hi == 64:
            raise ValueError(f"chunk {lo}-{hi}")

    with pytest.raises(ValueError, match="chunk"):
        run_chunks(kernel, 64)


def test_map_threads_keeps_order_runs_on_several_threads_and_re_raises(monkeypatch) -> None:
    import threading

    from aeromag_env import threads

    monkeypatch.setattr(threads, "cores", lambda: 3)
    seen: set[str] = set()
    barrier = threading.Barrier(3, timeout=120)  # generous: threads on busy cores start late

    def work(i: int) -> int:
        seen.add(threading.current_thread().name)
        barrier.wait()  # only returns when three threads are inside at once
        return i * i

    assert threads.map_threads(work, range(3)) == [0, 1, 4]
    assert len(seen) == 3

    def boom(i: int) -> int:
        if i == 2:
            raise ValueError("axis 2")
        return i

    with pytest.raises(ValueError, match="axis 2"):
        threads.map_threads(boom, range(3))
    monkeypatch.setattr(threads, "cores", lambda: 1)
    assert threads.map_threads(lambda i: i + 1, range(3)) == [1, 2, 3]
