"""Baseline posture solvers for ``bench/ik.py``: mink (differential IK) and MuJoCo
simulation stepping with mocap ``connect`` constraints.

Both take the same :class:`azee_mj.ik.IKProblem` s as our solver, move only the problem's
free joints, and return ``(qpos, iterations or steps, wall time [s])``; ``bench/ik.py`` scores
every method's posture with the same evaluator (our solver's residual report).

mink (differential IK QP, https://github.com/kevinzakka/mink):
  - a placement at a fixed point is a ``FrameTask`` on the site with position cost only;
  - a site-to-site contact is a ``RelativeFrameTask`` (site in the other site's frame,
    identity target) with position cost only;
  - "axis along / opposite" is mink's ``AxisAlignTask`` (rank 2, axis only, no roll);
  - "axis perpendicular" has no mink task: :class:`PerpTask` is a one-row custom
    ``mink.Task`` (error ``a . v``, Jacobian ``v . (-[a]x J_rot)``);
  - joint limits: ``ConfigurationLimit``; self-collision: ``CollisionAvoidanceLimit`` over
    every pair of the signer's colliding geoms except the pairs a contact brings together;
  - step size: a ``VelocityLimit`` of ``MINK_MAX_STEP`` rad per iteration on every joint, as
    mink's collision-avoidance examples pair the collision limit with a velocity limit: the
    collision limit is a linearisation, and unbounded steps (up to 2 rad per iteration
    here) jump geoms through each other in one iteration;
  - joints other than the free ones: ``DofFreezingTask`` as an equality constraint.
  Costs are 1/tolerance per row (as in our solver), QP solver daqp, iterations until every
  constraint is within tolerance or 200 iterations, or until the QP is infeasible
  (``NoSolutionFound``, counted in ``qp_failures``).

Simulation stepping: a second :class:`~azee_mj.ik.Solver` (so a copy of the solver's model
with its pool of mocap targets) with gravity off; ``Solver.configure_equalities`` turns the
placements into ``connect`` equalities (fixed points on mocap targets, contacts site to site);
the model's joint damping and contacts stay on (contact margin 0); the non-free joints
are held at their start value every step. Orientation constraints cannot be expressed as
connect equalities (MuJoCo has no "axis along / perpendicular" equality) and are ignored by
this baseline. Stepping stops when every joint speed is under ``QVEL_STILL`` or after ``SIM_TIME`` simulated seconds.
"""

from __future__ import annotations

import time

import mujoco
import numpy as np

from azee_mj import constraints as cn
from azee_mj import ik
from azee_mj import kinematics as kin
from azee_mj.kinematics import skew
from azee_mj.schedule import make_solver

MINK_MAX_ITER = 200
#: The QP's step is dq = v * dt; dt only scales the limits' velocity bounds. The loop is
#: offline, so dt = 1 (v = dq per iteration): mink's collision bound is gain * (d - d_min) / dt
#: on dq, so with dt = 1 its ``gain`` is, as documented, the fraction of the gap the geoms may
#: close per iteration (dt = 0.01 allowed closing 85 times the gap, i.e. no avoidance).
MINK_DT = 1.0
#: Largest change of any joint per iteration [rad] (``VelocityLimit`` of MINK_MAX_STEP / dt).
MINK_MAX_STEP = 0.1
MINK_DAMPING = 1.0  # Levenberg-Marquardt damping on the QP Hessian (rows scaled 1/tol); chosen
# before the step limit (14 of 30 quick keyframes against 12 with 1e-3), not re-checked since
#: mink's collision limit: geoms closer than this are constrained not to approach [m]; at
#: least the hand's travel in one MINK_MAX_STEP iteration (0.1 rad on a ~0.5 m lever), or
#: geoms further apart than this close the gap and penetrate within one unconstrained step.
MINK_DETECTION = 0.05
#: mink's collision limit: minimum distance kept between geoms [m] (0: touching allowed).
MINK_MIN_DIST = 0.0

SIM_TIME = 2.0  # [s] simulated
QVEL_STILL = 1e-2  # [rad/s]
SIM_MIN_STEPS = 10


def _import_mink():
    import mink

    return mink


def _world_perp_row(model, data, bid, local, v, jr):
    mujoco.mj_jacBody(model, data, None, jr, bid)
    a = data.xmat[bid].reshape(3, 3) @ local
    da = -skew(a) @ jr  # da/dq = -[a]x J_rot
    return float(a @ v), v @ da


class MinkSolver:
    """Differential IK with mink on our solver's model (its own ``MjData``)."""

    def __init__(
        self,
        solver: ik.Solver,
        solver_name: str = "daqp",
        max_iter: int = MINK_MAX_ITER,
        damping: float = MINK_DAMPING,
    ):
        mink = _import_mink()
        self.mink = mink
        self.s = solver
        self.model = solver.model
        self.config = mink.Configuration(self.model)
        self.solver_name = solver_name
        self.max_iter = max_iter
        self.damping = damping
        m = self.model
        self.collision_geoms = [int(g) for g in np.flatnonzero(m.geom_contype | m.geom_conaffinity)]
        self.config_limit = mink.ConfigurationLimit(m)
        self.step_limit = mink.VelocityLimit(
            m, {m.joint(j).name: MINK_MAX_STEP / MINK_DT for j in range(m.njnt)}
        )
        self.all_pairs = mink.CollisionAvoidanceLimit(
            m,
            [(self.collision_geoms, self.collision_geoms)],
            minimum_distance_from_collisions=MINK_MIN_DIST,
            collision_detection_distance=MINK_DETECTION,
        ).geom_id_pairs
        self._limits: dict[frozenset, object] = {}
        self._jr = np.empty((3, m.nv))
        self.qp_failures = 0

        class PerpTask(mink.Task):
            """Body axis ``local`` perpendicular to the world vector ``v`` (one row)."""

            k = 1

            def __init__(task, body_id, local, v, cost):
                super().__init__(cost=np.array([cost]), gain=1.0)
                task.bid, task.local, task.v = body_id, np.asarray(local, float), np.asarray(v)
                task.jr = np.empty((3, m.nv))

            def compute_error(task, configuration):
                e, _ = _world_perp_row(
                    configuration.model, configuration.data, task.bid, task.local, task.v, task.jr
                )
                return np.array([e])

            def compute_jacobian(task, configuration):
                _, j = _world_perp_row(
                    configuration.model, configuration.data, task.bid, task.local, task.v, task.jr
                )
                return j[None, :]

        self.PerpTask = PerpTask

    def _collision_limit(self, joined: frozenset):
        """The collision limit without the geom pairs of bodies a contact brings together."""
        lim = self._limits.get(joined)
        if lim is None:
            mink, m = self.mink, self.model
            lim = mink.CollisionAvoidanceLimit(
                m,
                [([self.collision_geoms[0]], [self.collision_geoms[1]])],
                minimum_distance_from_collisions=MINK_MIN_DIST,
                collision_detection_distance=MINK_DETECTION,
            )
            b = m.geom_bodyid
            lim.geom_id_pairs = [
                (g1, g2) for g1, g2 in self.all_pairs if (int(b[g1]), int(b[g2])) not in joined
            ]
            lim.max_num_contacts = len(lim.geom_id_pairs)
            lim._init_broadphase(m)
            self._limits[joined] = lim
        return lim

    def tasks(self, problem: ik.IKProblem):
        mink, s = self.mink, self.s
        out = []
        for c in problem.constraints:
            if isinstance(c, cn.Place) and isinstance(c.target, kin.Const):
                t = mink.FrameTask(c.site, "site", position_cost=1.0 / c.tol, orientation_cost=0.0)
                t.set_target(mink.SE3.from_translation(np.asarray(c.target.value, float)))
                out.append(t)
            elif isinstance(c, cn.Place) and isinstance(c.target, kin.SitePos):
                t = mink.RelativeFrameTask(
                    c.site,
                    "site",
                    c.target.site,
                    "site",
                    position_cost=1.0 / c.tol,
                    orientation_cost=0.0,
                )
                t.set_target(mink.SE3.identity())
                out.append(t)
            elif isinstance(c, cn.Orient) and isinstance(c.vector, kin.Const):
                v = np.asarray(c.vector.value, float)
                v = v / np.linalg.norm(v)
                if c.rel is cn.Rel.PERP:
                    out.append(self.PerpTask(s.body_id(c.body), c.local, v, 1.0 / c.tol))
                else:
                    t = mink.AxisAlignTask(c.body, "body", axis=c.local, cost=1.0 / c.tol)
                    t.set_target(-v if c.rel is cn.Rel.OPP else v)
                    out.append(t)
            else:
                raise NotImplementedError(f"no mink form for {c!r}")
        return out

    def solve(self, problem: ik.IKProblem, q0: np.ndarray):
        t0 = time.perf_counter()
        mink, s, m = self.mink, self.s, self.model
        free = s.free_dofs(problem)
        frozen = np.setdiff1d(np.arange(m.nv), free)
        joined = frozenset(s.joined_bodies(problem))
        tasks = self.tasks(problem)
        limits = [self.config_limit, self.step_limit, self._collision_limit(joined)]
        constraints = [mink.DofFreezingTask(m, [int(i) for i in frozen])] if frozen.size else []
        plan = s.plan(problem)
        cfg = self.config
        cfg.update(np.clip(q0, s.lower, s.upper))
        it = 0
        for it in range(1, self.max_iter + 1):
            try:
                v = mink.solve_ik(
                    cfg,
                    tasks,
                    MINK_DT,
                    self.solver_name,
                    damping=self.damping,
                    limits=limits,
                    constraints=constraints,
                )
            except mink.NoSolutionFound:  # infeasible QP (e.g. limits violated): give up
                self.qp_failures += 1
                break
            cfg.integrate_inplace(v, MINK_DT)
            if _within(plan, cfg.data):
                break
        return cfg.data.qpos.copy(), it, time.perf_counter() - t0


def _within(plan, data) -> bool:
    """Every constraint within its tolerance on the posture in ``data`` (kinematics done)."""
    for c in plan.cons:
        if isinstance(c, cn.Place):
            p = data.site_xpos[plan.s.site_id(c.site)]
            t = (
                np.asarray(c.target.value)
                if isinstance(c.target, kin.Const)
                else data.site_xpos[plan.s.site_id(c.target.site)]
            )
            if np.linalg.norm(p - t) > c.tol:
                return False
        elif isinstance(c, cn.Orient):
            bid = plan.s.body_id(c.body)
            a = data.xmat[bid].reshape(3, 3) @ np.asarray(c.local, float)
            v = np.asarray(c.vector.value, float)
            v = v / np.linalg.norm(v) * (-1.0 if c.rel is cn.Rel.OPP else 1.0)
            dot = float(np.clip(a @ v, -1.0, 1.0))
            err = abs(np.arcsin(dot)) if c.rel is cn.Rel.PERP else np.arccos(dot)
            if err > c.tol:
                return False
    return True


class SimStepper:
    """Simulation stepping with mocap ``connect`` equalities until still."""

    def __init__(self, sim_time: float = SIM_TIME, still: float = QVEL_STILL):
        self.s = make_solver()  # own copy of the model: configure_equalities writes into it
        m = self.s.model
        m.opt.gravity[:] = 0.0
        m.geom_margin[:] = 0.0  # MuJoCo's default (the solver's own copy detects at 4 mm)
        self.model, self.data = m, mujoco.MjData(m)
        self.n_steps = round(sim_time / m.opt.timestep)
        self.still = still

    def solve(self, problem: ik.IKProblem, q0: np.ndarray):
        t0 = time.perf_counter()
        s, m, d = self.s, self.model, self.data
        free = s.free_dofs(problem)
        frozen = np.setdiff1d(np.arange(m.nv), free)
        mujoco.mj_resetData(m, d)
        q_start = np.clip(q0, s.lower, s.upper)
        d.qpos[:] = q_start
        d.qvel[:] = 0.0
        s.configure_equalities(problem, d)
        mujoco.mj_forward(m, d)
        steps = 0
        for steps in range(1, self.n_steps + 1):
            mujoco.mj_step(m, d)
            d.qpos[frozen] = q_start[frozen]
            d.qvel[frozen] = 0.0
            if steps >= SIM_MIN_STEPS and np.abs(d.qvel).max() < self.still:
                break
        return d.qpos.copy(), steps, time.perf_counter() - t0
