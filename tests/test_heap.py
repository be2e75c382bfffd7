"""The heap release: freed small blocks go back to the system."""

import os
import sys

import numpy as np
import pytest

from azee_mj import heap


def resident_mb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/statm")
def test_freed_small_blocks_interleaved_with_live_ones_are_returned():
    # 160 MB of 1 kB arrays, one in ten kept: the heap cannot shrink from its top alone
    blocks = [np.ones(128) for _ in range(160_000)]
    kept = blocks[::10]
    del blocks
    before = resident_mb()
    if not heap.release():
        pytest.skip("the C library has no malloc_trim")
    after = resident_mb()
    assert before - after > 60, (before, after)
    assert all(float(k.sum()) == 128.0 for k in kept)  # the live ones are untouched
