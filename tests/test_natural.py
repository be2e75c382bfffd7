"""Natural postures: the effort term, its gradient, strict priorities, seeds, mirror, speed."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import mujoco
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scores import cstr, envelope, shaped, sync

from azee_mj import constraints as cn
from azee_mj import ergonomics, ik, mirror, natural, reach, timeline
from azee_mj.anatomy import SignerAnatomy
from azee_mj.kinematics import Const, Lin, SitePos
from azee_mj.sites import DEFAULT_MAP

DATA = Path(__file__).parent / "data"


def _posture(m: mujoco.MjModel, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    lo, hi = m.jnt_range[m.dof_jntid].T
    return np.where(m.jnt_limited[m.dof_jntid], rng.uniform(lo, hi), 0.0)


def _fk(m, d, q):
    d.qpos[:] = q
    mujoco.mj_kinematics(m, d)
    mujoco.mj_comPos(m, d)


def test_effort_torques_are_mujocos_gravity_torques(solver):
    m = mujoco.MjModel.from_xml_path(str(__import__("azee_mj").MODEL_PATH))
    m.body_gravcomp[:] = 0.0
    d = mujoco.MjData(m)
    hinges = np.flatnonzero(m.jnt_type[m.dof_jntid] == mujoco.mjtJoint.mjJNT_HINGE)
    effort = natural.Effort(m, hinges)
    for seed in range(5):
        d.qpos[:] = _posture(m, seed)
        d.qvel[:] = 0.0
        mujoco.mj_forward(m, d)
        np.testing.assert_allclose(effort.torques(d), -d.qfrc_bias[hinges], atol=1e-10)


@settings(
    max_examples=15, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(seed=st.integers(0, 10_000))
def test_effort_jacobian_matches_finite_differences(solver, seed):
    m, d = solver.model, mujoco.MjData(solver.model)
    q = _posture(m, seed)
    dofs = solver.effort_dofs
    effort = natural.Effort(m, dofs)
    _fk(m, d, q)
    J = effort.jacobian(d, dofs)
    fd = np.empty_like(J)
    h = 1e-6
    for c, k in enumerate(dofs):
        tau = []
        for s in (1.0, -1.0):
            qq = q.copy()
            qq[k] += s * h
            _fk(m, d, qq)
            tau.append(effort.torques(d))
        fd[:, c] = (tau[0] - tau[1]) / (2 * h)
    np.testing.assert_allclose(J, fd, atol=1e-6 * max(1.0, np.abs(fd).max()))


def test_natural_rows_jacobian_matches_finite_differences(solver):
    m, d = solver.model, mujoco.MjData(solver.model)
    nat = solver.naturalness
    effort = natural.Effort(m, solver.effort_dofs)
    cols = np.array([solver.joint_id(j) for j in DEFAULT_MAP.tracks["arm_R"]])
    q = _posture(m, 3)
    _fk(m, d, q)
    r, J = natural.rows(nat, effort, d, cols)
    h = 1e-6
    for c, k in enumerate(cols):
        qq = q.copy()
        qq[k] += h
        _fk(m, d, qq)
        rp, _ = natural.rows(nat, effort, d, cols)
        np.testing.assert_allclose((rp - r) / h, J[:, c], atol=1e-4)


def test_a_hanging_arm_costs_no_effort_and_a_raised_one_does(solver):
    m, d = solver.model, mujoco.MjData(solver.model)
    effort = natural.Effort(m, solver.effort_dofs)
    shoulder = list(solver.effort_dofs).index(solver.joint_id("arm_R_flex"))
    _fk(m, d, solver.natural)
    hanging = abs(effort.torques(d)[shoulder])
    q = solver.natural.copy()
    q[solver.joint_id("arm_R_flex")] = np.pi / 2  # arm straight forward
    _fk(m, d, q)
    raised = abs(effort.torques(d)[shoulder])
    # the whole arm's weight (about 3 kg) about 0.3 m out, against a relaxed arm
    assert raised > 5.0
    assert hanging < 0.05 * raised


def _chin_problem(solver):
    arm = tuple(DEFAULT_MAP.tracks["arm_R"])
    return ik.IKProblem((cn.Place("I_TIP_R", SitePos("CH"), 1e-3, "chin"),), arm)


def _index_hand(solver):
    q = solver.natural.copy()
    for mid, w in (("fist", 1.0), ("index_bend", -1.04), ("index_hook", -1.1)):
        for j, v in DEFAULT_MAP.morphs[mid].joint_changes("R").items():
            q[solver.joint_id(j)] += w * v
    return np.clip(q, solver.lower, solver.upper)


def _cost(solver, problem, q):
    d = solver.data
    _fk(solver.model, d, q)
    plan = solver.plan(problem)
    r, _ = natural.rows(solver.naturalness, plan.effort, d, plan.free)
    return float(r @ r)


def test_the_natural_term_never_moves_a_met_constraint(solver):
    # Solved first without naturalness (the first posture reached), then polished: the
    # polish lowers the natural cost and the constraint stays within 5 % of its tolerance.
    q0 = _index_hand(solver)
    problem = _chin_problem(solver)
    plain = solver.solve(ik.IKProblem(problem.constraints, problem.free_joints, natural=False), q0)
    assert plain.converged
    polished = solver.solve(problem, plain.qpos)
    assert polished.converged
    assert polished.residuals[0].value <= 0.05e-3
    assert _cost(solver, problem, polished.qpos) < 0.8 * _cost(solver, problem, plain.qpos)


#: The index-pointing hand shape of the scores below (fist, index straight).
INDEX_SHAPE = [
    {"type": "morph", "id": "fist", "weight": 1.0},
    {"type": "morph", "id": "index_bend", "weight": -1.04},
    {"type": "morph", "id": "index_hook", "weight": -1.1},
]


def test_the_hand_goes_to_the_face_not_the_face_to_the_hand(solver):
    score = shaped(INDEX_SHAPE, 0.4, 1.0, {"type": "place", "site": "@I_TIP(s)", "at": "@TE(s)"})
    rollout = timeline.realize(score, solver=solver)
    assert all(t.ok for t in rollout.traces)
    head_and_trunk = [solver.joint_id(j) for t in ("head", "spine") for j in DEFAULT_MAP.tracks[t]]
    assert np.abs(rollout.qpos[:, head_and_trunk]).max() == 0.0


#: The wrist 0.45 m in front of the signing space: out of the arm's reach alone.
_FAR_WRIST = {"type": "place", "site": "@WR(s)", "at": {"translate": "^ssp", "by": [0.45, 0, 0]}}


def test_recruited_trunk_returns_to_neutral(solver):
    # Out of the arm's reach alone: the trunk leans to help, then straightens once the
    # block has ended.
    score = envelope(sync("R", 2.0, cstr("FAR", 0.3, 0.8, _FAR_WRIST)))
    rollout = timeline.realize(score, solver=solver)
    spine = [solver.joint_id(j) for j in DEFAULT_MAP.tracks["spine"]]
    assert all(t.ok for t in rollout.traces)
    assert np.abs(rollout.qpos[rollout.time - rollout.score_start < 0.8][:, spine]).max() > 0.05
    np.testing.assert_allclose(rollout.qpos[-1, spine], solver.natural[spine], atol=1e-9)


def test_a_recruited_trunk_leans_no_further_than_the_arm_needs(solver):
    # The wrist 0.45 m in front of the signing space: the trunk must lean. Held at 85 % of
    # the lean the realizer keeps (toward neutral), the arm alone no longer reaches.
    score = envelope(sync("R", 1.0, cstr("FAR", 0.3, 0.8, _FAR_WRIST)))
    rollout = timeline.realize(score, solver=solver)
    assert all(t.ok for t in rollout.traces)
    key = rollout.qpos[np.argmin(np.abs(rollout.time - rollout.score_start - 0.5))]
    spine = [solver.joint_id(j) for j in DEFAULT_MAP.tracks["spine"]]
    assert np.abs(key[spine] - solver.natural[spine]).max() > 0.05
    q = key.copy()
    q[spine] = solver.natural[spine] + 0.85 * (key[spine] - solver.natural[spine])
    target = Lin(((1.0, SitePos("ssp")), (1.0, Const((0.45, 0.0, 0.0)))))
    problem = ik.IKProblem(
        (cn.Place("WR_R", target, 1e-3, "far"),), tuple(DEFAULT_MAP.tracks["arm_R"])
    )
    assert not solver.solve(problem, q).converged


def test_a_look_turns_the_head_only_as_far_as_the_gaze_needs_when_the_trunk_helps(solver):
    # Pointing at ^Rssp from half way between the sternum and the locus, along that line,
    # palm exactly down: the arm alone cannot (the index is straight, the line falls 13.9
    # degrees, the wrist deviates 30 degrees at most), so the trunk helps the arm; the look at
    # ^Rssp (12 degrees of head alone) is then solved on the moved trunk, not carried along.
    score = shaped(
        INDEX_SHAPE,
        0.35,
        0.8,
        {
            "type": "place",
            "site": "@I_TIP(s)",
            "at": {
                "translate": {"mid": ["@ST(s)", "^Rssp"]},
                "by": {"scale": "fwd", "by": 0.05},
            },
        },
        {
            "type": "orient",
            "bone": "!index(s,1)",
            "axis": "dir",
            "rel": "along",
            "vector": {"from": "@ST(s)", "to": "^Rssp"},
        },
        {"type": "orient", "bone": "!palm(s)", "axis": "nrm", "rel": "along", "vector": "down"},
        {"type": "look", "at": "^Rssp"},
        names=("P", "HS", "IX"),
    )
    rollout = timeline.realize(score, solver=solver)
    assert all(t.ok for t in rollout.traces)
    tilt = [ergonomics.ergonomics(solver.model, q) for q in rollout.qpos]
    assert max(e.trunk_angle for e in tilt) > np.radians(5.0)  # recruited
    assert max(e.head_angle for e in tilt) <= np.radians(15.0)


def test_two_bone_seed_puts_the_wrist_on_target_with_the_elbow_below(solver):
    m, d = solver.model, mujoco.MjData(solver.model)
    rng = np.random.default_rng(1)
    for arm in reach.arms_of(DEFAULT_MAP):
        for _ in range(20):
            _fk(m, d, solver.natural)
            shoulder = d.xpos[solver.body_id(arm.upper)].copy()
            wrist = d.xpos[solver.body_id(arm.hand)].copy()
            target = shoulder + rng.uniform([0.15, -0.25, -0.3], [0.45, 0.25, 0.15])
            if np.linalg.norm(target - shoulder) > 0.5:
                continue
            q = solver.natural.copy()
            for j, v in reach.arm_seed(m, d, arm, wrist, target).items():
                q[solver.joint_id(j)] = v
            _fk(m, d, q)
            np.testing.assert_allclose(d.xpos[solver.body_id(arm.hand)], target, atol=1e-9)
            elbow = d.xpos[solver.body_id(arm.fore)]
            line = (target - shoulder) / np.linalg.norm(target - shoulder)
            below = elbow - shoulder - line * ((elbow - shoulder) @ line)
            assert below[2] < 0.0  # the elbow hangs below the shoulder-wrist line


def test_a_pad_seed_brings_the_hand_in_along_the_surface(solver):
    """A pad lies on the surface: the wrist stops short of the target by the pad's
    distance from it, along the surface (no part along its normal), and the two-bone
    solution puts it there."""
    m, d = solver.model, mujoco.MjData(solver.model)
    for arm in reach.arms_of(DEFAULT_MAP):
        _fk(m, d, solver.natural)
        shoulder = d.xpos[solver.body_id(arm.upper)].copy()
        wrist = d.xpos[solver.body_id(arm.hand)].copy()
        pad = d.site_xpos[solver.site_id(f"I_PAD_{'R' if arm.out < 0 else 'L'}")].copy()
        target = shoulder + np.array([0.2, -0.1 * arm.out, 0.05])
        normal = np.array([0.8, 0.0, 0.6])  # the surface faces forward and up
        q = solver.natural.copy()
        for j, v in reach.arm_seed(m, d, arm, pad, target, lying=normal).items():
            q[solver.joint_id(j)] = v
        _fk(m, d, q)
        w = d.xpos[solver.body_id(arm.hand)]
        assert (target - w) @ normal == pytest.approx(0.0, abs=1e-9)
        assert np.linalg.norm(target - w) == pytest.approx(np.linalg.norm(pad - wrist))


def test_a_rising_seed_puts_the_wrist_under_the_target_with_the_elbow_hanging(solver):
    """The hand brought up from below: the wrist under the target by the hand point's
    distance from it, the elbow in the vertical plane through shoulder and wrist, below
    them; only the arms asked are moved."""
    m, d = solver.model, mujoco.MjData(solver.model)
    k = solver.at(solver.natural)
    temple = k.value(SitePos("TE_R"))
    place = cn.Place("I_TIP_R", Const(tuple(temple)), 1e-3, "temple")
    (right,) = [a for a in reach.arms_of(DEFAULT_MAP) if a.upper == "arm_R"]
    tip, wrist0 = k.value(SitePos("I_TIP_R")), solver.data.xpos[solver.body_id(right.hand)].copy()
    q = reach.rising_seed(
        solver, {right}, [place], solver.natural, SignerAnatomy(m, DEFAULT_MAP).hand_of
    )
    _fk(m, d, q)
    wrist = d.xpos[solver.body_id(right.hand)]
    np.testing.assert_allclose(wrist, temple - [0, 0, np.linalg.norm(tip - wrist0)], atol=1e-9)
    shoulder, elbow = d.xpos[solver.body_id(right.upper)], d.xpos[solver.body_id(right.fore)]
    normal = np.cross(wrist - shoulder, [0.0, 0.0, 1.0])
    assert (elbow - shoulder) @ normal == pytest.approx(0.0, abs=1e-9)  # swivel 0
    assert elbow[2] < min(shoulder[2], wrist[2])
    left = [solver.model.jnt_qposadr[solver.joint_id(j)] for j in ("arm_L_flex", "f_arm_L_flex")]
    np.testing.assert_array_equal(q[left], solver.natural[left])


def test_two_bone_seed_turns_the_elbow_by_its_swivel(solver):
    m, d = solver.model, mujoco.MjData(solver.model)
    arm = reach.arms_of(DEFAULT_MAP)[0]
    _fk(m, d, solver.natural)
    shoulder = d.xpos[solver.body_id(arm.upper)].copy()
    target = shoulder + np.array([0.3, -0.1, -0.15])
    wrist = d.xpos[solver.body_id(arm.hand)].copy()
    line = (target - shoulder) / np.linalg.norm(target - shoulder)
    down = np.array([0.0, 0.0, -1.0]) - line * -line[2]
    down /= np.linalg.norm(down)
    for swivel in (0.0, 0.7, -1.2, 2.5):
        _fk(m, d, solver.natural)
        q = solver.natural.copy()
        for j, v in reach.arm_seed(m, d, arm, wrist, target, swivel=swivel).items():
            q[solver.joint_id(j)] = v
        _fk(m, d, q)
        np.testing.assert_allclose(d.xpos[solver.body_id(arm.hand)], target, atol=1e-9)
        off = d.xpos[solver.body_id(arm.fore)] - shoulder
        off -= line * (off @ line)
        # the swivel is the elbow's angle from hanging straight down, outward positive
        outward = np.cross(line, down) * (1 if np.cross(line, down)[1] * arm.out > 0 else -1)
        assert np.arctan2(off @ outward, off @ down) == pytest.approx(swivel, abs=1e-6)


def test_restarts_try_the_seeders_branches_and_keep_them_only_when_met(solver):
    # The palm far out of reach: no start meets it.
    calls = []
    seeder = solver.seeder

    def spy(s, problem, q):
        out = list(seeder(s, problem, q))
        calls.append(len(out))
        return out

    far = cn.Place("PA_R", Const((0.9, -0.3, 1.0)), 1e-3, "far")
    arm = tuple(DEFAULT_MAP.tracks["arm_R"])
    solver.seeder = spy
    try:
        plain = solver.solve(ik.IKProblem((far,), arm, restarts=1), solver.natural)
        assert calls == [] and plain.restarts == 1  # one restart: the start again only
        res = solver.solve(ik.IKProblem((far,), arm, restarts=3), solver.natural)
        # both arms' seed, the hand turned 4 ways, 4 swivels x (to the target, wrist kept)
        assert calls == [1 + 4 + len(reach.SWIVEL_RETRIES) * 2]
        assert res.restarts == 3 + calls[0]
        # a problem with starts of its own does not ask the seeder
        solver.solve(ik.IKProblem((far,), arm, seeds=(solver.natural,), restarts=3), solver.natural)
        assert len(calls) == 1
        # A failed seed never wins: the residual is the generic restarts' one.
        solver.seeder = None
        generic = solver.solve(ik.IKProblem((far,), arm, restarts=3), solver.natural)
        assert res.residuals[0].value == pytest.approx(generic.residuals[0].value, abs=1e-9)
    finally:
        solver.seeder = seeder


def _stored_problem(path) -> tuple[ik.IKProblem, np.ndarray]:
    doc = json.loads(path.read_text())
    cons = []
    for c in doc["constraints"]:
        target = c.get("target", c.get("vector"))
        expr = Const(tuple(target["const"])) if "const" in target else SitePos(target["site"])
        if "place" in c:
            cons.append(cn.Place(c["place"], expr, c["tol"], c["label"]))
        else:
            cons.append(
                cn.Orient(
                    c["orient"], tuple(c["local"]), cn.Rel(c["rel"]), expr, c["tol"], c["label"]
                )
            )
    return ik.IKProblem(tuple(cons), tuple(doc["free_joints"])), np.array(doc["start"])


@pytest.mark.parametrize(
    "name", ["branch_keyframe", "blocked_contact", "headon_contact", "raised_upper_arm"]
)
def test_a_start_on_another_branch_is_met_from_the_seeders_starts(solver, name):
    # Benchmark keyframes and the warm starts a chain reached them from: an arm on another
    # branch, fingers meeting interlocked, a thumb meeting the chin at a slant, an upper arm
    # raised past the side. The warm start misses; a two-bone arm seed, a turned hand, the
    # solve with the thumb head-on, the shoulder on its other branch meet them.
    problem, start = _stored_problem(DATA / f"{name}.json")
    res = solver.solve(problem, start)
    assert res.converged and res.restarts >= 2


def test_the_generic_restarts_alone_miss_a_keyframe_on_another_branch(solver):
    # Without the seeder's branches, six generic restarts do not find the arm's branch.
    # (The blocked contact of the test above is met by the generic restarts too on the
    # current signer.)
    problem, start = _stored_problem(DATA / "branch_keyframe.json")
    seeder = solver.seeder
    solver.seeder = None
    try:
        generic = solver.solve(dataclasses.replace(problem, restarts=6), start)
    finally:
        solver.seeder = seeder
    assert not generic.converged


def test_a_per_frame_solve_stays_within_its_step(solver):
    q0 = _index_hand(solver)
    far = tuple(np.array([0.35, -0.1, 0.55]))
    problem = ik.IKProblem(
        (cn.Place("I_TIP_R", Const(far), 1e-3, "far"),),
        tuple(DEFAULT_MAP.tracks["arm_R"]),
        max_change=0.1,
    )
    res = solver.solve(problem, q0)
    assert np.abs(res.qpos - q0).max() <= 0.1 + 1e-12


def test_a_per_frame_solve_stays_inside_its_bounds_from_a_start_outside(solver):
    """The bounds a blend frame gets from the key it leads to (within reach of it) hold
    even where the start lies outside them: the start is brought inside first."""
    q0 = _index_hand(solver)
    far = tuple(np.array([0.35, -0.1, 0.55]))
    elbow = solver.model.jnt_qposadr[solver.joint_id("f_arm_R_flex")]
    lo, hi = solver.lower.copy(), solver.upper.copy()
    lo[elbow], hi[elbow] = q0[elbow] + 0.2, q0[elbow] + 0.3
    problem = ik.IKProblem(
        (cn.Place("I_TIP_R", Const(far), 1e-3, "far"),),
        tuple(DEFAULT_MAP.tracks["arm_R"]),
        max_change=0.4,
        bounds=(lo, hi),
    )
    res = solver.solve(problem, q0)
    assert q0[elbow] + 0.2 <= res.qpos[elbow] <= q0[elbow] + 0.3
    assert np.abs(res.qpos - q0).max() <= 0.4 + 1e-12


def test_joints_never_exceed_25_rad_per_s_in_the_examples(solver):
    for name in ("bien", "armoire", "nicht-sondern", "info-about"):
        rollout = timeline.realize(f"examples/{name}.json", solver=solver)
        speed = np.abs(np.diff(rollout.qpos, axis=0)).max() * rollout.fps
        assert speed <= 25.0, (name, speed)


def _mirrored(site_pos: np.ndarray, names) -> np.ndarray:
    idx = [names.index(mirror.mirror_name(n)) for n in names]
    return site_pos[:, idx] * np.array([1.0, -1.0, 1.0])


def test_left_handed_signing_is_the_mirror_of_right_handed(solver):
    import json
    from pathlib import Path

    score = json.loads(Path("examples/bien.json").read_text())
    right = timeline.realize(score, solver=solver)
    left = timeline.realize({**score, "strong_side": "L"}, solver=solver)
    names = list(right.site_names)
    assert np.abs(_mirrored(right.site_pos, names) - left.site_pos).max() < 1e-6
    assert [t.ok for t in left.traces] == [t.ok for t in right.traces]


def test_mirror_of_a_score_swaps_sides_and_reflects(solver):
    from azee_mj.score import load_score

    tip = {
        "type": "place",
        "site": "@I_TIP(s)",
        "at": {"translate": "^ssp", "by": [0.1, 0.2, 0.3]},
    }
    palm = {
        "type": "orient",
        "bone": "!palm(w)",
        "axis": "nrm",
        "rel": "along",
        "vector": {"cross": ["lat(s)", "up"]},
    }
    s = load_score(envelope(cstr("A", 0, 1, tip, palm), strong_side="L"))
    m = mirror.mirror_score(s)
    assert m.strong_side == "R"
    place, orient = m.root.constraints
    assert place.site.name == "I_TIP_R"
    assert place.at.v.xyz == (0.1, -0.2, 0.3)
    assert orient.bone.name == "palm_L"
    # a reflection M turns a x b into -(Ma x Mb)
    assert orient.vector.v.a.name == "right" and orient.vector.v.a.xyz == (0.0, -1.0, 0.0)
    assert mirror.mirror_score(mirror.mirror_score(m)).root.constraints[0] == place


_UNREACHABLE = envelope(
    sync(
        "R",
        1.0,
        cstr(
            "FAR",
            0.3,
            0.8,
            {"type": "place", "site": "@WR(s)", "at": {"translate": "^ssp", "by": [1.2, 0, 0]}},
        ),
        cstr(
            "TWO",
            0.3,
            0.8,
            {"type": "orient", "bone": "!head", "axis": "nrm", "rel": "along", "vector": "left"},
            {"type": "orient", "bone": "!head", "axis": "nrm", "rel": "along", "vector": "right"},
        ),
    )
)


def test_a_miss_says_why(solver):
    rollout = timeline.realize(_UNREACHABLE, solver=solver)
    why = {f"{t.block}#{t.index}": t.reason for t in rollout.traces}
    # said on the posture kept: the trunk upright (it does not bow toward a target it cannot
    # reach; bowed, the clavicle came 293 mm nearer and the message said 462 mm)
    assert why["R.FAR#1"] == (
        "out of reach by 755 mm (the target is 1482 mm from clav_R, the limb reaches 727 mm)"
    )
    spine = [solver.model.jnt_qposadr[solver.joint_id(j)] for j in DEFAULT_MAP.tracks["spine"]]
    assert np.abs(rollout.qpos[:, spine] - solver.natural[spine]).max() <= np.deg2rad(5.0)
    assert why["R.TWO#1"] == "conflicts with R.TWO#2: each can be met without the other"
    assert why["R.TWO#2"] == "conflicts with R.TWO#1: each can be met without the other"


def test_a_collision_names_what_would_pass_through(solver):
    # The back of the fist on the front of the belly: its edge stops on the belly, and face
    # to face the forearm would have to pass through it.
    shape = [{"type": "morph", "id": "fist", "weight": 1, "side": "s"}]
    score = shaped(shape, 0.4, 0.8, {"type": "place", "site": "@H_BACK(s)", "at": "@AB(s)"})
    trace = next(t for t in timeline.realize(score, solver=solver).traces if t.block == "C.K")
    assert not trace.ok
    assert trace.reason == (
        "blocked by a collision between back_1 and palm_R (met only with them 29 mm into each "
        "other); face to face, blocked by a collision between f_arm_R and back_1 (met only "
        "with them 72 mm into each other)"
    )


def test_a_joint_limit_is_named(solver):
    # The face turned straight back: the neck, head and trunk rotations all end at limits.
    back = {"add": ["back", {"scale": "left", "by": 0.2}]}
    score = envelope(
        cstr(
            "L",
            0,
            0.5,
            {"type": "orient", "bone": "!head", "axis": "nrm", "rel": "along", "vector": back},
        )
    )
    (trace,) = timeline.realize(score, solver=solver).traces
    assert not trace.ok
    assert trace.reason.startswith("stopped by the upper limit of joint ")
    assert trace.reason.split("joint ")[1].split(" ")[0] in (
        DEFAULT_MAP.tracks["head"] + DEFAULT_MAP.tracks["spine"]
    )


def test_realize_strict_exits_1_on_a_miss(tmp_path):
    import json

    from azee_mj.cli import main

    score = tmp_path / "far.json"
    score.write_text(json.dumps(_UNREACHABLE))
    out = tmp_path / "far.npz"
    assert main(["realize", str(score), "-o", str(out)]) == 0
    assert main(["realize", str(score), "-o", str(out), "--strict"]) == 1


def test_the_bundled_signer_mirrors(solver):
    jm = mirror.JointMirror.of(solver.model)
    assert jm is not None
    q = _posture(solver.model, 7)
    assert not np.array_equal(jm(q), q)
    np.testing.assert_array_equal(jm(jm(q)), q)


def test_a_blend_pushed_out_of_the_body_stays_under_25_rad_per_s(solver):
    # The flat palm to the other elbow: the blend from rest passes through the body and is
    # pushed out frame by frame, each frame within a step of the one before.
    shape = [{"type": "morph", "id": "flat", "weight": 1, "side": "s"}]
    score = shaped(shape, 0.4, 0.8, {"type": "place", "site": "@PA(s)", "at": "@EL(w)"})
    rollout = timeline.realize(score, solver=solver)
    assert all(t.ok for t in rollout.traces)
    assert np.abs(np.diff(rollout.qpos, axis=0)).max() * rollout.fps <= 25.0
