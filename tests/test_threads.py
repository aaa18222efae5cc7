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


def test_an_error_in_any_chunk_is_raised():
    def kernel(lo, hi):
        if hi == 64:
            raise ValueError(f"chunk {lo}-{hi}")

    with pytest.raises(ValueError, match="chunk"):
        run_chunks(kernel, 64)
