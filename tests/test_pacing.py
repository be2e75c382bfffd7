"""Pacing a movement along its path: one speed bell, slower in curves (pure functions)."""

import numpy as np
import pytest

from azee_mj import movement as mv
from azee_mj import pacing as pc
from azee_mj.blend import minjerk

FS = 50.0


def line_with_a_stop(n: int = 41) -> np.ndarray:
    """(n, 1, 3): 0.3 m along x in two minimum-jerk halves, stopped in between."""
    u = np.linspace(0.0, 1.0, n)
    x = 0.15 * (minjerk(u / 0.4) + minjerk((u - 0.6) / 0.4))
    return np.c_[x, np.zeros(n), np.zeros(n)][:, None, :]


def ellipse(n: int = 61, a: float = 0.04, b: float = 0.15) -> np.ndarray:
    """(n, 3) half an ellipse from (a, 0) over its sharp end (0, b) to (-a, 0), evenly in
    angle (so not evenly in distance)."""
    th = np.linspace(0.0, np.pi, n)
    return np.c_[a * np.cos(th), b * np.sin(th), np.zeros(n)]


def shown(points: np.ndarray, frames: np.ndarray) -> np.ndarray:
    return pc.resample(points.reshape(len(points), -1), frames).reshape(-1, *points.shape[1:])


def test_a_movement_with_a_stop_becomes_one_bell_between_the_same_ends():
    pts = line_with_a_stop()
    before = mv.speed(pts[:, 0], FS)
    assert mv.speed_peaks(before) == 2
    frames = pc.paced(pts)
    assert frames[0] == 0.0 and frames[-1] == len(pts) - 1
    assert np.all(np.diff(frames) >= 0.0)
    after = shown(pts, frames)[:, 0]
    sp = mv.speed(after, FS)
    assert mv.speed_peaks(sp) == 1
    assert mv.sparc(sp, FS) == pytest.approx(-1.40, abs=0.02)
    # the same path: every shown point lies on the segment, the ends where they were
    assert np.allclose(after[[0, -1]], pts[[0, -1], 0])
    assert np.allclose(after[:, 1:], 0.0)
    # a minimum-jerk distance profile peaks at 15/8 of the mean speed
    duration = (len(pts) - 1) / FS
    assert sp.max() == pytest.approx(mv.MINJERK_PEAK * 0.3 / duration, rel=0.03)


def test_two_sites_are_paced_by_their_summed_distance():
    one = line_with_a_stop()
    two = np.concatenate([one, 2.0 * one], axis=1)  # the second goes twice as far
    assert np.allclose(pc.paced(two), pc.paced(one))


def test_a_pinned_frame_keeps_its_time_and_the_path_goes_forward():
    pts = line_with_a_stop()
    frames = pc.paced(pts, pins=[20])  # halfway along the path, halfway through the time
    assert frames[20] == pytest.approx(20.0)
    assert np.all(np.diff(frames) > 0.0)
    # the path's first half done by frame 12 would need the bell to run backwards later
    assert pc.paced(pts, pins=[12]) is None
    assert pc.paced(pts, pins=[1]) == pytest.approx(pc.paced(pts))  # next to an end


def test_a_joint_turning_where_the_sites_stand_still_is_not_rushed():
    n = 41
    pts = line_with_a_stop(n)
    joints = np.zeros((n, 1))
    joints[16:25, 0] = np.linspace(0.0, 10.0, 9)  # turns 10 rad while the sites stop
    joints[25:, 0] = 10.0
    without = np.diff(pc.resample(joints, pc.paced(pts))[:, 0]).max()
    with_lever = np.diff(pc.resample(joints, pc.paced(pts, joints=joints))[:, 0]).max()
    assert with_lever < 0.5 * without


def test_a_still_hand_is_left_as_it_is():
    pts = np.zeros((20, 1, 3)) + np.linspace(0.0, 0.001, 20)[:, None, None]
    assert pc.paced(pts) is None
    assert pc.paced(line_with_a_stop()[:2]) is None


def test_curvature_of_a_circle_a_line_and_a_stall():
    th = np.linspace(0.0, np.pi, 200)
    r = 0.05
    circle = np.c_[r * np.cos(th), r * np.sin(th), np.zeros_like(th)]
    assert np.allclose(pc.turning(circle), 1.0 / r, rtol=1e-3)
    line = np.c_[th, 2.0 * th, -th]
    assert np.allclose(pc.turning(line), 0.0, atol=1e-9)
    stalled = np.r_[circle[:50], circle[49:50], circle[50:]]  # a frame that did not move
    assert np.all(np.isfinite(pc.turning(stalled)))


def test_a_metre_counts_more_in_a_curve_by_the_power_law():
    th = np.linspace(0.0, np.pi, 100)
    r = 0.05
    circle = np.c_[r * np.cos(th), r * np.sin(th), np.zeros_like(th)]
    s = th * r  # its arc length
    w = pc.distance_weight(circle, s, np.linspace(0.0, s[-1], 50))
    assert np.allclose(w[5:-5], (1.0 / r / pc.STRAIGHT) ** pc.BETA, rtol=1e-2)
    line = np.c_[np.linspace(0.0, 0.3, 30), np.zeros(30), np.zeros(30)]
    w = pc.distance_weight(line, line[:, 0], np.linspace(0.0, 0.3, 20))
    assert np.allclose(w, 1.0)


def test_the_law_slows_a_hand_where_its_path_bends_most():
    path = ellipse()
    with_law = shown(path[:, None, :], pc.paced(path[:, None, :], path))[:, 0]
    without = shown(path[:, None, :], pc.paced(path[:, None, :]))[:, 0]
    # the ellipse's sharp end (x = 0) is the curviest point of its path: reached at
    # the same time with or without the law (symmetry), passed slower with it
    mid = len(path) // 2
    assert with_law[mid] == pytest.approx(without[mid], abs=1e-9)
    v_law, v_no = mv.speed(with_law, FS), mv.speed(without, FS)
    assert v_law[mid] < 0.9 * v_no[mid]
    # the sharp end is where the hand is slowest between its two halves (a hand drawing a
    # sharp curve slows there), and speed falls with curvature: a negative exponent
    assert v_law[mid] == pytest.approx(v_law[mid - 10 : mid + 11].min())
    assert mv.power_law_exponent(with_law, FS) < mv.power_law_exponent(without, FS)


def test_smoothing_removes_a_one_frame_spike_and_keeps_the_ends():
    q = np.linspace(0.0, 1.0, 21)[:, None] * np.ones((1, 3))
    q[10, 1] += 0.2
    out = pc.smoothed(q)
    assert np.allclose(out[[0, -1]], q[[0, -1]])
    assert abs(out[10, 1] - q[10, 0]) < 0.5 * 0.2
    assert np.allclose(pc.smoothed(q, 0), q)
    straight = np.linspace(0.0, 1.0, 21)[:, None]
    assert np.allclose(pc.smoothed(straight), straight)  # a straight path is unchanged


def test_resample_interpolates_rows():
    q = np.array([[0.0, 1.0], [2.0, 3.0], [4.0, 7.0]])
    out = pc.resample(q, np.array([0.0, 0.5, 1.25, 2.0]))
    assert np.allclose(out, [[0.0, 1.0], [1.0, 2.0], [2.5, 4.0], [4.0, 7.0]])
