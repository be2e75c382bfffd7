"""Pure functions of azee_mj.findings: runs of frames, frame speeds, the block a movement
belongs to, speed and constraint findings."""

import numpy as np
import pytest

from azee_mj.findings import (
    JOINT_LIMIT,
    WRIST_LIMIT,
    block_at,
    constraint_findings,
    frame_speeds,
    leaving,
    runs,
    speed_findings,
    turning_fast,
)
from azee_mj.rollout import ConstraintTrace
from azee_mj.schedule import TrackInterval


def test_runs_are_the_consecutive_true_frames():
    flags = np.array([0, 1, 1, 0, 0, 1, 0, 1, 1, 1], bool)
    assert runs(flags) == [(1, 2), (5, 5), (7, 9)]
    assert runs(np.zeros(4, bool)) == []


def test_frame_speed_is_the_larger_step_around_a_frame():
    x = np.array([[0.0, 0, 0], [0.1, 0, 0], [0.1, 0, 0], [0.1, 0.3, 0.4]])
    np.testing.assert_allclose(frame_speeds(x, 10.0), [1.0, 1.0, 5.0, 5.0])


def test_the_screen_keeps_every_joint_whose_speed_passes_the_limit():
    """Joints screened a block of frames at a time: those that turn faster than the limit
    somewhere (however the blocks fall), a joint exactly at it too (never missed by
    rounding), none slower."""
    fps = 50.0
    rng = np.random.default_rng(2)
    q = np.cumsum(rng.uniform(-0.7, 0.7, size=(40, 6)) * [1, 1, 0.5, 0.5, 1, 1], axis=0)
    q[:, 4] = np.arange(40) * (JOINT_LIMIT / fps)  # exactly at the limit
    q[:, 5] = 0.1 * np.sin(np.arange(40) / 5)  # slow
    over = [(frame_speeds(q[:, j], fps) > JOINT_LIMIT).any() for j in range(6)]
    for block in (1, 3, 4096):
        got = turning_fast(q, [0, 1, 2, 3, 4, 5], JOINT_LIMIT / fps, block)
        assert (got[:4] == over[:4]).all() and got[4] and not got[5]
    assert over[:4] == [True, True, False, False] and not over[5]


def test_a_movement_belongs_to_the_block_it_moves_into():
    ivs = (TrackInterval("arm_R", "A", 1.0, 1.5), TrackInterval("arm_R", "B", 2.0, 2.5))
    assert block_at(ivs, 0.5, 1.0, 2.5) == "lead-in"
    assert block_at(ivs, 1.8, 1.0, 2.5) == "B"
    assert block_at(ivs, 2.2, 1.0, 2.5) == "B"  # inside the last block
    assert block_at(ivs, 2.8, 1.0, 2.5) == "return to rest"


def test_speed_findings_name_the_block_the_speed_and_the_frames():
    fps, T = 50.0, 40
    t = np.arange(T) / fps
    pos = np.zeros((T, 1, 3))
    pos[20:, 0, 0] = 0.1  # a 0.1 m jump in one frame: 5 m/s
    q = np.zeros((T, 1))
    q[30:, 0] = 0.6  # a 0.6 rad jump in one frame: 30 rad/s
    sched = {"arm_R": (TrackInterval("arm_R", "S.JUMP", 0.4, 0.8),)}
    out = speed_findings(t, q, pos, ["WR_R"], {"j": ("arm_R", 0)}, sched, 0.0, 0.8)
    wrist, joint = out
    assert (wrist.kind, wrist.block, wrist.what, wrist.unit) == ("speed", "S.JUMP", "WR_R", "m/s")
    assert wrist.value == pytest.approx(5.0) and wrist.limit == WRIST_LIMIT
    assert (wrist.start, wrist.end, wrist.frames) == (t[19], t[20], 2)
    assert (joint.what, joint.value, joint.limit) == ("j", pytest.approx(30.0), JOINT_LIMIT)
    assert joint.block == "S.JUMP"
    assert "WR_R 5.00 m/s (limit 3.00) in S.JUMP" in wrist.describe()


def test_constraint_findings_count_the_frames_out_of_tolerance():
    tr = ConstraintTrace(
        "S.K", 0, "place", 1e-3, "m", 0.2, 0.4, 10, np.array([0, 2e-3, 3e-3, 0.5e-3]), 30
    )
    ok = ConstraintTrace("S.L", 1, "orient", 0.1, "rad", 0.2, 0.4, 10, np.zeros(4), 30)
    (f,) = constraint_findings([tr, ok], np.arange(30) / 50.0)
    assert (f.block, f.frames, f.value, f.limit) == ("S.K", 2, 3e-3, 1e-3)
    assert (f.start, f.end) == (11 / 50.0, 12 / 50.0)
    assert f.describe().startswith("constraint: constraint 0 (place) 3.00 mm (limit 1.00)")
    assert leaving([tr, ok]).nonzero()[0].tolist() == [11, 12]


def test_site_speeds_a_block_at_a_time_are_frame_speeds_of_the_whole_array():
    from azee_mj.findings import frame_speeds, site_speeds

    pos = np.random.default_rng(3).random((10_000, 5, 3))

    class Blocks:  # as a lazy rollout's site positions give them
        def blocks(self):
            for a in range(0, len(pos), 1024):
                yield a, pos[a : a + 1024]

    for source in (pos, Blocks()):
        got = site_speeds(source, [4, 1], 50.0)
        assert [g.shape for g in got] == [(10_000,), (10_000,)]
        np.testing.assert_array_equal(got[0], frame_speeds(pos[:, 4], 50.0))
        np.testing.assert_array_equal(got[1], frame_speeds(pos[:, 1], 50.0))
    assert site_speeds(pos[:1], [0], 50.0)[0].tolist() == [0.0]
