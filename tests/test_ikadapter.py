"""The realizer's adapter to the solver: penetration depths as MuJoCo measures them."""

from __future__ import annotations

import mujoco
import numpy as np
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


def test_contact_depth_in_the_core_is_the_deepest_contact_mujoco_finds(solver):
    """The compiled core's reading of ``mj_collision``'s contacts gives, to the bit, the
    deepest penetration outside the allowed body pairs, on postures that go into the body
    (none allowed, the deepest contact's pair allowed in one order or both, an unrelated
    pair allowed)."""
    m = solver.model
    rng = np.random.default_rng(7)
    deep = 0
    for _ in range(40):
        d = mujoco.MjData(m)
        d.qpos[:] = rng.uniform(solver.lower, solver.upper)
        mujoco.mj_kinematics(m, d)
        mujoco.mj_collision(m, d)
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
