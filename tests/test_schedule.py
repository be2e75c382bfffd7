"""The schedule's pure helpers."""

from __future__ import annotations

import math

import numpy as np

from azee_mj.schedule import clip_scalar


def test_clip_scalar_is_numpys_clip_to_the_bit():
    """``clip_scalar`` gives ``np.clip``'s value bit for bit: inside, outside and on the
    bounds, signed zeros on a zero bound, NaN, infinities."""
    rng = np.random.default_rng(5)
    xs = [*rng.normal(0.0, 2.0, 2000), 0.0, -0.0, 1.0, -1.0, math.inf, -math.inf, math.nan]
    bounds = [(-1.0, 1.0), (0.0, 1.0), (-1.0, 0.0), (-0.0, 0.0), (0.0, 0.0), (-0.0, 2.0)]
    for lo, hi in bounds:
        for x in xs:
            want = float(np.clip(np.float64(x), np.float64(lo), np.float64(hi)))
            got = float(clip_scalar(np.float64(x), np.float64(lo), np.float64(hi)))
            assert np.float64(got).tobytes() == np.float64(want).tobytes(), (x, lo, hi)
