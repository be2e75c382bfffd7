"""Where a posture solve's restarts begin.

Units: radians (metres for slide joints).
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterable, Iterator

import numpy as np

#: Restarts from the seeder's starts between two generic (natural, random) ones.
SEEDS_PER_GENERIC = 4


def generic_starts(
    natural: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    seed: int,
    q_start: np.ndarray,
    free: np.ndarray,
) -> Iterator[np.ndarray]:
    """The natural posture (unless it is the start), then random postures halfway between it
    and a uniform sample of the joint ranges (endless); the dofs outside ``free`` keep
    ``q_start``."""
    untouched = np.setdiff1d(np.arange(natural.size), free)
    attempt = 1
    while True:
        attempt += 1
        q = natural.copy()
        if attempt > 2 or np.allclose(q[free], q_start[free]):
            lo = np.maximum(lower[free], -np.pi)
            hi = np.minimum(upper[free], np.pi)
            # Seeded per attempt: a solve depends only on its problem and start.
            rng = np.random.default_rng((seed, attempt))
            q[free] = 0.5 * (q[free] + rng.uniform(lo, hi))
        q[untouched] = q_start[untouched]
        yield np.clip(q, lower, upper)


def restart_points(
    q_start: np.ndarray,
    restarts: int,
    seeder: Callable[[], Iterable[np.ndarray]] | None,
    generic: Iterator[np.ndarray],
) -> Iterator[tuple[np.ndarray, bool]]:
    """(start, from the seeder) of the restarts, in order: the start again (with
    self-collision off at first); then, from two restarts up, ``restarts - 1`` of the
    ``generic`` starts with every start of the ``seeder`` (other arm branches; asked for
    only now; None: none) between them, a generic one after every ``SEEDS_PER_GENERIC``
    seeds."""
    if restarts < 1:
        return
    yield q_start.copy(), False
    if restarts < 2:
        return
    seeds = seeder() if seeder is not None else ()
    gen = ((q, False) for q in itertools.islice(generic, restarts - 1))
    for k, q in enumerate(seeds, 1):
        yield q, True
        if k % SEEDS_PER_GENERIC == 0:
            yield from itertools.islice(gen, 1)
    yield from gen
