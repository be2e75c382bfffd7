"""Per-track curves between key postures: minimum-jerk blends, timed (pure functions).

A track holds each key posture while driven; consecutive keys with the same posture merge
into one :class:`Hold`; between holds the track moves with a minimum-jerk blend, timed by
:func:`blend_window` (in the gap before the next hold, or just before it when there is
none), so that no joint turns faster than the blend is sized for.

Units: seconds, radians (metres for a slide joint).
"""

from __future__ import annotations

import bisect
import dataclasses

import numpy as np

from azee_mj import constraints as cn

#: Longest blend between two postures of a track when the gap allows more [s].
MAX_BLEND = 0.6
#: Shortest blend when a posture must change with no gap [s].
MIN_BLEND = 0.08
#: Postures closer than this per joint [rad] are the same (the solver's accuracy).
SAME_POSTURE = 2e-3
#: Peak joint speed a blend is sized for [rad/s] (the limit is 25 rad/s).
BLEND_SPEED = 12.0
#: The step box of frames solved one by one, where the blend itself moves slower [rad/s]:
#: a per-frame solve stays on the branch of the frame before. It is not a speed limit: a
#: frame's box grows with its blend's own step (:mod:`azee_mj.framesolver`), and a gap too
#: short for it only makes a blend start earlier (:func:`blend_window`).
BRANCH_SPEED = 20.0
#: The name this constant had when it clamped joint speeds (kept for callers).
MAX_JOINT_SPEED = BRANCH_SPEED
#: The minimum-jerk profile's peak speed over its mean speed (its slope at the middle,
#: 30 u^2 (1 - u)^2 at u = 1/2): a change ``dq`` over ``T`` peaks at ``15/8 dq / T``.
MINJERK_PEAK = 15 / 8
#: Two times closer than this are the same instant [s].
EPS = 1e-9

# Movements the realizer times itself (from rest, back to rest): sized from their distance
# at a human speed, a single minimum-jerk bell (peak = 15/8 x distance / duration).
#: Peak wrist speed a lead-in or a return to rest is sized for [m/s] (human range <= 3).
REST_SPEED = 1.5
#: Peak joint speed of a track without a wrist (trunk, head, eyes, face, fingers) on such a
#: movement [rad/s].
REST_JOINT_SPEED = 6.0
#: Shortest lead-in from rest [s]: Performs' default time to place a sign (0.3 s).
MIN_LEAD = 0.3
#: Shortest return to rest [s]: Performs' default time to relax to neutral (0.5 s).
MIN_RELAX = 0.5
#: Longest lead-in or return to rest [s].
MAX_REST_MOVE = 1.2
#: How long a track with no further block holds its last posture before relaxing [s].
REST_HOLD = 0.3
#: The shortest gap [s] between two holds of a track in which it returns to rest and
#: comes back (a *pause*; shorter gaps hold the posture, as a signer keeps a hand up
#: between two nearby signs). Configurable: ``realize(rest_gap=...)``, ``--rest-gap``.
REST_GAP = 1.5
#: The least time [s] a pausing track stays at rest between its return and its lead-in:
#: a gap that cannot fit the hold, the return, this and the lead-in holds the posture.
REST_STAY = 0.2


@dataclasses.dataclass(frozen=True, eq=False)
class Key:
    """One track's posture over a segment ``[start, end)`` [s], and the constraints that
    hold it there."""

    start: float
    end: float
    q: np.ndarray  # (nq,) the component's solved posture (only this track's joints count;
    # read only: the keys of a component's tracks share it)
    cons: tuple  # ik constraints of the component (hard), for frames inside this key
    free: tuple[str, ...]  # joints of the component
    relax: bool = False  # a return to neutral: it blends from its start, not before it


@dataclasses.dataclass(frozen=True)
class Hold:
    """Consecutive keys of one track with the same posture, merged.

    Attributes:
      start, end: the interval the track holds ``q`` [s].
      q: the track's joint values (its dofs only).
      relax: the first key is a return to neutral (it blends from its start).
      shape_only: the first key's constraints are all joint targets (a hand shape).
      due: when a return to neutral must have arrived: the end of its relax keys [s].
    """

    start: float
    end: float
    q: np.ndarray
    relax: bool
    shape_only: bool
    due: float


@dataclasses.dataclass(frozen=True)
class Pause:
    """A track's return to rest in a long gap between two of its holds, and its lead-in
    back into the next.

    Attributes:
      at: when [s] it starts back to rest (after the hold before, and its carried keys).
      relax: duration [s] of the return to rest.
      lead: duration [s] of the lead-in from rest, ending as the next hold starts.
      until: when [s] the next hold starts.
    """

    at: float
    relax: float
    lead: float
    until: float


@dataclasses.dataclass(frozen=True)
class Rest:
    """How one track leaves and returns to rest (the neutral posture).

    Attributes:
      lead: duration [s] of the blend from rest into its first hold, ending as that hold
        starts; None: the track starts in its first hold's posture (no lead-in).
      relax_at: when [s] it starts back to rest after its last hold; None: it stays.
      relax: duration [s] of that return.
      pauses: its returns to rest between holds (:func:`pause_between`), in time order.
    """

    lead: float | None
    relax_at: float | None = None
    relax: float = 0.0
    pauses: tuple[Pause, ...] = ()


def pause_between(
    end: float,
    start: float,
    hold: float,
    relax: float,
    lead: float,
    shortest: float = REST_GAP,
    busy=(),
) -> Pause | None:
    """A track's pause at rest between a hold ending at ``end`` [s] and its next hold
    starting at ``start`` [s], or None (it holds its posture through the gap).

    It pauses when the gap is at least ``shortest`` [s] and fits, in order: the ``hold``
    [s] before relaxing, the return to rest (``relax`` [s]), :data:`REST_STAY` at rest
    and the lead-in back (``lead`` [s], ending as the next hold starts). ``busy``:
    ``(start, end)`` [s] of other tracks' keys this track carries (a hand held at the
    chin rides on the head); it starts back to rest only after those in the gap end."""
    at = end + hold
    for s, e in busy:
        if s < start - EPS and e > end + EPS:
            at = max(at, e)
    if start - end < shortest - EPS or start - at < relax + REST_STAY + lead - EPS:
        return None
    return Pause(at, relax, lead, start)


def rest_duration(distance: float, speed: float, shortest: float) -> float:
    """The duration [s] of a minimum-jerk movement over ``distance`` (m or rad) that peaks
    at ``speed`` (m/s or rad/s), within ``[shortest, MAX_REST_MOVE]``."""
    return float(np.clip(MINJERK_PEAK * distance / speed, shortest, MAX_REST_MOVE))


def minjerk(u: np.ndarray | float):
    """The minimum-jerk profile 10u^3 - 15u^4 + 6u^5 on [0, 1] (clipped outside)."""
    u = np.clip(u, 0.0, 1.0)
    return u**3 * (10.0 - 15.0 * u + 6.0 * u**2)


def blend_time(change: np.ndarray, speed: float) -> float:
    """The duration [s] of a minimum-jerk blend by ``change`` (per joint) whose fastest
    joint peaks at ``speed`` [rad/s]."""
    return MINJERK_PEAK * float(np.max(np.abs(change))) / speed


def holds_of(keys: list[Key], dofs: np.ndarray) -> list[Hold]:
    """The holds of one track (joints ``dofs``): its keys, consecutive ones with the same
    posture merged. A return to neutral is due by the end of its relax keys: a key merged
    after those needs the posture from its start. A hand shape held on into a key that
    also places or turns the hand takes that key's posture (solved with the contact: the
    two differ by less than ``SAME_POSTURE``, the shape's tolerance holds, and the
    contact is met as solved, not a milliradian off, where fingers of two hands touch)."""
    holds: list[Hold] = []
    for k in keys:
        qk = k.q[dofs]
        last = holds[-1] if holds else None
        shape_only = all(isinstance(c, cn.JointTarget) for c in k.cons)
        if (
            last is not None
            and abs(last.end - k.start) < EPS
            and np.allclose(last.q, qk, atol=SAME_POSTURE)
        ):
            due = k.end if last.end == last.due and k.relax else last.due
            q = qk if last.shape_only and not shape_only and k.cons else last.q
            holds[-1] = dataclasses.replace(last, end=k.end, due=due, q=q)
        else:
            holds.append(Hold(k.start, k.end, qk, k.relax, shape_only, k.end))
    return holds


def after_carried(w0: float, w1: float, carried) -> float:
    """A blend's start ``w0`` [s] moved no earlier than the last end before ``w1`` of a
    key of another track this one carries (``carried``, end times, ascending), but never so late the
    blend is shorter than ``MIN_BLEND`` (a carried hold may end as this one starts)."""
    i = bisect.bisect_left(carried, w1 + EPS)  # (ascending) the last one before w1
    return max(w0, min(carried[i - 1], w1 - MIN_BLEND)) if i else w0


def blend_window(
    hold: Hold, prev: Hold | None, prev_q: np.ndarray, flattened: bool, carried=()
) -> tuple[float, float]:
    """When [s] a track blends from ``prev_q`` (the posture of hold ``prev``, or the
    neutral one when None) into ``hold``: ``(w0, w1)``, no blend when equal.

    A return to neutral blends from its start. Flattened, a blend fills the gap between
    holds. Multitrack, a blend takes the gap before the hold (at most ``MAX_BLEND``, at
    least what ``BLEND_SPEED`` needs), starting inside the previous hold when the gap is
    too short for ``MAX_JOINT_SPEED``; it starts no earlier than the end of a key of
    another track this one carries (``carried``, end times), and a hand shape still too
    fast finishes late."""
    a, b = hold.start, hold.end
    first = prev is None
    prev_start, prev_end = (0.0, 0.0) if first else (prev.start, prev.end)
    if hold.relax:
        need = max(MIN_BLEND, blend_time(hold.q - prev_q, BLEND_SPEED))
        return a, min(b, a + max(need, min(MAX_BLEND, hold.due - a)))
    if flattened:
        return (a, a) if first else (prev_end, a)
    gap = a - prev_end
    need = max(MIN_BLEND, blend_time(hold.q - prev_q, BLEND_SPEED))
    # the shortest blend that keeps every joint under MAX_JOINT_SPEED
    fastest = blend_time(hold.q - prev_q, MAX_JOINT_SPEED)
    at_start = first and a <= EPS
    if at_start:
        w0 = w1 = a
    elif gap >= EPS:
        w0, w1 = max(prev_end, a - max(min(gap, MAX_BLEND), min(need, gap))), a
        if first:
            w0 = max(0.0, a - max(min(a, MAX_BLEND), need))
        # a gap too short for the change: start inside the previous hold
        if w1 - w0 < fastest and not first:
            w0 = max(prev_start, w1 - fastest)
    else:  # no gap: blend at the end of the previous hold
        w0, w1 = max(prev_start, a - need), a
    w0 = after_carried(w0, w1, carried)
    if w1 - w0 < fastest and not at_start and hold.shape_only:
        w1 = min(b, w0 + fastest)  # still too fast: finish a shape change late
    return w0, w1


def track_curve(
    keys: list[Key],
    times: np.ndarray,
    dofs: np.ndarray,
    home: np.ndarray,
    flattened: bool = False,
    carried=(),
    rest: Rest | None = None,
    out=None,
) -> tuple[np.ndarray, np.ndarray]:
    """Joint values (T, len(dofs)) of one track at ``times`` [s] (ascending), from the neutral
    posture ``home`` (nq,) through its ``keys``, and a (T,) flag where it blends (see
    :func:`blend_window`). With ``rest``, the first blend is the track's lead-in (``rest.lead``
    long, or none: it starts in its first posture), it returns to ``home`` and back in each
    of its ``rest.pauses`` and after its last hold at ``rest.relax_at`` (see :class:`Rest`).
    ``out``: where to write the joint values (anything taking ``out[a:b] = values``, e.g.
    :class:`Columns` of the frames; returned) instead of a new array."""
    holds = holds_of(keys, dofs)
    start = holds[0].q if rest is not None and rest.lead is None and holds else home[dofs]
    if out is None:
        out = np.empty((len(times), len(dofs)))
    out[:] = start
    blending = np.zeros(len(times), bool)
    prev, prev_q, blends = None, start, []
    pauses = {p.until: p for p in rest.pauses} if rest is not None else {}
    for hold in holds:
        pause = pauses.get(hold.start) if prev is not None else None
        if prev is None and rest is not None:
            w0, w1 = hold.start - (rest.lead or 0.0), hold.start
            if w1 > w0:  # no earlier than a carried hold ends, as any blend
                w0 = after_carried(w0, w1, carried)
        elif pause is not None:  # back to rest, and from rest into this hold
            blends.append((pause.at, pause.at + pause.relax, prev_q, home[dofs]))
            prev_q = home[dofs]
            w0, w1 = pause.until - pause.lead, pause.until
        else:
            w0, w1 = blend_window(hold, prev, prev_q, flattened, carried)
        blends.append((w0, w1, prev_q, hold.q))
        prev, prev_q = hold, hold.q
    if rest is not None and rest.relax_at is not None and holds:
        w0 = rest.relax_at
        blends.append((w0, w0 + rest.relax, prev_q, home[dofs]))
    _blend(out, blending, times, blends)
    return out, blending


class Columns:
    """The columns ``cols`` of the frames ``q`` (T, nq) as a (T, len(cols)) target of
    slice assignments, written in place (``q[:, cols]`` would be a copy, as large as the
    track: 46 columns of 120 for the face)."""

    def __init__(self, q: np.ndarray, cols: np.ndarray):
        self.q, self.cols = q, cols

    def __setitem__(self, rows: slice, values) -> None:
        self.q[rows, self.cols] = values


def _blend(out, blending, times, blends) -> None:
    """Frames at ``times`` through ``blends`` ``(w0, w1, qa, qb)``, in order: each from
    ``qa`` to ``qb`` in minimum-jerk time over the frames in ``[w0, w1)``, and ``qb`` after
    them, until a later blend starts (in place). What writing each blend over every frame
    after its start would leave, each frame written once: that was quadratic in the
    score."""
    # ``times`` ascend: the frames in a window are a slice (not a scan of every frame)
    spans = [np.searchsorted(times, (w0, w1), side="left") for w0, w1, _, _ in blends]
    until, stop = [], len(times)  # a blend's frames end where a later one starts
    for a, b in reversed(spans):
        until.append(stop)
        stop = min(stop, a, b)
    for (w0, w1, qa, qb), (a, b), end in zip(blends, spans, reversed(until)):
        if w1 > w0:
            blending[a:b] = True
            if min(b, end) > a:
                u = minjerk((times[a : min(b, end)] - w0) / (w1 - w0))[:, None]
                out[a : min(b, end)] = qa + u * (qb - qa)
        if end > b:
            out[b:end] = qb


def goal_key(keys: list[Key], i: int, dofs: np.ndarray) -> Key | None:
    """The key a track's blend from key ``i`` heads for: the first after the keys that
    hold key ``i``'s posture on without a gap (None: the last posture)."""
    for a, b in zip(keys[i:], keys[i + 1 :]):
        if abs(a.end - b.start) > EPS or not np.allclose(a.q[dofs], b.q[dofs], atol=SAME_POSTURE):
            return b
    return None


def next_still(moving: np.ndarray) -> np.ndarray:
    """(T, tracks) the first frame at or after each frame where each track does not blend
    (-1: it blends to the end), from the (T, tracks) blending flags ``moving``."""
    out = np.full(moving.shape, -1, np.int32)  # (half the memory of int64, a frame a row)
    nxt = np.full(moving.shape[1], -1, np.int32)
    for f in range(len(moving) - 1, -1, -1):
        nxt = np.where(moving[f], nxt, f)
        out[f] = nxt
    return out
