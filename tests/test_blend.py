"""Blend timing and the minimum-jerk profile, called directly (no solver)."""

from __future__ import annotations

import numpy as np
import pytest

from azee_mj import constraints as cn
from azee_mj.blend import (
    BLEND_SPEED,
    MAX_BLEND,
    MAX_JOINT_SPEED,
    MIN_BLEND,
    MINJERK_PEAK,
    REST_GAP,
    REST_STAY,
    Hold,
    Key,
    Pause,
    Rest,
    blend_time,
    blend_window,
    goal_key,
    holds_of,
    minjerk,
    next_still,
    pause_between,
    track_curve,
)
from azee_mj.kinematics import SitePos

DOFS = np.array([0, 1])


def _key(start, end, q, cons=(), relax=False) -> Key:
    return Key(start, end, np.asarray(q, float), cons, ("a", "b"), relax)


def test_minjerk_runs_from_rest_to_rest_through_its_middle():
    assert minjerk(0.0) == 0.0 and minjerk(1.0) == 1.0
    assert minjerk(0.5) == pytest.approx(0.5)
    assert minjerk(-0.3) == 0.0 and minjerk(1.7) == 1.0  # clipped outside [0, 1]
    u = np.linspace(0.0, 1.0, 101)
    np.testing.assert_allclose(minjerk(u) + minjerk(1.0 - u), 1.0, atol=1e-12)  # symmetric
    h = 1e-5
    for end in (0.0, 1.0 - 2 * h):  # no speed and no acceleration at either end
        assert abs(minjerk(end + h) - minjerk(end)) / h < 1e-6
    assert np.all(np.diff(minjerk(u)) >= 0.0)


def test_minjerk_peak_speed_is_its_named_constant():
    h = 1e-6
    u = np.linspace(0.0, 1.0, 10001)
    speed = (minjerk(np.minimum(u + h, 1.0)) - minjerk(np.maximum(u - h, 0.0))) / (2 * h)
    assert MINJERK_PEAK == 15 / 8
    assert speed.max() == pytest.approx(MINJERK_PEAK, rel=1e-6)
    assert u[speed.argmax()] == pytest.approx(0.5, abs=1e-3)


def test_a_blend_of_blend_time_peaks_at_its_speed():
    change = np.array([0.4, -1.2, 0.1])
    T = blend_time(change, BLEND_SPEED)
    t = np.linspace(0.0, T, 20001)
    q = minjerk(t / T)[:, None] * change
    speed = np.abs(np.diff(q, axis=0)).max(axis=0) / (t[1] - t[0])
    assert speed.max() == pytest.approx(BLEND_SPEED, rel=1e-4)
    assert blend_time(np.zeros(2), BLEND_SPEED) == 0.0


def test_holds_merge_consecutive_keys_with_the_same_posture():
    shape = cn.JointTarget("a", 0.1, 0.02, "morph:a")
    keys = [
        _key(0.0, 0.5, [0.0, 1.0], (shape,)),
        _key(0.5, 0.8, [0.0, 1.0 + 1e-4]),  # the same posture within SAME_POSTURE
        _key(0.9, 1.2, [0.0, 1.0]),  # after a gap: a new hold
        _key(1.2, 1.5, [0.3, 1.0]),  # another posture: a new hold
    ]
    holds = holds_of(keys, DOFS)
    assert [(h.start, h.end) for h in holds] == [(0.0, 0.8), (0.9, 1.2), (1.2, 1.5)]
    assert holds[0].shape_only and holds[1].shape_only  # no constraint is a shape too
    np.testing.assert_array_equal(holds[0].q, [0.0, 1.0])  # the first key's posture
    assert [h.due for h in holds] == [0.5, 1.2, 1.5]


def test_a_hand_shape_held_into_a_contact_takes_the_contact_s_posture():
    """The shape's key and the contact's key differ by less than SAME_POSTURE: one hold,
    with the posture solved with the contact (where two hands' fingers touch, the
    shape's posture a milliradian off put them 0.14 mm into each other)."""
    shape = cn.JointTarget("a", 0.1, 0.02, "morph:a")
    touch = cn.Place("PA_R", SitePos("ST_R"), 0.001, "K")
    keys = [
        _key(0.0, 0.4, [0.0, 1.0], (shape,)),
        _key(0.4, 0.8, [0.0, 1.0 + 1e-3], (touch, shape)),
        _key(0.8, 1.0, [0.0, 1.0 + 2e-3], (shape,)),  # a shape again: the posture stays
    ]
    (hold,) = holds_of(keys, DOFS)
    assert (hold.start, hold.end, hold.shape_only) == (0.0, 1.0, True)
    np.testing.assert_array_equal(hold.q, [0.0, 1.0 + 1e-3])


def test_a_return_to_neutral_is_due_when_its_relax_keys_end():
    keys = [
        _key(0.0, 0.4, [0.0, 0.0], relax=True),
        _key(0.4, 0.7, [0.0, 0.0], relax=True),
        _key(0.7, 1.0, [0.0, 0.0]),  # held on, not a return: due stays
    ]
    (hold,) = holds_of(keys, DOFS)
    assert (hold.start, hold.end, hold.due, hold.relax) == (0.0, 1.0, 0.7, True)


def _hold(start, end, q, relax=False, shape_only=False, due=None) -> Hold:
    return Hold(start, end, np.asarray(q, float), relax, shape_only, end if due is None else due)


def test_blend_window_fills_the_gap_before_a_hold():
    prev = _hold(0.0, 0.5, [0.0, 0.0])
    small = _hold(0.8, 1.2, [0.1, 0.0])  # 0.3 s gap, a small change: the whole gap
    assert blend_window(small, prev, prev.q, False) == pytest.approx((0.5, 0.8))
    late = _hold(2.0, 2.5, [0.1, 0.0])  # a long gap: MAX_BLEND before the hold
    assert blend_window(late, prev, prev.q, False) == pytest.approx((2.0 - MAX_BLEND, 2.0))


def test_blend_window_without_a_gap_blends_at_the_end_of_the_previous_hold():
    prev = _hold(0.0, 0.5, [0.0, 0.0])
    nxt = _hold(0.5, 1.0, [1.0, 0.0])
    need = max(MIN_BLEND, MINJERK_PEAK * 1.0 / BLEND_SPEED)
    assert blend_window(nxt, prev, prev.q, False) == pytest.approx((0.5 - need, 0.5))


def test_blend_window_starts_inside_the_previous_hold_when_the_gap_is_too_short():
    prev = _hold(0.0, 0.5, [0.0, 0.0])
    nxt = _hold(0.52, 1.0, [2.0, 0.0])
    w0, w1 = blend_window(nxt, prev, prev.q, False)
    assert w1 == 0.52
    assert w1 - w0 == pytest.approx(blend_time(np.array([2.0]), MAX_JOINT_SPEED))
    assert w0 < prev.end


def test_blend_window_first_hold_at_zero_and_flattened_and_relax():
    home = np.zeros(2)
    first = _hold(0.0, 0.5, [1.0, 0.0])
    assert blend_window(first, None, home, False) == (0.0, 0.0)  # starts there
    prev = _hold(0.0, 0.5, [1.0, 0.0])
    nxt = _hold(0.9, 1.4, [0.0, 0.0])
    assert blend_window(nxt, prev, prev.q, True) == (0.5, 0.9)  # flattened: the gap
    back = _hold(0.9, 2.0, [0.0, 0.0], relax=True, due=1.5)
    assert blend_window(back, prev, prev.q, False) == pytest.approx((0.9, 1.5))


def test_blend_window_waits_for_a_carried_key_and_finishes_a_shape_late():
    prev = _hold(0.0, 0.5, [0.0, 0.0])
    nxt = _hold(1.0, 1.5, [0.1, 0.0])
    w0, w1 = blend_window(nxt, prev, prev.q, False, carried=[0.9])
    assert (w0, w1) == pytest.approx((0.9, 1.0))
    w0, _ = blend_window(nxt, prev, prev.q, False, carried=[0.99])
    assert w0 == pytest.approx(1.0 - MIN_BLEND)  # never shorter than MIN_BLEND
    # a hand shape pinned by a carried key until just before it: finished late, inside
    # its hold, at the joint speed limit (a placement would keep the short blend)
    shape = _hold(0.5, 1.5, [3.0, 0.0], shape_only=True)
    w0, w1 = blend_window(shape, prev, prev.q, False, carried=[0.49])
    assert w0 == pytest.approx(0.5 - MIN_BLEND)
    assert w1 - w0 == pytest.approx(blend_time(np.array([3.0]), MAX_JOINT_SPEED))
    assert w1 > shape.start
    placed = _hold(0.5, 1.5, [3.0, 0.0])
    assert blend_window(placed, prev, prev.q, False, carried=[0.49]) == pytest.approx(
        (0.5 - MIN_BLEND, 0.5)
    )


def test_track_curve_holds_its_keys_and_blends_between_them():
    home = np.zeros(3)
    keys = [_key(0.2, 0.6, [0.5, -0.5]), _key(1.0, 1.4, [-0.3, 0.2])]
    times = np.arange(0, 80) / 50.0
    q, blending = track_curve(keys, times, DOFS, home)
    inside = (times >= 0.2) & (times < 0.6)
    np.testing.assert_allclose(q[inside], [[0.5, -0.5]] * int(inside.sum()))
    np.testing.assert_allclose(q[times >= 1.0], [[-0.3, 0.2]] * int((times >= 1.0).sum()))
    assert not blending[inside].any() and blending[(times > 0.6) & (times < 1.0)].all()
    assert np.abs(np.diff(q, axis=0)).max() * 50.0 <= BLEND_SPEED * 1.01
    q, blending = track_curve([], times, DOFS, home)
    assert not q.any() and not blending.any()


def test_goal_key_and_next_still():
    keys = [_key(0.0, 0.5, [0.0, 0.0]), _key(0.5, 0.7, [0.0, 0.0]), _key(0.7, 1.0, [1.0, 0.0])]
    assert goal_key(keys, 0, DOFS) is keys[2]
    assert goal_key(keys, 2, DOFS) is None
    moving = np.array([[1, 0], [1, 1], [0, 1], [0, 1]], bool)
    np.testing.assert_array_equal(next_still(moving), [[2, 0], [2, -1], [2, -1], [3, -1]])


def test_a_long_gap_is_a_pause_at_rest_timed_from_its_moves():
    # hold 0.3, return 0.8, at rest, lead-in 0.6, ending as the next hold starts
    p = pause_between(1.0, 4.0, 0.3, 0.8, 0.6)
    assert p == Pause(1.3, 0.8, 0.6, 4.0)
    assert p.at + p.relax + REST_STAY <= p.until - p.lead


def test_a_gap_shorter_than_the_threshold_or_the_moves_holds_the_posture():
    assert pause_between(1.0, 1.0 + REST_GAP - 0.01, 0.0, 0.5, 0.3) is None  # below the gap
    assert pause_between(1.0, 1.0 + REST_GAP, 0.0, 0.5, 0.3) is not None  # at it
    # the threshold is the caller's: a larger one holds where the default pauses
    assert pause_between(1.0, 4.0, 0.3, 0.8, 0.6, shortest=3.5) is None
    assert pause_between(1.0, 4.0, 0.3, 0.8, 0.6, shortest=0.0) is not None
    # long enough by the threshold, but the moves and the stay at rest do not fit
    need = 0.3 + 1.2 + REST_STAY + 1.2
    assert pause_between(1.0, 1.0 + need - 0.01, 0.3, 1.2, 1.2, shortest=0.0) is None
    assert pause_between(1.0, 1.0 + need, 0.3, 1.2, 1.2, shortest=0.0) is not None


def test_a_pause_waits_for_the_keys_it_carries_in_the_gap():
    # a key of another track on this one over [1.0, 2.5] in the gap: the return after it
    assert pause_between(1.0, 5.0, 0.3, 0.5, 0.5, busy=[(1.0, 2.5)]).at == 2.5
    # one that leaves too little time after it: no pause
    assert pause_between(1.0, 5.0, 0.3, 0.5, 0.5, busy=[(2.0, 4.5)]) is None
    # those before or after the gap (touching it) do not count
    p = pause_between(1.0, 5.0, 0.3, 0.5, 0.5, busy=[(0.0, 1.0), (5.0, 6.0)])
    assert p.at == 1.3


def test_track_curve_pauses_at_rest_between_two_far_holds():
    home = np.zeros(3)
    keys = [_key(0.2, 0.6, [0.5, -0.5]), _key(3.0, 3.4, [-0.3, 0.2])]
    times = np.arange(0, 200) / 50.0
    pause = Pause(0.9, 0.5, 0.4, 3.0)
    q, blending = track_curve(keys, times, DOFS, home, rest=Rest(None, pauses=(pause,)))
    held = (times < 0.6) & (times >= 0.2)
    np.testing.assert_allclose(q[held], [[0.5, -0.5]] * int(held.sum()))
    still = (times >= 0.6) & (times < 0.9)  # the hold before relaxing
    np.testing.assert_allclose(q[still], [[0.5, -0.5]] * int(still.sum()))
    at_rest = (times >= 1.4) & (times < 2.6)
    np.testing.assert_allclose(q[at_rest], 0.0, atol=1e-12)
    assert not blending[at_rest].any() and blending[(times >= 0.9) & (times < 1.4)].all()
    assert blending[(times >= 2.6) & (times < 3.0)].all()
    np.testing.assert_allclose(q[times >= 3.0], [[-0.3, 0.2]] * int((times >= 3.0).sum()))
    # the return starts from the held posture and ends at rest
    back = q[(times >= 0.9) & (times <= 1.4)]
    np.testing.assert_allclose(back[[0, -1]], [[0.5, -0.5], [0.0, 0.0]], atol=1e-12)
    # without the pause the same keys blend straight from one hold into the next
    q, _ = track_curve(keys, times, DOFS, home, rest=Rest(None))
    assert np.abs(q[at_rest]).min() > 0.0
