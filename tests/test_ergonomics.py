"""Naturalness metrics (azee_mj.ergonomics) on the real signer, against values worked out by
hand from the model's dimensions and the RULA tables."""

import mujoco
import numpy as np
import pytest

from azee_mj.ergonomics import ergonomics, table_a, table_b, table_c

DEG = np.pi / 180.0


@pytest.fixture(scope="module")
def home(model):
    k = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, "home")
    return model.key_qpos[k].copy()


def posture(model, q, **joints):
    q = q.copy()
    for name, value in joints.items():
        q[model.jnt_qposadr[model.joint(name).id]] = value
    return q


def test_home_is_upright_and_low_risk(model, home):
    e = ergonomics(model, home)
    assert e.trunk_angle == pytest.approx(0.0, abs=1e-9)
    assert e.head_angle == pytest.approx(0.0, abs=1e-9)
    assert e.gaze_deviation == pytest.approx(0.0, abs=1e-9)
    # home: arm 8 deg from the trunk (1), elbow 8.6 deg bent (< 60: 2), wrist 2.9 deg (1),
    # forearm twist mid-range (1) -> table A 2; neck 1, trunk 1, legs 1 -> B 1; C(2, 1) = 2.
    r = e.rula
    for arm in (r.right, r.left):
        assert (arm.upper_arm, arm.lower_arm, arm.wrist, arm.wrist_twist) == (1, 2, 1, 1)
        assert (arm.score_a, arm.score) == (2, 2)
    assert (r.neck, r.trunk, r.legs, r.score_b, r.score) == (1, 1, 1, 1, 2)
    # arms hang: the elbow one upper arm (316 mm at 8 deg) below the shoulder
    assert e.right.elbow_above_shoulder == pytest.approx(-0.316 * np.cos(0.14), abs=1e-3)
    assert e.left.elbow_above_shoulder == pytest.approx(e.right.elbow_above_shoulder, abs=1e-9)
    assert e.right.hand_above_eyes < -0.5
    assert e.elbows_ok()


def test_spine_flexed_30_degrees(model, home):
    q = posture(model, home, back_1_flex=15 * DEG, back_2_flex=15 * DEG)
    e = ergonomics(model, q)
    assert e.trunk_angle == pytest.approx(30 * DEG, abs=1e-6)
    assert e.trunk_flexion == pytest.approx(30 * DEG, abs=1e-6)
    # the head rides on the chest: 30 deg from upright, neck itself straight
    assert e.head_angle == pytest.approx(30 * DEG, abs=1e-6)
    assert e.neck_flexion == pytest.approx(0.0, abs=1e-6)
    # trunk 20-60 deg flexion: 3; B(neck 1, trunk 3, legs 1) = 3; C(A 2, B 3) = 3
    assert (e.rula.trunk, e.rula.score_b, e.rula.score) == (3, 3, 3)


def test_elbow_raised_above_shoulder(model, home):
    q = posture(model, home, arm_R_abd=110 * DEG)
    e = ergonomics(model, q)
    # shoulder to elbow 316 mm, 110 deg from hanging: 316 sin(20 deg) above the shoulder
    assert e.right.elbow_above_shoulder == pytest.approx(0.316 * np.sin(20 * DEG), abs=1e-3)
    assert e.right.hand_above_eyes < 0.0
    assert not e.elbows_ok()
    a = e.rula.right
    # > 90 deg elevation: 4, +1 abducted; elbow 8.6 deg (2) +1 wrist far out to the side;
    # table A(5, 3, 1, 1) = 6; C(6, 1) = 4
    assert a.upper_arm_elevation == pytest.approx(110 * DEG, abs=1e-6)
    assert (a.upper_arm, a.lower_arm, a.wrist, a.wrist_twist, a.score_a) == (5, 3, 1, 1, 6)
    assert (a.score, e.rula.score) == (4, 4)
    assert e.rula.left.score == 2  # the other side is unchanged


def test_head_tilted_to_the_side(model, home):
    q = posture(model, home, head_lat=20 * DEG)
    e = ergonomics(model, q)
    assert e.head_angle == pytest.approx(20 * DEG, abs=1e-6)
    assert abs(e.neck_side_bend) == pytest.approx(20 * DEG, abs=1e-6)
    assert e.gaze_deviation == pytest.approx(0.0, abs=1e-6)  # still faces forward
    assert e.trunk_angle == pytest.approx(0.0, abs=1e-9)
    # neck flexion 0-10 (1) +1 side bent; B(2, 1, 1) = 2; C(2, 2) = 2
    assert (e.rula.neck, e.rula.score_b, e.rula.score) == (2, 2, 2)


def test_head_bowed_forward(model, home):
    q = posture(model, home, neck_flex=25 * DEG)
    e = ergonomics(model, q)
    assert e.head_angle == pytest.approx(25 * DEG, abs=1e-6)
    assert e.gaze_deviation == pytest.approx(25 * DEG, abs=1e-6)
    assert e.neck_flexion == pytest.approx(25 * DEG, abs=1e-6)
    # neck > 20 deg flexion: 3; B(3, 1, 1) = 3; C(2, 3) = 3
    assert (e.rula.neck, e.rula.score_b, e.rula.score) == (3, 3, 3)


def test_rula_tables_corners():
    assert table_a(1, 1, 1, 1) == 1 and table_a(6, 3, 4, 2) == 9
    assert table_a(3, 2, 2, 1) == 4
    assert table_b(1, 1, 1) == 1 and table_b(6, 6, 2) == 9 and table_b(4, 2, 1) == 5
    assert table_c(1, 1) == 1 and table_c(8, 7) == 7 and table_c(12, 9) == 7
    assert table_c(4, 5) == 5


def test_bad_posture_shape(model):
    with pytest.raises(ValueError) as e:
        ergonomics(model, np.zeros(3))
    assert str(e.value) == f"qpos must have shape ({model.nq},), got (3,)"
