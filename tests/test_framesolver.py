"""Constrained blend frames: the curve preference's rows against finite differences, the
reach bounds, and frames that hold a placement while the other joints blend."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from azee_mj import timeline
from azee_mj.blend import MAX_JOINT_SPEED
from azee_mj.framesolver import CURVE_TOL, TURN_TOL, FrameSolver, transpath
from azee_mj.ikadapter import IKAdapter
from azee_mj.keyposes import KeyPoser
from azee_mj.schedule import Mode, Schedule
from azee_mj.score import load_score

FPS = 50.0
ROOT = Path(__file__).resolve().parent.parent


def _adapter(solver, constraints=()) -> IKAdapter:
    score = load_score(
        {
            "format": "azee-score",
            "version": 1,
            "root": {
                "name": "F",
                "kind": "cstr",
                "start": 0.0,
                "end": 1.0,
                "constraints": list(constraints),
            },
        }
    )
    return IKAdapter(Schedule(score, solver))


def test_curve_preference_rows_and_jacobian(solver):
    fs = FrameSolver(_adapter(solver), FPS)
    joints = ["arm_R_flex", "f_arm_R_flex", "palm_R_dev"]
    qf = solver.natural.copy()
    pref = fs.curve_preference(qf, joints)
    rng = np.random.default_rng(1)
    q = qf + 0.1 * rng.normal(size=qf.shape)
    rows, J = pref.rows(solver.at(q))
    adr = [solver.model.jnt_qposadr[solver.joint_id(j)] for j in joints]
    np.testing.assert_allclose(rows, (q[adr] - qf[adr]) / CURVE_TOL)
    h = 1e-6
    for v in range(solver.model.nv):  # hinge joints only: dof v is qpos v
        dq = np.zeros_like(q)
        dq[v] = h
        fd = (pref.rows(solver.at(q + dq))[0] - pref.rows(solver.at(q - dq))[0]) / (2 * h)
        np.testing.assert_allclose(J[:, v], fd, atol=1e-6)


def test_reach_bounds_keep_a_track_within_steps_of_its_goal(solver):
    fs = FrameSolver(_adapter(solver), FPS)
    assert fs.step == MAX_JOINT_SPEED / FPS
    T, names = 10, ["arm_R", "head"]
    curve = np.tile(solver.natural, (T, 1))
    d = fs.schedule.track_dofs["arm_R"]
    curve[:, d] += np.linspace(0.0, 1.0, T)[:, None]
    q = curve.copy()
    goal = np.array([8, -1])  # arm_R arrives at frame 8; the head blends to the end
    lo, hi = fs.reach(q, curve, goal, 3, names, {"arm_R", "head"})
    n, step = 8 - 3, fs.step
    np.testing.assert_allclose(
        lo[d], np.clip(np.maximum(solver.lower[d], curve[8][d] - n * step), q[2][d] - step, None)
    )
    assert np.all(hi[d] <= q[2][d] + step + 1e-12) and np.all(lo[d] >= q[2][d] - step - 1e-12)
    other = np.setdiff1d(np.arange(solver.model.nv), d)
    np.testing.assert_array_equal(lo[other], solver.lower[other])
    assert fs.reach(q, curve, np.array([-1, -1]), 3, names, {"arm_R"}) is None


def test_constrained_frames_hold_the_placement_while_the_hand_blends(solver):
    target = [0.3, -0.15, 1.2]
    adapter = _adapter(solver, [{"type": "place", "site": "@I_TIP(s)", "at": target}])
    keys = KeyPoser(adapter, Mode.MULTITRACK).key_postures()
    (key,) = keys["arm_R"]
    T = 12
    times = np.arange(T) / FPS
    q = np.tile(key.q, (T, 1))
    hand = adapter.schedule.track_dofs["hand_R"]
    q[:, hand] += np.linspace(0.0, 0.3, T)[:, None]  # a hand shape blending under it
    moving = np.zeros((T, len(keys)), bool)
    names = list(keys)
    moving[:, names.index("hand_R")] = True
    moving[:, names.index("arm_R")] = True
    out = FrameSolver(adapter, FPS).solve(q.copy(), times, moving, names, keys)
    sid = solver.site_id("I_TIP_R")
    for f in range(T):
        assert np.linalg.norm(solver.at(out[f]).d.site_xpos[sid] - target) <= 1e-3
    assert np.abs(np.diff(out, axis=0)).max() <= MAX_JOINT_SPEED / FPS + 1e-9


def _path_of(solver, score_dict, name: str):
    """The transpath ``name`` of a score on its realized frames."""
    score = load_score(score_dict)
    r = timeline.realize(score, solver=solver)
    adapter = IKAdapter(Schedule(score, solver))
    block = next(b for b in score.blocks() if b.transpath_site and b.path.endswith(name))
    return transpath(adapter, block, r.qpos, r.time - r.score_start)


def test_a_hand_turns_along_a_circle_and_is_left_to_its_blend_across_a_sweep(solver):
    penser = json.loads((ROOT / "examples" / "penser.json").read_text())
    circle = _path_of(solver, {**penser, "strong_side": "R"}, "CIRCLE")
    assert circle.hand == "palm_R"
    assert circle.turn.shape == (len(circle.points), 2, 3)
    np.testing.assert_allclose(np.linalg.norm(circle.turn, axis=2), 1.0, atol=1e-12)
    assert circle.turned(circle.first)[0].tol == TURN_TOL
    sweep = json.loads((ROOT / "bench" / "data" / "motion" / "sweep.json").read_text())
    wide = _path_of(solver, sweep, "SWEEP")  # its ends 0.43 m apart, an arc
    assert wide.hand is None and wide.turned(wide.first) == ()
