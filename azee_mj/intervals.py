"""Which of many intervals hold a time, in logarithmic time: the lookup that asking every
block of a score at every frame made quadratic in the score's length.

:class:`IntervalIndex` answers exactly what ``[i for i, (s, e) in enumerate(spans) if s <= t <
e]`` answers, for any ``t``, by a binary search among the intervals' ends (the set of
intervals holding ``t`` changes only there). Units: those of the spans (seconds).
"""

from __future__ import annotations

import bisect
from collections.abc import Iterable


class IntervalIndex:
    """The half-open intervals ``[start, end)`` of ``spans``, by position."""

    def __init__(self, spans: Iterable[tuple[float, float]]):
        spans = [(float(s), float(e)) for s, e in spans]
        self._bounds: list[float] = sorted({x for s, e in spans if s < e for x in (s, e)})
        opens: dict[float, list[int]] = {}
        closes: dict[float, list[int]] = {}
        for i, (s, e) in enumerate(spans):
            if s < e:
                opens.setdefault(s, []).append(i)
                closes.setdefault(e, []).append(i)
        # _held[k]: the intervals holding every t in [bounds[k], bounds[k + 1])
        self._held: list[tuple[int, ...]] = []
        active: set[int] = set()
        for x in self._bounds:
            active.difference_update(closes.get(x, ()))
            active.update(opens.get(x, ()))
            self._held.append(tuple(sorted(active)))

    def at(self, t: float) -> tuple[int, ...]:
        """The positions of the intervals holding ``t``, ascending."""
        k = bisect.bisect_right(self._bounds, t) - 1
        return self._held[k] if k >= 0 else ()

    def first_at(self, t: float) -> int | None:
        """The first position of an interval holding ``t``, or ``None``."""
        held = self.at(t)
        return held[0] if held else None
