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


#: Starts drawn over the whole joint ranges when nothing has met a problem, and how many
#: more are tried once one meets (the most natural meet kept).
WIDE_STARTS = 16
WIDE_AFTER_MEET = 6


def wide_starts(
    lower: np.ndarray, upper: np.ndarray, seed: int, q_start: np.ndarray, drawn: np.ndarray
) -> Iterator[np.ndarray]:
    """Postures with the ``drawn`` dofs uniform over their whole ranges (within [-pi, pi]),
    the others at ``q_start`` (endless). Unlike :func:`generic_starts` they do not lean
    toward the natural posture: a hand behind the head or on the nape lies in a basin that
    neither the natural posture nor the arm seeds reach. Seeded per draw, so a mirrored
    problem (the same ranges) draws the mirrored starts."""
    lo = np.maximum(lower[drawn], -np.pi)
    hi = np.minimum(upper[drawn], np.pi)
    k = 0
    while True:
        k += 1
        q = q_start.copy()
        q[drawn] = np.random.default_rng((seed, 7919, k)).uniform(lo, hi)
        yield np.clip(q, lower, upper)


def wide_search(attempt: Callable, best, points: Iterator[np.ndarray], natural: Callable):
    """Attempts (``attempt(start)`` -> an attempt with ``q``, ``rank``, 0 first when it
    meets everything, and ``iterations``) from ``points`` while ``best`` misses: up to
    :data:`WIDE_STARTS`, and :data:`WIDE_AFTER_MEET` more after the first meet so that the
    most natural of a few meets is kept. Only a meet counts, and only one that
    ``natural(q)`` accepts: a far start is no licence for another arm branch that the
    signer's preferences (the elbow low) reject, and a miss keeps the posture it had.
    Returns (the best attempt, iterations)."""
    iters, left = 0, None
    for start in itertools.islice(points, WIDE_STARTS):
        if left == 0:
            break
        run = attempt(start)
        iters += run.iterations
        if not run.rank[0] and run.rank < best.rank and natural(run.q):
            best = run
        if not best.rank[0]:
            left = WIDE_AFTER_MEET if left is None else left - 1
    return best, iters
