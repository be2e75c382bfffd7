"""Posture solving on the real signer: Jacobians, convergence, limits, collisions."""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from azee_mj import constraints as cn
from azee_mj import ik, natural
from azee_mj import kinematics as kin
from azee_mj.check import check_poses
from azee_mj.posture.contract import RANGE_FREE
from azee_mj.schedule import make_solver
from azee_mj.sites import DEFAULT_MAP


def _fk(solver, q):
    d = solver.data
    d.qpos[:] = q
    mujoco.mj_kinematics(solver.model, d)
    mujoco.mj_comPos(solver.model, d)
    return d


def _random_arm_posture(solver, rng):
    q = solver.natural.copy()
    for side in "RL":
        for j in DEFAULT_MAP.tracks[f"arm_{side}"]:
            jid = solver.joint_id(j)
            lo, hi = solver.model.jnt_range[jid]
            q[solver.model.jnt_qposadr[jid]] = rng.uniform(
                lo + 0.2 * (hi - lo), hi - 0.2 * (hi - lo)
            )
    return q


PALM_R = DEFAULT_MAP.bones["palm_R"]
FARM_L = DEFAULT_MAP.bones["f_arm_L"]
CONSTRAINTS = [
    cn.Place("I_TIP_R", kin.Const((0.3, -0.1, 0.3))),
    cn.Place("I_TIP_R", kin.SitePos("PA_L")),
    cn.Place(
        "T_TIP_R", kin.Lin(((1.0, kin.SitePos("CH")), (0.06, kin.BodyAxis("head", (1.0, 0, 0)))))
    ),
    cn.Orient("palm_R", PALM_R.nrm, cn.Rel.ALONG, kin.Const((0.0, 0.0, -1.0))),
    cn.Orient("palm_R", PALM_R.dir, cn.Rel.OPP, kin.Const((1.0, 0.0, 0.0))),
    cn.Orient("palm_R", PALM_R.nrm, cn.Rel.PERP, kin.Const((0.0, 1.0, 0.0))),
    cn.Orient("f_arm_R", (0, 0, -1.0), cn.Rel.ALONG, kin.BodyAxis("f_arm_L", FARM_L.dir)),
    cn.Orient(
        "palm_R",
        PALM_R.dir,
        cn.Rel.PERP,
        kin.Unit(kin.Cross(kin.BodyAxis("f_arm_L", FARM_L.dir), kin.Const((0, 0, 1.0)))),
    ),
    cn.Look((("eye_L", (1.0, 0, 0)), ("eye_R", (1.0, 0, 0))), kin.SitePos("I_TIP_R")),
    cn.JointTarget("index_R_1_flex", 0.5),
    # forms the compiled core writes itself besides the ones above
    cn.Orient(
        "index_R_1",
        (0, 0, -1.0),
        cn.Rel.ALONG,
        kin.Lin(((1.0, kin.SitePos("I_TIP_L")), (-1.0, kin.SitePos("WR_R")))),
    ),
    cn.Orient(
        "palm_R",
        PALM_R.nrm,
        cn.Rel.PERP,
        kin.Lin(
            (
                (0.5, kin.SitePos("PA_L")),
                (0.5, kin.SitePos("CH")),
                (-1.0, kin.BodyOrigin("palm_R")),
                (1.0, kin.Const((0.0, 0.1, 0.0))),
            )
        ),
    ),
    cn.Orient(
        "palm_R", PALM_R.dir, cn.Rel.OPP, kin.Lin(((-2.0, kin.BodyAxis("f_arm_L", FARM_L.dir)),))
    ),
    cn.Orient(
        "palm_R",
        PALM_R.dir,
        cn.Rel.ALONG,
        kin.Lin(((1.0, kin.Const((0.0, 0.0, 1.0))), (1.0, kin.Const((0.6, 0.0, 0.0))))),
    ),
    cn.Place(
        "I_TIP_R",
        kin.Lin(
            (
                (0.5, kin.SitePos("PA_L")),
                (0.5, kin.BodyOrigin("head")),
                (1.0, kin.Const((0.0, 0.05, 0.0))),
            )
        ),
    ),
    cn.Look((("eye_L", (1.0, 0, 0)), ("eye_R", (1.0, 0, 0))), kin.Const((0.4, 0.1, 0.3))),
    # round ends (fingertips): one end on a flat site, two ends meeting
    cn.Place(
        "I_TIP_R",
        kin.SitePos("PA_L"),
        shift=kin.Lin(
            (
                (-0.0068, kin.BodyAxis("index_R_3", (0.0, 0.0, -1.0))),
                (-0.0068, kin.BodyAxis("palm_L", (0.0, 1.0, 0.0))),
            )
        ),
    ),
    cn.Place(
        "I_TIP_R",
        kin.SitePos("T_TIP_R"),
        shift=kin.Lin(
            (
                (-0.0068, kin.BodyAxis("index_R_3", (0.0, 0.0, -1.0))),
                (0.0085, kin.BodyAxis("thumb_R_3", (0.422, 0.052, -0.905))),
            )
        ),
        gap=0.0153,
    ),
]


@pytest.mark.parametrize("c", CONSTRAINTS, ids=lambda c: type(c).__name__)
def test_jacobian_matches_finite_differences(solver, c):
    rng = np.random.default_rng(3)
    q = _random_arm_posture(solver, rng)
    plan = solver.plan(ik.IKProblem((c,), tuple(j for t in DEFAULT_MAP.tracks.values() for j in t)))
    _fk(solver, q)
    r0, J = (x.copy() for x in plan.rows())
    eps = 1e-6
    fd = np.zeros_like(J)
    for i in range(solver.model.nv):
        dq = q.copy()
        dq[i] += eps
        _fk(solver, dq)
        fd[:, i] = (plan.rows()[0] - r0) / eps
    scale = max(1.0, np.abs(J).max())
    np.testing.assert_allclose(J, fd, atol=1e-4 * scale)


@pytest.mark.parametrize("c", CONSTRAINTS, ids=lambda c: type(c).__name__)
def test_fast_rows_equal_expression_rows(solver, c):
    """The compiled core's rows equal those of the general expression evaluator
    (:meth:`Constraint.rows` on :class:`~azee_mj.kinematics.Kinematics`)."""
    q = _random_arm_posture(solver, np.random.default_rng(4))
    plan = solver.plan(ik.IKProblem((c,)))
    _fk(solver, q)
    r, J = plan.rows()
    rg, Jg = c.rows(solver.kinematics())
    np.testing.assert_allclose(r, rg, atol=1e-9)
    np.testing.assert_allclose(J, Jg, atol=1e-9)


def test_connect_equality_rows_are_mujocos(solver):
    """Placements mirrored as connect equalities give MuJoCo the rows the solver uses."""
    problem = ik.IKProblem(
        (cn.Place("I_TIP_R", kin.Const((0.3, -0.1, 0.3))), cn.Place("I_TIP_L", kin.SitePos("PA_R")))
    )
    m = solver.model
    m.opt.jacobian = mujoco.mjtJacobian.mjJAC_DENSE
    d = mujoco.MjData(m)
    assert solver.configure_equalities(problem, d) == 2
    d.qpos[:] = _random_arm_posture(solver, np.random.default_rng(5))
    mujoco.mj_forward(m, d)
    eq_rows = np.flatnonzero(d.efc_type[: d.nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY)
    assert eq_rows.size == 6
    efc_J = d.efc_J[: d.nefc * m.nv].reshape(d.nefc, m.nv)
    plan = solver.plan(problem)
    solver.data.qpos[:] = d.qpos
    mujoco.mj_kinematics(m, solver.data)
    mujoco.mj_comPos(m, solver.data)
    r, J = plan.rows()
    np.testing.assert_allclose(d.efc_pos[eq_rows], r * 1e-3, atol=1e-12)
    np.testing.assert_allclose(efc_J[eq_rows], J * 1e-3, atol=1e-9)
    solver.configure_equalities(ik.IKProblem(()), d)
    m.opt.jacobian = mujoco.mjtJacobian.mjJAC_AUTO


def test_reachable_problems_converge_to_a_tenth_of_a_millimetre(solver):
    rng = np.random.default_rng(7)
    free = DEFAULT_MAP.tracks["arm_R"] + DEFAULT_MAP.tracks["arm_L"]
    for _ in range(8):
        truth = _random_arm_posture(solver, rng)
        d = _fk(solver, truth)
        if cn.penetration_depth(solver.model, d) > 0:
            continue
        d = _fk(solver, truth)
        cons = tuple(
            cn.Place(s, kin.Const(tuple(d.site_xpos[solver.site_id(s)])))
            for s in ("I_TIP_R", "WR_R", "I_TIP_L", "WR_L")
        )
        res = solver.solve(ik.IKProblem(cons, free), solver.natural)
        assert res.converged
        assert max(r.value for r in res.residuals) < 1e-4


def test_out_of_reach_target_reports_its_residual(solver):
    target = np.array([1.5, -0.4, 0.4])
    res = solver.solve(ik.IKProblem((cn.Place("M_TIP_R", kin.Const(tuple(target))),)))
    assert not res.converged
    assert np.all(np.isfinite(res.qpos))
    d = _fk(solver, res.qpos)
    tip = d.site_xpos[solver.site_id("M_TIP_R")]
    assert res.residuals[0].value == pytest.approx(np.linalg.norm(tip - target), abs=1e-9)
    # The best posture reaches out toward the target: the residual is the distance left
    # once the arm is stretched (shoulder-to-target minus the limb length, within 5 cm).
    shoulder = d.xpos[solver.body_id("arm_R")]
    reach = np.linalg.norm(tip - shoulder)
    assert res.residuals[0].value == pytest.approx(
        np.linalg.norm(target - shoulder) - reach, abs=0.05
    )
    assert (
        np.dot(tip - shoulder, target - shoulder) / (reach * np.linalg.norm(target - shoulder))
        > 0.99
    )


@settings(
    max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(st.tuples(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0), st.floats(-0.6, 1.2)))
def test_joint_limits_are_never_exceeded(solver, target):
    res = solver.solve(
        ik.IKProblem(
            (
                cn.Place("I_TIP_R", kin.Const(target)),
                cn.Orient("palm_R", PALM_R.nrm, cn.Rel.ALONG, kin.Const((0, 0, 1.0))),
            )
        )
    )
    m = solver.model
    q = res.qpos[m.jnt_qposadr]
    assert np.all(q >= m.jnt_range[:, 0]) and np.all(q <= m.jnt_range[:, 1])
    assert np.all(np.isfinite(res.qpos))


def test_hand_pushed_into_the_face_stops_at_the_skin(solver):
    d = _fk(solver, solver.natural)
    nose = d.site_xpos[solver.site_id("NO")]
    inside = nose + np.array([-0.06, 0.0, 0.0])  # 6 cm behind the nose tip, inside the head
    arm = DEFAULT_MAP.tracks["arm_R"]
    res = solver.solve(ik.IKProblem((cn.Place("I_TIP_R", kin.Const(tuple(inside))),), arm))
    assert not res.converged
    assert res.penetration <= cn.PENETRATION_LIMIT
    report = check_poses(solver.model, res.qpos)
    assert report.clean, report
    # It got as close as the skin allows: within a few centimetres of the nose tip.
    tip = _fk(solver, res.qpos).site_xpos[solver.site_id("I_TIP_R")]
    assert np.linalg.norm(tip - nose) < 0.04


def test_fingertip_contact_touches_without_interpenetration():
    solver = make_solver(seed=0)
    # Index fingertips touch, the other fingers curled (the pointing hand shape).
    curl = tuple(
        cn.JointTarget(f"{f}_{x}_{n}_flex", v)
        for x in "RL"
        for f in ("middle", "ring", "little")
        for n, v in ((1, 1.5), (2, 1.6), (3, 1.0))
    )
    res = solver.solve(ik.IKProblem((cn.Place("I_TIP_R", kin.SitePos("I_TIP_L")),) + curl))
    assert res.converged, res.residuals
    assert res.residuals[0].value <= 1e-3
    report = check_poses(solver.model, res.qpos)  # nothing deeper than 1 mm
    assert report.clean, report.penetrations
    assert report.max_depth[0] <= cn.CONTACT_ALLOWANCE + 1e-5


def test_pose_check_finds_a_penetration_made_on_purpose(solver):
    m = solver.model
    assert check_poses(m, solver.natural).clean
    q = solver.natural.copy()
    # Swing the right arm across the chest: the forearm goes through the torso.
    for j, v in (("arm_R_flex", 0.3), ("arm_R_abd", -0.5), ("f_arm_R_flex", 0.0)):
        q[m.jnt_qposadr[solver.joint_id(j)]] = v
    report = check_poses(m, q)
    assert not report.clean
    assert report.penetrations[0].depth > 1e-3
    assert any(
        "arm_R" in p.geom1 + p.geom2 or "f_arm_R" in p.geom1 + p.geom2 for p in report.penetrations
    )


def _penetrating_posture(solver, depth=0.01):
    """The right hand pushed ``depth`` [m] into the chest: several collision rows."""
    d = _fk(solver, solver.natural)
    chest = d.site_xpos[solver.site_id("CH")].copy()
    res = solver.solve(
        ik.IKProblem(
            (cn.Place("PA_R", kin.Const(tuple(chest + [-depth, 0, 0]))),),
            DEFAULT_MAP.tracks["arm_R"],
            collide=False,
        ),
        solver.natural,
    )
    return res.qpos


def _rigid(m, free):
    """rigid(a, b): no dof of ``free`` on the tree path between bodies a and b."""
    moving = set(m.dof_bodyid[free])

    def chain(x):
        out = []
        while x > 0:
            out.append(x)
            x = m.body_parentid[x]
        return set(out)

    return lambda a, b: not (chain(a) ^ chain(b)) & moving


def _contacts(solver, q, near=False):
    """MuJoCo's own contacts of posture q: (dist, geom pairs) in mj_collision's order;
    without the margin (the core's rows are for penetrations only) unless ``near``."""
    m, d = solver.model, solver.data
    margin = m.geom_margin.copy()
    m.geom_margin[:] = margin if near else 0.0
    try:
        _fk(solver, q)
        mujoco.mj_collision(m, d)
    finally:
        m.geom_margin[:] = margin
    return d.contact.dist[: d.ncon].copy(), d.contact.geom[: d.ncon].copy()


def test_collision_rows_match_finite_differences(solver):
    """Each collision row is d(dist)/dq / COLLISION_TOL of its contact over the free dofs,
    checked where MuJoCo's distance is smooth (capsule and sphere pairs; ellipsoids go
    through GJK/EPA and boxes have edges)."""
    q = _penetrating_posture(solver, 0.002)
    m = solver.model
    plan = solver.plan(ik.IKProblem((), DEFAULT_MAP.tracks["arm_R"]))
    r0, J0, _, depth = plan.core.evaluate(q, True)
    r0 = np.frombuffer(r0)
    J0 = np.frombuffer(J0).reshape(r0.size, plan.free.size)
    dist, geoms = _contacts(solver, q)
    rigid = _rigid(m, plan.free)
    hits = [
        k
        for k in range(dist.size)  # no pair may touch: floor 0
        if dist[k] < 0 and not rigid(*m.geom_bodyid[geoms[k]])
    ]
    assert len(hits) == r0.size and depth > 0
    np.testing.assert_allclose(r0, dist[hits] / cn.COLLISION_TOL)
    smooth = (int(mujoco.mjtGeom.mjGEOM_SPHERE), int(mujoco.mjtGeom.mjGEOM_CAPSULE))
    rows = [i for i, c in enumerate(hits) if all(m.geom_type[g] in smooth for g in geoms[c])]
    assert len(rows) >= 2
    eps = 1e-7
    fd = np.zeros((len(rows), plan.free.size))
    for k, dof in enumerate(plan.free):
        dq = q.copy()
        dq[dof] += eps
        r1 = np.frombuffer(plan.core.evaluate(dq, True)[0])
        assert r1.size == r0.size
        fd[:, k] = (r1[rows] - r0[rows]) / eps
    np.testing.assert_allclose(J0[rows], fd, atol=1e-3 * np.abs(J0[rows]).max())


def test_collision_rows_are_mujocos_contacts_less_the_rigid_pairs(solver):
    """The core collides the pairs a free dof can move apart, and finds there exactly
    ``mj_collision``'s penetrations in its order: with a hand shape fixed, nothing between
    bodies that no free dof moves, every other penetration row for row."""
    q = _penetrating_posture(solver)
    m = solver.model
    plan = solver.plan(ik.IKProblem((), DEFAULT_MAP.tracks["arm_R"]))
    rigid = _rigid(m, plan.free)
    pairs = solver.collision_pairs(plan.free)
    assert not any(rigid(*m.geom_bodyid[p]) for p in pairs)
    assert any(rigid(*m.geom_bodyid[g]) for g in _contacts(solver, q, near=True)[1])
    dist, geoms = _contacts(solver, q)
    moved = [k for k in range(dist.size) if not rigid(*m.geom_bodyid[geoms[k]])]
    listed = {tuple(p) for p in pairs.tolist()}
    assert all(tuple(geoms[k]) in listed for k in moved)
    r = np.frombuffer(plan.core.evaluate(q, True)[0])
    deep = [k for k in moved if dist[k] < 0]
    assert len(deep) >= 2
    np.testing.assert_array_equal(r, dist[deep] / cn.COLLISION_TOL)


def test_compiled_natural_rows_equal_the_objective(solver):
    """The core's naturalness rows are :func:`azee_mj.natural.rows` over the free dofs."""
    q = _random_arm_posture(solver, np.random.default_rng(11))
    plan = solver.plan(ik.IKProblem((cn.Place("I_TIP_R", kin.Const((0.3, -0.1, 0.3))),)))
    d = _fk(solver, q)
    r, J = plan.core.natural()
    r = np.frombuffer(r)
    rp, Jp = natural.rows(solver.naturalness, plan.effort, d, plan.free)
    np.testing.assert_allclose(r, rp, atol=1e-12)
    np.testing.assert_allclose(np.frombuffer(J).reshape(r.size, -1), Jp, atol=1e-12)


@pytest.mark.parametrize(
    "c",
    [
        cn.Orient(
            "palm_R", (0.0, 1.0, 0.0), cn.Rel.ALONG, kin.Const((0.0, 0.0, -1.0)), 0.26, "", False
        ),
        cn.Orient(
            "palm_R", (0.0, 1.0, 0.0), cn.Rel.OPP, kin.Const((1.0, 0.0, 0.0)), 0.5, "", False
        ),
        cn.Orient(
            "f_arm_R", (0.0, 0.0, 1.0), cn.Rel.PERP, kin.Const((0.0, 0.0, 1.0)), 0.2, "", False
        ),
        cn.Place("I_TIP_R", kin.Const((0.3, -0.1, 1.3)), 0.01),
    ],
    ids=["along", "opp", "perp", "place"],
)
def test_a_hard_constraints_norm_in_the_core_is_its_residual_over_its_tolerance(solver, c):
    """The core's norm of a hard constraint (what "met" and "done" compare to 1 and to the
    stop fraction) is the residual the report measures over the tolerance: the angle, not
    the chord or the sine an orientation's rows measure. It was the chord: a 15-degree
    orientation counted as met at 15.03 degrees, which the report then called a miss."""
    rng = np.random.default_rng(12)
    plan = solver.plan(ik.IKProblem((c,)))
    for _ in range(8):
        q = _random_arm_posture(solver, rng)
        norms = np.frombuffer(plan.core.evaluate(q, False)[2])
        residual = c.residual(solver.at(q))
        assert norms[0] == pytest.approx(residual / c.tol, rel=1e-9, abs=1e-12)


@pytest.mark.parametrize("rel", [cn.Rel.ALONG, cn.Rel.PERP])
def test_a_ranged_orientations_norm_is_zero_within_its_free_range_and_one_at_its_tol(solver, rel):
    """A ranged orientation's norm in the core, in a problem solved with ranges: 0 while
    its residual is within ``RANGE_FREE`` of its tolerance, then linear in the residual up
    to 1 at the tolerance; its rows shrink by the same factor. Without ranges, or not
    ranged, its rows and norm are as they are."""
    rng = np.random.default_rng(3)
    exact = cn.Orient("palm_R", PALM_R.nrm, rel, kin.Const((0.0, 0.0, -1.0)), 0.6, "", False)
    ranged = dataclasses.replace(exact, ranged=True)
    cores = [solver.plan(ik.IKProblem((c,), ranges=True)).core for c in (exact, ranged)]
    plain = solver.plan(ik.IKProblem((ranged,))).core
    seen = set()
    for _ in range(24):
        q = _random_arm_posture(solver, rng)
        (r0, _, n0), (r1, _, n1) = (core.evaluate(q, False)[:3] for core in cores)
        r2, _, n2 = plain.evaluate(q, False)[:3]
        x = ranged.residual(solver.at(q)) / ranged.tol
        n0, n1 = np.frombuffer(n0)[0], np.frombuffer(n1)[0]
        assert n0 == pytest.approx(x, rel=1e-9)
        assert np.frombuffer(n2)[0] == pytest.approx(x, rel=1e-9)
        np.testing.assert_array_equal(np.frombuffer(r2), np.frombuffer(r0))
        want = max(0.0, (x - RANGE_FREE) / (1.0 - RANGE_FREE))
        assert n1 == pytest.approx(want, rel=1e-9, abs=1e-12)
        f = max(0.0, (x - RANGE_FREE) / x)
        np.testing.assert_allclose(np.frombuffer(r1), f * np.frombuffer(r0), atol=1e-12)
        seen.add(x > RANGE_FREE)
    assert seen == {True, False}  # both sides of the free range were drawn


def test_a_reach_turns_a_ranged_orientation_only_into_its_range(solver):
    """From a palm 20 degrees off an axis it may be 30 degrees off, a solve with ranges
    leaves it there (the reach need not move it); without ranges, or asked exactly (not
    ranged), the same solve turns it to the axis."""
    place = cn.Place("I_TIP_R", kin.Const((0.3, -0.15, 0.45)))
    down = cn.Orient("palm_R", PALM_R.nrm, cn.Rel.ALONG, kin.Const((0.0, 0.0, -1.0)))
    met = solver.solve(ik.IKProblem((place, dataclasses.replace(down, tol=0.01))), solver.natural)
    assert met.converged
    tilted = dataclasses.replace(down, vector=kin.Const((0.0, np.sin(0.35), -np.cos(0.35))))
    angles = {}
    for ranged, ranges in ((True, True), (False, True), (True, False)):
        c = dataclasses.replace(tilted, tol=np.radians(30.0), ranged=ranged)
        res = solver.solve(ik.IKProblem((place, c), natural=False, ranges=ranges), met.qpos)
        assert res.converged
        angles[ranged, ranges] = np.degrees(c.residual(solver.at(res.qpos)))
    assert angles[True, True] == pytest.approx(np.degrees(0.35), abs=0.5)  # as it started
    assert angles[False, True] < 1.5  # the stop fraction of 30 degrees
    assert angles[True, False] < 1.5


def test_a_looks_norm_in_the_core_is_at_least_its_worse_eyes_angle(solver):
    c = cn.Look((("eye_L", (1.0, 0, 0)), ("eye_R", (1.0, 0, 0))), kin.Const((0.4, 0.1, 0.3)), 0.1)
    plan = solver.plan(ik.IKProblem((c,)))
    for q in (solver.natural, _random_arm_posture(solver, np.random.default_rng(1))):
        norm = np.frombuffer(plan.core.evaluate(q, False)[2])[0]
        worst = c.residual(solver.at(q)) / c.tol
        assert worst <= norm <= np.sqrt(2.0) * worst + 1e-12
        assert worst > 0.5  # far from the target: the angles matter, not their chords


def test_natural_cost_is_what_the_polish_minimises(solver):
    """:func:`azee_mj.ik.natural_cost` of a polished posture is the cost the core's polish
    reports for it, preferences included; a raised arm costs more than a hanging one."""
    elbow = natural.Below("f_arm_R", "arm_R", 0.02, 0.02, "elbow low")
    problem = ik.IKProblem(
        (cn.Place("I_TIP_R", kin.Const((0.3, -0.15, 0.45))),), preferences=(elbow,)
    )
    met = solver.solve(problem, solver.natural)
    assert met.converged
    q, nat, _, _ = solver.plan(problem).polish(met.qpos, [])
    assert ik.natural_cost(solver, problem, q) == pytest.approx(nat, rel=1e-9)
    raised = solver.natural.copy()
    raised[solver.model.jnt_qposadr[solver.joint_id("arm_R_abd")]] = np.radians(120.0)
    free = ik.IKProblem(problem.constraints)
    assert ik.natural_cost(solver, free, raised) > ik.natural_cost(solver, free, solver.natural)
    assert ik.natural_cost(solver, problem, raised) > ik.natural_cost(solver, free, raised)
