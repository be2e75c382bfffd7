"""The interval index answers what a scan of every interval answers."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from azee_mj.intervals import IntervalIndex

times = st.floats(-5, 5, allow_nan=False).map(lambda x: round(x, 1))
spans = st.lists(st.tuples(times, times), max_size=30)


def _scan(spans, t):
    return tuple(i for i, (s, e) in enumerate(spans) if s <= t < e)


@settings(max_examples=300, deadline=None)
@given(spans, st.lists(times, min_size=1, max_size=20))
def test_the_index_answers_what_a_scan_answers(spans, queries):
    # shifted starts, as a contact's window is opened a nanosecond early
    spans = [(s - 1e-9 if k % 2 else s, e) for k, (s, e) in enumerate(spans)]
    index = IntervalIndex(spans)
    for t in [*queries, *(s for s, _ in spans), *(e for _, e in spans)]:
        assert index.at(t) == _scan(spans, t), t
        assert index.first_at(t) == next(iter(_scan(spans, t)), None)


def test_edges_and_empty_intervals():
    index = IntervalIndex([(0.0, 1.0), (1.0, 2.0), (1.5, 1.5), (2.0, 1.0), (0.5, 3.0)])
    assert index.at(-0.1) == ()
    assert index.at(0.0) == (0,)
    assert index.at(0.5) == (0, 4)
    assert index.at(1.0) == (1, 4)
    assert index.at(1.5) == (1, 4)
    assert index.at(2.0) == (4,)
    assert index.at(3.0) == ()
    assert IntervalIndex([]).at(0.0) == ()
