"""The realizer's adapter to the solver: penetration depths as MuJoCo measures them."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from scores import envelope, sync

from azee_mj import constraints as cn
from azee_mj.ikadapter import IKAdapter
from azee_mj.schedule import Schedule
from azee_mj.score import load_score


def test_depth_is_mujocos_deepest_contact_asked_once_or_again(solver):
    """Each posture's depth is that of ``mj_collision`` on a fresh copy of the data (with
    and without the deepest contact's body pair allowed), the same when asked again (kept),
    and the solver's data holds the posture's kinematics either way."""
    adapter = IKAdapter(Schedule(load_score(envelope(sync("S", 0.4))), solver))
    m = solver.model
    rng = np.random.default_rng(3)
    joints = adapter.schedule.track_joints
    arms = adapter.dofs(sorted(joints["arm_R"] + joints["arm_L"]))
    deep = 0
    for _ in range(24):
        q = solver.natural.copy()
        q[arms] = rng.uniform(solver.lower[arms], solver.upper[arms])
        d = mujoco.MjData(m)
        d.qpos[:] = q
        want = cn.penetration_depth(m, d)
        allowed = frozenset()
        if want > 0.0:
            deep += 1
            i = int(np.argmin(d.contact.dist[: d.ncon]))
            a, b = m.geom_bodyid[d.contact.geom[i]].tolist()
            allowed = frozenset({(a, b), (b, a)})
        for ask in (frozenset(), allowed, frozenset(), allowed):
            got = adapter.depth(q, ask)
            d2 = mujoco.MjData(m)
            d2.qpos[:] = q
            assert got == cn.penetration_depth(m, d2, ask)
            np.testing.assert_array_equal(solver.data.site_xpos, d2.site_xpos)
    assert deep >= 3  # postures that go into the body were asked


def test_a_known_depth_not_posed_is_the_same_and_leaves_the_data_as_it_was(solver):
    """``posed=False``: a depth asked again is the kept one, with no kinematics run (the
    data still holds the posture asked last); a depth not yet known poses its posture."""
    adapter = IKAdapter(Schedule(load_score(envelope(sync("S", 0.4))), solver))
    joints = adapter.schedule.track_joints
    arms = adapter.dofs(sorted(joints["arm_R"]))
    rng = np.random.default_rng(5)
    q1, q2 = solver.natural.copy(), solver.natural.copy()
    q1[arms] = rng.uniform(solver.lower[arms], solver.upper[arms])
    q2[arms] = rng.uniform(solver.lower[arms], solver.upper[arms])
    first = adapter.depth(q1)
    adapter.depth(q2)
    at_q2 = solver.data.site_xpos.copy()
    assert adapter.depth(q1, posed=False) == first
    np.testing.assert_array_equal(solver.data.site_xpos, at_q2)
    q3 = q1.copy()
    q3[arms] = rng.uniform(solver.lower[arms], solver.upper[arms])
    d = mujoco.MjData(solver.model)
    d.qpos[:] = q3
    assert adapter.depth(q3, posed=False) == cn.penetration_depth(solver.model, d)
    np.testing.assert_array_equal(solver.data.site_xpos, d.site_xpos)


def deepest_contact(m, d, allowed) -> float:
    """The reference reading of MuJoCo's contacts (after ``mj_collision``): the deepest with
    ``dist < 0`` but between the body pairs ``allowed``."""
    dist = d.contact.dist[: d.ncon]
    bodies = m.geom_bodyid[d.contact.geom[: d.ncon]].tolist()
    deep = [-x for x, b in zip(dist.tolist(), bodies) if x < 0.0 and tuple(b) not in allowed]
    return max(deep, default=0.0)


def collided_at_random(solver, rng) -> mujoco.MjData:
    """New data of ``solver``'s model at a posture drawn uniformly within the joint ranges,
    its kinematics and ``mj_collision``'s contacts run."""
    d = mujoco.MjData(solver.model)
    d.qpos[:] = rng.uniform(solver.lower, solver.upper)
    mujoco.mj_kinematics(solver.model, d)
    mujoco.mj_collision(solver.model, d)
    return d


def test_contact_depth_in_the_core_is_the_deepest_contact_mujoco_finds(solver):
    """The compiled core's reading of ``mj_collision``'s contacts gives, to the bit, the
    deepest penetration outside the allowed body pairs, on postures that go into the body
    (none allowed, the deepest contact's pair allowed in one order or both, an unrelated
    pair allowed)."""
    m = solver.model
    rng = np.random.default_rng(7)
    deep = 0
    for _ in range(40):
        d = collided_at_random(solver, rng)
        i = int(np.argmin(d.contact.dist[: d.ncon])) if d.ncon else 0
        a, b = m.geom_bodyid[d.contact.geom[i]].tolist() if d.ncon else (1, 2)
        for allowed in (
            frozenset(),
            frozenset({(a, b)}),
            frozenset({(a, b), (b, a)}),
            frozenset({(0, 1), (1, 0)}),
        ):
            want = deepest_contact(m, d, allowed)
            deep += want > 0.0
            assert cn.contact_depth(m, d, allowed) == want
    assert deep >= 40  # most postures went into the body


def test_pairs_depth_is_the_depth_of_mujocos_contacts_pair_by_pair(solver):
    """The narrowphase on one geom pair alone (no ``mj_collision``) gives that pair's deepest
    contact of ``mj_collision``: to the bit for the analytic pairs; with an ellipsoid (the
    convex solver's iterations) within 1 um under 5 mm of depth and 1 % deeper down."""
    m = solver.model
    ellipsoid = int(mujoco.mjtGeom.mjGEOM_ELLIPSOID)
    rng = np.random.default_rng(11)
    deep = 0
    for _ in range(30):
        d = collided_at_random(solver, rng)
        want: dict[tuple, float] = {}
        for g, dist in zip(d.contact.geom[: d.ncon].tolist(), d.contact.dist[: d.ncon]):
            key = tuple(sorted(g))
            want[key] = max(want.get(key, 0.0), -float(dist))
        for pair in solver.all_pairs:
            got = cn.pairs_depth(m, d, np.ascontiguousarray(pair[None]))
            ref = want.get(tuple(sorted(pair.tolist())), 0.0)
            deep += ref > 0.0
            if ellipsoid in m.geom_type[pair]:
                assert abs(got - ref) <= (1e-6 if max(got, ref) < 0.005 else 0.01 * ref)
            else:
                assert got == ref
    assert deep >= 100  # many pairs went into each other


def test_pairs_depth_skips_the_allowed_body_pairs_and_splits(solver):
    """Over every pair, the deepest outside the allowed body pairs (either order listed) is
    the deepest of the pair-by-pair depths outside them, and the deeper of any split."""
    m = solver.model
    pairs = solver.all_pairs
    rng = np.random.default_rng(2)
    for _ in range(10):
        d = mujoco.MjData(m)
        d.qpos[:] = rng.uniform(solver.lower, solver.upper)
        mujoco.mj_kinematics(m, d)
        each = np.array([cn.pairs_depth(m, d, np.ascontiguousarray(p[None])) for p in pairs])
        a, b = m.geom_bodyid[pairs[int(np.argmax(each))]].tolist()
        half = rng.random(len(pairs)) < 0.5
        one, other = np.ascontiguousarray(pairs[half]), np.ascontiguousarray(pairs[~half])
        for allowed in (frozenset(), frozenset({(a, b), (b, a)})):
            bodies = [tuple(x) for x in m.geom_bodyid[pairs].tolist()]
            want = max(x for x, bb in zip(each, bodies) if bb not in allowed)
            assert cn.pairs_depth(m, d, pairs, allowed) == want
            split = max(cn.pairs_depth(m, d, one, allowed), cn.pairs_depth(m, d, other, allowed))
            assert split == want


def test_pairs_depth_refuses_geoms_the_model_does_not_have(solver):
    m = solver.model
    d = mujoco.MjData(m)
    bad = np.array([[0, m.ngeom]], np.int32)
    with pytest.raises(ValueError, match="^pairs: geom ids out of range$"):
        cn.pairs_depth(m, d, bad)


def test_a_run_of_pairs_depths_is_each_postures_pairs_depth(solver):
    """The compiled run over many postures gives, to the bit, :func:`pairs_depth` on each
    posture's own kinematics, and leaves the data on the last posture."""
    m = solver.model
    rng = np.random.default_rng(5)
    qs = rng.uniform(solver.lower, solver.upper, size=(12, m.nq))
    pairs = np.ascontiguousarray(solver.all_pairs[::3])
    for allowed in (frozenset(), frozenset({(1, 2), (2, 1)})):
        d = mujoco.MjData(m)
        got = cn.run_pairs_depth(m, d, qs, pairs, allowed)
        np.testing.assert_array_equal(d.qpos, qs[-1])
        want = []
        for q in qs:
            d2 = mujoco.MjData(m)
            d2.qpos[:] = q
            mujoco.mj_kinematics(m, d2)
            want.append(cn.pairs_depth(m, d2, pairs, allowed))
        assert got.tolist() == want
        assert (got > 0.0).sum() >= 3  # several postures went into the body


def test_a_run_of_pairs_depths_refuses_postures_of_another_size(solver):
    m = solver.model
    d = mujoco.MjData(m)
    with pytest.raises(ValueError, match=rf"^postures: expected \(n, {m.nq}\), got \(2, 3\)$"):
        cn.run_pairs_depth(m, d, np.zeros((2, 3)), np.ascontiguousarray(solver.all_pairs))


def test_the_adapters_depths_of_a_run_are_its_depths_one_by_one(solver):
    """:meth:`IKAdapter.depths` (split, in one call) gives each posture's depth of the
    moved pairs on its own kinematics, or the known rest if deeper, known or not (half of
    them asked before)."""
    adapter = IKAdapter(Schedule(load_score(envelope(sync("S", 0.4))), solver))
    m = solver.model
    rng = np.random.default_rng(8)
    joints = adapter.schedule.track_joints
    arms = adapter.dofs(sorted(joints["arm_R"] + joints["arm_L"]))
    qs = np.tile(solver.natural, (10, 1))
    qs[:, arms] = rng.uniform(solver.lower[arms], solver.upper[arms], size=(10, len(arms)))
    pairs = solver.all_pairs
    moved, rest = np.ascontiguousarray(pairs[::2]), 0.001
    want = []
    for q in qs:
        d = mujoco.MjData(m)
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        want.append(max(cn.pairs_depth(m, d, moved, frozenset()), rest))
    half = adapter.depths(qs[::2], frozenset(), (moved, rest))  # known before, half of them
    assert half.tolist() == want[::2]
    got = adapter.depths(qs, frozenset(), (moved, rest))
    assert got.tolist() == want
    assert max(want) > rest  # some posture deeper than the pairs it leaves out
    assert adapter.depths(qs, frozenset(), (moved, rest)).tolist() == want  # kept
    assert m.nq == qs.shape[1]
