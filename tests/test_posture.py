"""The solver's parts in azee_mj.posture: the contract with the compiled core (record
layouts, tunables, stop reasons), the stop a solve reports, and the pure helpers."""

from __future__ import annotations

import numpy as np
import pytest

from azee_mj import constraints as cn
from azee_mj import ik, native
from azee_mj import kinematics as kin
from azee_mj.posture import contract, starts
from azee_mj.posture.collision import moving_pairs, pair_coordinates, still_pairs
from azee_mj.posture.contract import BLOCK, HARD_LINEAR
from azee_mj.posture.plan import (
    BlockCompiler,
    Plan,
    _joint_record,
    _record,
    axis_target,
    flat_point,
)
from azee_mj.posture.problem import Stop
from azee_mj.sites import DEFAULT_MAP


@pytest.mark.parametrize(
    "name, dtype",
    [("Block", contract.BLOCK), ("Term", contract.TERM), ("Tunables", contract.TUNABLES)],
)
def test_record_layouts_are_the_c_structs(name, dtype):
    """Every numpy record has the size and field offsets of its C struct."""
    assert native.core().layout()[name] == contract.layout(dtype)


def test_stop_reasons_are_the_cores_in_order():
    assert native.core().STOPS == tuple(s.name for s in Stop)
    assert all(s.message and s.message[0].islower() for s in Stop)


def test_tunables_record_holds_the_python_values():
    t = contract.tunables()[0]
    assert (t["mu0"], t["max_step"], t["met_gain"]) == (ik.MU0, ik.MAX_STEP, ik.MET_GAIN)
    assert (t["far_cost"], t["far_gain"], t["collision_tol"]) == (
        ik.FAR_COST,
        ik.FAR_GAIN,
        cn.COLLISION_TOL,
    )
    assert (t["null_tol"], t["natural_step"], t["natural_iter"]) == (
        ik.NULL_TOL,
        ik.NATURAL_STEP,
        ik.NATURAL_ITER,
    )


def test_a_met_solve_says_why_it_stopped(solver):
    d = solver.at(solver.natural).d
    target = d.site_xpos[solver.site_id("PA_R")] + np.array([0.05, 0.0, 0.05])
    res = solver.solve(ik.IKProblem((cn.Place("PA_R", kin.Const(tuple(target))),)))
    assert res.converged
    assert res.stop in (Stop.DONE, Stop.MET_SLOW)
    assert res.polish in (Stop.NO_FREEDOM, Stop.POLISHED, Stop.MAX_ITER)
    assert res.stop_message == f"{res.stop.message}; polish: {res.polish.message}"


def test_an_unreachable_target_is_not_done(solver):
    res = solver.solve(ik.IKProblem((cn.Place("PA_R", kin.Const((3.0, 0.0, 0.0))),)))
    assert not res.converged
    assert res.stop not in (Stop.DONE, Stop.MET_SLOW) and res.polish is None


def _raw_core(solver, nrows: int, hard: np.ndarray, pairs: np.ndarray):
    """The compiled core built directly on ``solver``'s model and data, no blocks or terms,
    ``nrows`` rows over the right arm's dofs, hard records ``hard`` and geom ``pairs``:
    what the plan would pass, to check what the core refuses."""
    plan = solver.plan(ik.IKProblem((), DEFAULT_MAP.tracks["arm_R"]))
    return native.core().Core(
        solver.model._address,
        solver.data._address,
        None,
        np.zeros(0, contract.BLOCK),
        np.zeros(0, contract.TERM),
        contract.tunables(),
        np.zeros(nrows),
        plan.free.astype(np.int32),
        np.zeros((solver.model.nbody, solver.model.nbody)),
        np.zeros(nrows),
        np.zeros(nrows * solver.model.nv),
        None,
        hard,
        pairs,
        solver.clusters,
    )


def test_a_bad_geom_pair_is_refused_with_its_message(solver):
    bad = np.array([[0, solver.model.ngeom]], np.int32)
    with pytest.raises(ValueError) as e:
        _raw_core(solver, 0, np.zeros(0), bad)
    assert str(e.value) == f"pairs: (0, {solver.model.ngeom}) is no geom pair in type order"


def test_flat_point_collects_constants_and_terms():
    e = kin.Lin(((2.0, kin.SitePos("a")), (1.0, kin.Const((1.0, 2.0, 3.0)))))
    const, terms = flat_point(e)
    np.testing.assert_array_equal(const, [1.0, 2.0, 3.0])
    assert terms == [(2.0, contract.SITE, "a")]
    assert flat_point(kin.Unit(kin.SitePos("a"))) is None


def test_axis_target_of_a_negated_body_axis_keeps_its_sign():
    kind, body, local, sign = axis_target(kin.Lin(((-2.0, kin.BodyAxis("b", (0, 0, 2.0))),)))
    assert (kind, body, sign) == ("axis", "b", -1.0)
    np.testing.assert_array_equal(local, [0.0, 0.0, 1.0])
    kind, v = axis_target(kin.Const((0.0, 3.0, 4.0)))
    np.testing.assert_allclose(v, [0.0, 0.6, 0.8])


def test_restart_points_put_a_generic_start_after_every_four_seeds():
    q0 = np.zeros(2)
    seeds = [np.full(2, float(k)) for k in range(1, 6)]
    generic = iter([np.full(2, -1.0), np.full(2, -2.0)])
    out = list(starts.restart_points(q0, 3, lambda: seeds, generic))
    assert [float(q[0]) for q, _ in out] == [0.0, 1.0, 2.0, 3.0, 4.0, -1.0, 5.0, -2.0]
    assert [s for _, s in out] == [False, True, True, True, True, False, True, False]


def test_generic_starts_stay_in_range_and_keep_the_untouched_dofs():
    lo, hi = np.array([-1.0, -1.0, -1.0]), np.array([1.0, 1.0, 1.0])
    q_start = np.array([0.5, 0.5, 0.5])
    gen = starts.generic_starts(np.zeros(3), lo, hi, 0, q_start, np.array([0, 1]))
    for q in (next(gen) for _ in range(4)):
        assert np.all(q >= lo) and np.all(q <= hi) and q[2] == 0.5


def test_wide_starts_cover_the_whole_ranges_of_the_drawn_dofs_only():
    lo, hi = np.array([-4.0, -1.0, 0.0]), np.array([4.0, 1.0, 2.0])
    q_start = np.array([0.5, 0.5, 0.5])
    gen = starts.wide_starts(lo, hi, 0, q_start, np.array([0, 1]))
    qs = np.array([next(gen) for _ in range(200)])
    assert np.all(qs[:, 2] == 0.5)
    assert np.all(np.abs(qs[:, 0]) <= np.pi) and np.all(np.abs(qs[:, 1]) <= 1.0)
    # uniform over the range, not drawn toward the start: both ends are reached
    assert qs[:, 0].min() < -2.5 and qs[:, 0].max() > 2.5
    again = starts.wide_starts(lo, hi, 0, q_start, np.array([0, 1]))
    np.testing.assert_array_equal(next(again), qs[0])  # seeded per draw


def test_wide_search_keeps_only_natural_meets_and_stops_a_few_after_the_first():
    from azee_mj.posture.problem import Attempt

    tried = []

    def attempt(q):
        tried.append(float(q[0]))
        meets = q[0] >= 3.0
        return Attempt(q, (0, 10.0 - q[0]) if meets else (1, 5.0), 1, None)

    miss = Attempt(np.zeros(1), (1, 9.0), 0, None)
    points = iter([np.array([float(k)]) for k in range(40)])
    best, iters = starts.wide_search(attempt, miss, points, natural=lambda q: q[0] != 4.0)
    # 3 is the first meet; WIDE_AFTER_MEET more; 4 meets but is rejected
    assert tried == [float(k) for k in range(4 + starts.WIDE_AFTER_MEET)]
    assert float(best.q[0]) == 3.0 + starts.WIDE_AFTER_MEET and iters == len(tried)
    none = starts.wide_search(attempt, miss, iter([np.zeros(1)] * 40), natural=bool)
    assert none[0] is miss and none[1] == starts.WIDE_STARTS


def test_moving_pairs_drop_the_pairs_no_free_dof_moves(solver):
    m = solver.model
    free = solver.free_dofs(ik.IKProblem((), DEFAULT_MAP.tracks["arm_R"]))
    kept = moving_pairs(m, solver.all_pairs, free)
    assert 0 < len(kept) < len(solver.all_pairs)
    moved = set(m.dof_bodyid[free].tolist())
    for g1, g2 in kept:
        chains = []
        for b in (m.geom_bodyid[g1], m.geom_bodyid[g2]):
            chain = set()
            while b > 0:
                chain.add(int(b))
                b = m.body_parentid[b]
            chains.append(chain)
        assert (chains[0] ^ chains[1]) & moved


@pytest.mark.parametrize(
    "c",
    [
        cn.Place("I_TIP_R", kin.Const((0.3, -0.1, 0.3))),
        cn.Orient("palm_R", (1.0, 0.0, 0.0), cn.Rel.ALONG, kin.Const((0.0, 0.0, 1.0))),
        cn.Orient("palm_R", (1.0, 0.0, 0.0), cn.Rel.PERP, kin.Const((0.0, 1.0, 0.0))),
        cn.Look((("eye_L", (1.0, 0, 0)), ("eye_R", (1.0, 0, 0))), kin.Const((0.4, 0.1, 0.3))),
        cn.JointTarget("arm_R_flex", 0.4),
    ],
    ids=lambda c: f"{type(c).__name__}-{getattr(c, 'rel', '')}",
)
def test_report_from_the_cores_rows_is_the_constraints_residual(solver, c):
    """The report reads the core's rows; it gives the error the expression evaluator does."""
    q = solver.natural.copy()
    q[solver.free_dofs(ik.IKProblem((), DEFAULT_MAP.tracks["arm_R"]))] += 0.3
    plan = solver.plan(ik.IKProblem((c,)))
    (res,), _ = plan.report(q)
    assert res.value == pytest.approx(c.residual(solver.at(q, jacobians=True)), abs=1e-9)


def test_a_joint_targets_record_is_the_compilers(solver):
    """A joint target laid out directly (``_joint_record``) is the record the general
    compiler gives for it, field by field, and a plan of joint targets holds those records
    with each row's tolerance, hardness and unit (a slide joint in metres)."""
    names = [solver.model.joint(j).name for j in range(solver.model.njnt)]
    slide = next(n for n in names if solver.joint_info(n)[2])
    turning = next(n for n in names if not solver.joint_info(n)[2])
    cons = (
        cn.JointTarget(turning, 0.3, 0.02, "a"),
        cn.JointTarget(slide, -0.01, 0.001, "b", soft=True),
    )
    for row, c in enumerate(cons):
        qadr, dof, _ = solver.joint_info(c.joint)
        (block,) = BlockCompiler(solver).blocks(c)
        want = np.array([_record(BLOCK, {**block, "start": row, "hard": int(not c.soft)})], BLOCK)
        got = np.array([_joint_record(row, int(not c.soft), qadr, dof, c.value)], BLOCK)
        assert want.tobytes() == got.tobytes()
    plan = Plan(solver, ik.IKProblem(cons, ()))
    np.testing.assert_array_equal(plan.inv, [1 / 0.02, 1 / 0.001])
    assert plan.hard == [(0, 1, HARD_LINEAR, 0.02)]
    assert [(b.start, b.stop, b.scaled) for b in plan.items] == [(0, 1, False), (1, 2, False)]
    residuals, _ = plan.report(solver.natural)
    assert [(r.kind, r.unit) for r in residuals] == [("jointtarget", "rad"), ("jointtarget", "m")]


def test_still_pairs_keep_their_geoms_to_the_bit_and_the_others_move(solver):
    """Over postures that move the right arm only, the pairs called still have both geoms
    at the same place to the bit; every other pair has a geom on the right arm's chain
    (checked against the kinematics)."""
    m = solver.model
    d = solver.data
    pairs = solver.all_pairs
    coords = pair_coordinates(m, pairs)
    free = solver.free_dofs(ik.IKProblem((), DEFAULT_MAP.tracks["arm_R"]))
    rng = np.random.default_rng(3)
    postures = np.repeat(solver.natural[None], 4, axis=0)
    qadr = [m.jnt_qposadr[m.dof_jntid[f]] for f in free]  # hinge joints: one coordinate
    postures[1:, qadr] = rng.uniform(solver.lower[qadr], solver.upper[qadr], (3, len(qadr)))
    still = still_pairs(coords, postures)
    assert 0 < still.sum() < len(pairs)
    xpos = []
    for q in postures:
        solver.at(q)
        xpos.append(d.geom_xpos.copy())
    xpos = np.array(xpos)
    same = (xpos == xpos[:1]).all(axis=(0, 2))  # (ngeom,) unmoved to the bit
    assert same[pairs[still]].all()
    assert not same[pairs[~still]].all(axis=1).any()
    assert still_pairs(coords, postures[:1]).all()  # one posture: nothing moves


def test_a_bad_hard_record_is_refused_with_its_message(solver):
    for hard, message in [
        (np.zeros(3), "hard: records of 4 f64"),
        (np.array([0.0, 2.0, 0.0, 0.01]), "hard: record 0 is no (first, end, kind, tol)"),
        (np.array([0.0, 1.0, 3.0, 0.01]), "hard: record 0 is no (first, end, kind, tol)"),
        # a range is an orientation's
        (np.array([0.0, 1.0, 4.0, 0.01]), "hard: record 0 is no (first, end, kind, tol)"),
    ]:
        with pytest.raises(ValueError) as e:
            _raw_core(solver, 1, hard, np.zeros((0, 2), np.int32))
        assert str(e.value) == message
