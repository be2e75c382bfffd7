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
