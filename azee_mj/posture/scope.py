"""Which bodies and dofs a posture problem touches: the dofs the solver moves, the body pairs
allowed to touch.

Units: metres, radians.
"""

from __future__ import annotations

import mujoco
import numpy as np

from azee_mj.constraints import Constraint, JointTarget, Look, Orient, Place
from azee_mj.kinematics import BodyAxis, BodyOrigin, Cross, Lin, Names, SitePos, Unit
from azee_mj.posture.problem import IKProblem


class Scope:
    """Names and joints of one model, and what a problem's constraints touch in it."""

    def __init__(self, model: mujoco.MjModel, names: Names):
        self.model = model
        self.names = names
        self._joint_info: dict[str, tuple[int, int, bool]] = {}

    def joint_info(self, name: str) -> tuple[int, int, bool]:
        """(qpos address, dof address, is a slide joint) of joint ``name`` (looked up once)."""
        info = self._joint_info.get(name)
        if info is None:
            j = self.names.joint(name)
            m = self.model
            info = (
                int(m.jnt_qposadr[j]),
                int(m.jnt_dofadr[j]),
                bool(m.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE),
            )
            self._joint_info[name] = info
        return info

    def bodies_of(self, c: Constraint) -> set[int]:
        """The bodies whose motion changes constraint ``c``'s rows."""
        out: set[int] = set()

        def walk(e):
            if isinstance(e, SitePos):
                out.add(int(self.model.site_bodyid[self.names.site(e.site)]))
            elif isinstance(e, (BodyAxis, BodyOrigin)):
                out.add(self.names.body(e.body))
            elif isinstance(e, Lin):
                for _, t in e.terms:
                    walk(t)
            elif isinstance(e, Cross):
                walk(e.a)
                walk(e.b)
            elif isinstance(e, Unit):
                walk(e.a)

        if isinstance(c, Place):
            walk(SitePos(c.site))
            walk(c.target)
            if c.shift is not None:
                walk(c.shift)
        elif isinstance(c, Orient):
            walk(BodyAxis(c.body, c.local))
            walk(c.vector)
        elif isinstance(c, Look):
            for body, _ in c.eyes:
                out.add(self.names.body(body))
            walk(c.target)
        return out

    def free_dofs(self, problem: IKProblem) -> np.ndarray:
        """Dof indices the solver moves for ``problem`` (sorted)."""
        m = self.model
        if problem.free_joints is not None:
            dofs = {self.joint_info(j)[1] for j in problem.free_joints}
        else:
            dofs = set()
            for c in problem.constraints:
                if isinstance(c, JointTarget):
                    dofs.add(self.joint_info(c.joint)[1])
                for b in self.bodies_of(c):
                    while b > 0:
                        a, n = m.body_dofadr[b], m.body_dofnum[b]
                        dofs.update(range(a, a + n))
                        b = m.body_parentid[b]
        return np.array(sorted(dofs), dtype=int)

    def joined_bodies(self, problem: IKProblem) -> set[tuple[int, int]]:
        """Body pairs a site-to-site placement brings together (allowed to touch)."""
        body = self.names.body
        pairs = set()
        for a, b in problem.touching:
            pairs |= {(body(a), body(b)), (body(b), body(a))}
        for c in problem.constraints:
            if isinstance(c, Place):
                bodies = self.bodies_of(c)
                for a in bodies:
                    for b in bodies:
                        if a != b:
                            pairs.add((a, b))
        return pairs
