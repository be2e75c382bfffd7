"""A key that leads into a path takes the hand orientation of the key after it
(azee_mj/pathkeys.py): the pure functions, the preference's rows against finite
differences, and *penser*'s keys around its circle on the real model."""

from __future__ import annotations

import json
from pathlib import Path

import mujoco
import numpy as np
import pytest

from azee_mj import constraints as cn
from azee_mj import movement as mv
from azee_mj import pathkeys as pk
from azee_mj.blend import Key
from azee_mj.ikadapter import IKAdapter
from azee_mj.keyposes import KeyPoser
from azee_mj.kinematics import BodyAxis, Const, SitePos
from azee_mj.schedule import Mode, Schedule
from azee_mj.score import load_score
from azee_mj.timeline import realize

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
FPS = 50.0


def rotation(axis, angle: float) -> np.ndarray:
    """(3, 3) the rotation by ``angle`` [rad] about unit ``axis`` (Rodrigues)."""
    n = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0.0, -n[2], n[1]], [n[2], 0.0, -n[0]], [-n[1], n[0], 0.0]])
    return np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * K @ K


def axes_of(R: np.ndarray) -> np.ndarray:
    """(2, 3) the world directions of the hand axes of a body turned by ``R``."""
    return (R @ np.array(pk.HAND_AXES).T).T


def test_a_hand_turn_runs_from_one_orientation_to_the_other_about_one_axis_evenly():
    R0 = rotation((0.2, -0.5, 1.0), 0.7)
    R1 = rotation((1.0, 0.3, 0.1), 1.9) @ R0
    u = np.linspace(0.0, 1.0, 11)
    turn = pk.hand_turn(R0, R1, u)
    np.testing.assert_allclose(turn[0], axes_of(R0), atol=1e-12)
    np.testing.assert_allclose(turn[-1], axes_of(R1), atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(turn, axis=2), 1.0, atol=1e-12)
    # evenly: each axis turns by the same angle at every step (about one fixed axis)
    steps = np.degrees(np.arccos(np.clip(np.sum(turn[1:] * turn[:-1], axis=2), -1.0, 1.0)))
    np.testing.assert_allclose(steps, np.broadcast_to(steps[:1], steps.shape), atol=1e-6)
    assert steps.min() > 0.0
    np.testing.assert_allclose(
        pk.hand_turn(R0, R1, np.array([0.5]))[0],
        axes_of(rotation((1.0, 0.3, 0.1), 0.95) @ R0),
        atol=1e-12,
    )


def test_a_half_turn_is_turned_about_an_axis_it_keeps():
    R0 = rotation((0.0, 1.0, 0.0), 0.3)
    R1 = rotation((1.0, 0.0, 0.0), np.pi) @ R0
    turn = pk.hand_turn(R0, R1, np.array([0.0, 0.5, 1.0]))
    np.testing.assert_allclose(turn[-1], axes_of(R1), atol=1e-9)
    np.testing.assert_allclose(
        turn[1], axes_of(rotation((1.0, 0.0, 0.0), np.pi / 2) @ R0), atol=1e-9
    )


def test_no_turn_between_equal_orientations():
    R = rotation((0.3, 0.4, 0.5), 1.1)
    turn = pk.hand_turn(R, R, np.linspace(0.0, 1.0, 5))
    np.testing.assert_allclose(turn, np.broadcast_to(axes_of(R), turn.shape), atol=1e-12)


PLACE = cn.Place("I_TIP_R", Const((0.3, 0.0, 1.2)), 1e-3, "K")


def key(start: float, end: float, cons=(PLACE,), relax: bool = False) -> Key:
    return Key(start, end, np.zeros(3), tuple(cons), ("a",), relax)


def test_the_keys_around_a_path_end_by_its_start_and_start_by_its_end():
    keys = [key(0.0, 0.3), key(0.35, 0.5), key(1.05, 1.4)]
    assert pk.around(keys, 0.5, 1.05) == (1, 2)
    assert pk.around(keys, 0.6, 1.05) == (1, 2)  # a gap before the path
    assert pk.around(keys, 0.5, 1.0) == (1, 2)  # and after it


@pytest.mark.parametrize(
    "keys",
    [
        [key(0.35, 0.5), key(0.6, 0.9), key(1.05, 1.4)],  # a key of the track inside the path
        [key(0.35, 0.5)],  # none after it
        [key(1.05, 1.4)],  # none before it
        [key(0.35, 0.5, cons=()), key(1.05, 1.4)],  # a hold: no constraint of its own
        [key(0.35, 0.5, relax=True), key(1.05, 1.4)],  # a return to rest
    ],
)
def test_no_keys_around_a_path_without_a_constrained_key_on_either_side(keys):
    assert pk.around(keys, 0.5, 1.05) is None


def test_orients_says_whether_a_constraint_turns_a_bone_of_the_arm(model):
    up = Const((0.0, 0.0, 1.0))
    right_arm = model.body("arm_R").id
    index = cn.Orient("index_R_3", (1.0, 0.0, 0.0), cn.Rel.PERP, up)
    forearm = cn.Orient("f_arm_R", (1.0, 0.0, 0.0), cn.Rel.ALONG, up)
    left = cn.Orient("palm_L", (1.0, 0.0, 0.0), cn.Rel.ALONG, up)
    assert pk.orients((PLACE, index), model, right_arm)
    assert pk.orients((forearm,), model, right_arm)
    assert not pk.orients((PLACE, left), model, right_arm)
    assert not pk.orients((PLACE,), model, right_arm)


def test_hand_orientation_rows_and_jacobian(solver):
    rng = np.random.default_rng(3)
    q = solver.natural + 0.2 * rng.normal(size=solver.natural.shape)
    q = np.clip(q, solver.lower, solver.upper)
    want = axes_of(rotation((0.1, 0.7, -0.2), 0.8))
    pref = pk.HandOrientation("palm_R", want)
    rows, J = pref.rows(solver.at(q, jacobians=True))
    k = solver.at(q)
    axes = np.array([k.value(BodyAxis("palm_R", a)) for a in pk.HAND_AXES])  # the geometry's
    np.testing.assert_allclose(pk.hand_axes(k, "palm_R"), axes, atol=1e-12)
    np.testing.assert_allclose(rows, (axes - want).ravel() / pref.tol, atol=1e-9)
    h = 1e-6
    for v in range(solver.model.nv):  # hinge joints only: dof v is qpos v
        dq = np.zeros_like(q)
        dq[v] = h
        fd = (pref.rows(solver.at(q + dq))[0] - pref.rows(solver.at(q - dq))[0]) / (2 * h)
        np.testing.assert_allclose(J[:, v], fd, atol=1e-4)


def test_body_rotation_is_the_bodys_frame(solver):
    k = solver.at(solver.natural)
    R = pk.body_rotation(k, "palm_R")
    from_quat = np.zeros(9)  # the body's orientation as MuJoCo keeps it, a quaternion
    mujoco.mju_quat2Mat(from_quat, solver.data.xquat[solver.model.body("palm_R").id])
    np.testing.assert_allclose(R, from_quat.reshape(3, 3), atol=1e-12)
    for i in range(3):  # its columns: the body's axes
        np.testing.assert_allclose(R[:, i], k.value(BodyAxis("palm_R", tuple(np.eye(3)[i]))))


def penser_right() -> dict:
    s = json.loads((EXAMPLES / "penser.json").read_text())
    return {**s, "strong_side": "R"}


def angle(a: np.ndarray, b: np.ndarray) -> float:
    """Degrees between two hand orientations given by their axes (2, 3)."""
    Ra = np.column_stack([a[0], a[1], np.cross(a[1], a[0])])
    Rb = np.column_stack([b[0], b[1], np.cross(b[1], b[0])])
    return float(np.degrees(np.arccos(np.clip((np.trace(Ra.T @ Rb) - 1.0) / 2.0, -1.0, 1.0))))


def test_penser_before_its_circle_holds_the_hand_as_it_touches_after_it(solver):
    # NEAR leaves the hand free: solved for its placement alone, its hand can stand far from
    # TOUCH's (82 degrees when TOUCH asked the index level), and the hand then turned over
    # during the circle. Solved again from TOUCH, it holds the hand as TOUCH does.
    adapter = IKAdapter(Schedule(load_score(penser_right()), solver))
    near, touch = KeyPoser(adapter, Mode.MULTITRACK).key_postures()["arm_R"]
    assert [c.label for c in near.cons] == ["PENSER.NEAR#1"]
    turned = angle(*(pk.hand_axes(adapter.at(k.q), "palm_R") for k in (near, touch)))
    assert turned < 10.0
    k = adapter.at(near.q)
    assert near.cons[0].residual(k) <= near.cons[0].tol
    assert adapter.depth(near.q) <= cn.COLLISION_TOL


def test_penser_circle_is_one_speed_bell():
    r = realize(load_score(json.loads((EXAMPLES / "penser.json").read_text())), fps=FPS)
    pos = r.site_pos[:, r.site_names.index("WR_L")]
    mid = r.score_start + 0.5 * (0.5 + 1.05)  # the circle's middle
    moves = [m for m in mv.movements(pos, FPS) if r.time[m.first] <= mid <= r.time[m.last]]
    assert len(moves) == 1
    assert moves[0].peaks == 1  # 2 before (SPARC -1.75)
    assert moves[0].sparc >= -1.45
    tip = r.site_pos[:, r.site_names.index("I_TIP_L")]
    sel = slice(moves[0].first, moves[0].last + 1)
    wrist_path = np.linalg.norm(np.diff(pos[sel], axis=0), axis=1).sum()
    tip_path = np.linalg.norm(np.diff(tip[sel], axis=0), axis=1).sum()
    assert wrist_path < 1.1 * tip_path  # the hand carried around the circle, not turned over


def test_a_wide_sweep_keeps_its_keys(solver):
    # The ends of a path more than a hand's length apart: the forearm turns over the
    # sweep, and the hand with it.
    score = load_score(json.loads((EXAMPLES.parent / "bench/data/motion/sweep.json").read_text()))
    adapter = IKAdapter(Schedule(score, solver))
    poser = KeyPoser(adapter, Mode.MULTITRACK)
    keys = poser.key_postures()
    site = adapter.schedule.comp.site(
        next(b for b in score.blocks() if b.kind.value == "transpath").transpath_site
    )
    first, second = keys["arm_R"][0], keys["arm_R"][1]
    ends = [adapter.at(k.q).value(SitePos(site)) for k in (first, second)]
    assert np.linalg.norm(ends[1] - ends[0]) > pk.NEAR_ENDS
    before = [k.q.copy() for k in keys["arm_R"]]
    pk.lead_into_paths(adapter, keys)
    for b, k in zip(before, keys["arm_R"]):
        np.testing.assert_array_equal(b, k.q)
