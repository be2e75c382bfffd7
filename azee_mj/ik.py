"""Posture solving: AZee constraints on the MuJoCo signer, with joint limits and self-collision.

An :class:`IKProblem` is everything that must hold at one instant. :class:`Solver` turns it
into residual rows with exact Jacobians from MuJoCo's kinematics (``mj_jacSite``,
``mj_jacBody``, ``mj_jac`` at contact points from ``mj_collision``) and solves them with a
damped least-squares (Levenberg-Marquardt) iteration whose steps are box-constrained QPs
(``mujoco.mju_boxQP``), so joint limits hold exactly.

Placements with a fixed target and site-to-site contacts are also mirrored as MuJoCo
``connect`` equality constraints on a pool of mocap targets in the solver's model
(:meth:`Solver.configure_equalities`), so the viewer can draw them and a simulation can use
them; their rows are the same as MuJoCo's (the tests compare them with ``efc_J``/``efc_pos``).
MuJoCo has no equality for "axis along / opposite / perpendicular", so orientations and gaze
are rows of our own (for a world axis ``a = R u``: ``a - v`` along, ``a . v`` perpendicular,
``da/dq = -[a]x J_rot``).

Self-collision is a one-sided penalty row per contact reported by ``mj_collision`` between
non-excluded geoms: zero while the geoms are apart, ``depth`` when they penetrate.
Infeasible problems are not errors: the solver returns its best posture, ``converged=False``
and every constraint's residual.

Units: metres, radians, seconds.
"""

from __future__ import annotations

import dataclasses
import enum
import time

import mujoco
import numpy as np

# ---------------------------------------------------------------------------------------
# Kinematic expressions: points and vectors that may depend on the posture being solved.
# Each evaluates to a value (3,) and its Jacobian (3, nv), or None when constant.
# ---------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Const:
    """A fixed point or vector in the signer frame [m or unitless]."""

    value: tuple[float, float, float]


@dataclasses.dataclass(frozen=True)
class SitePos:
    """The world position of a model site on the current posture [m]."""

    site: str


@dataclasses.dataclass(frozen=True)
class BodyAxis:
    """A unit axis fixed in a body (``local`` in the body frame), in world coordinates."""

    body: str
    local: tuple[float, float, float]


@dataclasses.dataclass(frozen=True)
class Lin:
    """A linear combination ``sum(c * e)`` of expressions (translate, mid, from, scale, add)."""

    terms: tuple[tuple[float, Expr], ...]


@dataclasses.dataclass(frozen=True)
class Cross:
    """Cross product ``a x b``."""

    a: Expr
    b: Expr


@dataclasses.dataclass(frozen=True)
class Unit:
    """``a / |a|``."""

    a: Expr


Expr = Const | SitePos | BodyAxis | Lin | Cross | Unit


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


class _Kin:
    """Kinematic quantities of one posture, computed on demand and cached."""

    def __init__(self, solver: Solver):
        self.s = solver
        self.m, self.d = solver.model, solver.data
        self._site: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._bodyr: dict[int, np.ndarray] = {}

    def site(self, sid: int) -> tuple[np.ndarray, np.ndarray]:
        if sid not in self._site:
            jac = np.empty((3, self.m.nv))
            mujoco.mj_jacSite(self.m, self.d, jac, None, sid)
            self._site[sid] = (self.d.site_xpos[sid].copy(), jac)
        return self._site[sid]

    def body_rot_jac(self, bid: int) -> np.ndarray:
        if bid not in self._bodyr:
            jac = np.empty((3, self.m.nv))
            mujoco.mj_jacBody(self.m, self.d, None, jac, bid)
            self._bodyr[bid] = jac
        return self._bodyr[bid]

    def eval(self, e: Expr, jac: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
        if isinstance(e, Const):
            return np.asarray(e.value, float), None
        if isinstance(e, SitePos):
            sid = self.s.site_id(e.site)
            if not jac:
                return self.d.site_xpos[sid].copy(), None
            return self.site(sid)
        if isinstance(e, _BodyOrigin):
            bid = self.s.body_id(e.body)
            if not jac:
                return self.d.xpos[bid].copy(), None
            jp = np.empty((3, self.m.nv))
            mujoco.mj_jacBody(self.m, self.d, jp, None, bid)
            return self.d.xpos[bid].copy(), jp
        if isinstance(e, BodyAxis):
            bid = self.s.body_id(e.body)
            a = self.d.xmat[bid].reshape(3, 3) @ np.asarray(e.local, float)
            return a, (-_skew(a) @ self.body_rot_jac(bid) if jac else None)
        if isinstance(e, Lin):
            v, J = np.zeros(3), None
            for c, t in e.terms:
                tv, tj = self.eval(t, jac)
                v = v + c * tv
                if tj is not None:
                    J = c * tj if J is None else J + c * tj
            return v, J
        if isinstance(e, Cross):
            a, ja = self.eval(e.a, jac)
            b, jb = self.eval(e.b, jac)
            J = None
            if ja is not None:
                J = -_skew(b) @ ja
            if jb is not None:
                J = _skew(a) @ jb if J is None else J + _skew(a) @ jb
            return np.cross(a, b), J
        if isinstance(e, Unit):
            a, ja = self.eval(e.a, jac)
            n = np.linalg.norm(a)
            if n < 1e-12:
                return np.zeros(3), None if ja is None else np.zeros_like(ja)
            u = a / n
            return u, None if ja is None else (np.eye(3) - np.outer(u, u)) @ ja / n
        raise TypeError(f"not a kinematic expression: {e!r}")


# ---------------------------------------------------------------------------------------
# Constraints: each gives residual rows (k,) and Jacobian rows (k, nv), and a report value.
# Rows are divided by the constraint's tolerance, so |row| <= 1 means "within tolerance".
# ---------------------------------------------------------------------------------------


class Rel(enum.Enum):
    """How a bone axis relates to a vector."""

    ALONG = "along"
    OPP = "opp"
    PERP = "perp"


@dataclasses.dataclass(frozen=True)
class Place:
    """Model site ``site`` at the point ``target``; within ``tol`` [m]."""

    site: str
    target: Expr
    tol: float = 1e-3
    label: str = ""

    def rows(self, k: _Kin):
        p, jp = k.site(k.s.site_id(self.site))
        t, jt = k.eval(self.target)
        return (p - t) / self.tol, (jp if jt is None else jp - jt) / self.tol

    def residual(self, k: _Kin) -> float:
        p = k.d.site_xpos[k.s.site_id(self.site)]
        return float(np.linalg.norm(p - k.eval(self.target, jac=False)[0]))


@dataclasses.dataclass(frozen=True)
class Orient:
    """Body axis ``local`` (a bone's DIR or NRM) along / opposite / perpendicular to
    ``vector``; within ``tol`` [rad]."""

    body: str
    local: tuple[float, float, float]
    rel: Rel
    vector: Expr
    tol: float = np.deg2rad(1.0)
    label: str = ""

    def _av(self, k: _Kin, jac: bool):
        a, ja = k.eval(BodyAxis(self.body, self.local), jac)
        v, jv = k.eval(Unit(self.vector), jac)
        if self.rel is Rel.OPP:
            v, jv = -v, (None if jv is None else -jv)
        return a, ja, v, jv

    def rows(self, k: _Kin):
        a, ja, v, jv = self._av(k, True)
        if self.rel is Rel.PERP:
            r = np.array([a @ v])
            J = (v @ ja)[None, :]
            if jv is not None:
                J = J + (a @ jv)[None, :]
        else:
            r = a - v
            J = ja if jv is None else ja - jv
        return r / self.tol, J / self.tol

    def residual(self, k: _Kin) -> float:
        a, _, v, _ = self._av(k, False)
        c = float(np.clip(a @ v, -1.0, 1.0))
        return abs(np.arcsin(c)) if self.rel is Rel.PERP else float(np.arccos(c))


@dataclasses.dataclass(frozen=True)
class Look:
    """Each eye body's gaze axis ``local`` points at ``target``; within ``tol`` [rad]."""

    eyes: tuple[tuple[str, tuple[float, float, float]], ...]
    target: Expr
    tol: float = np.deg2rad(1.0)
    label: str = ""

    def _orients(self) -> list[Orient]:
        return [
            Orient(body, local, Rel.ALONG, Lin(((1.0, self.target), (-1.0, _BodyOrigin(body)))),
                   self.tol)
            for body, local in self.eyes
        ]  # fmt: skip

    def rows(self, k: _Kin):
        rows = [o.rows(k) for o in self._orients()]
        return np.concatenate([r for r, _ in rows]), np.vstack([j for _, j in rows])

    def residual(self, k: _Kin) -> float:
        return max(o.residual(k) for o in self._orients())


@dataclasses.dataclass(frozen=True)
class _BodyOrigin:
    body: str


@dataclasses.dataclass(frozen=True)
class JointTarget:
    """Joint ``joint`` at ``value`` [rad or m], e.g. from a morph; within ``tol``."""

    joint: str
    value: float
    tol: float = 0.02
    label: str = ""
    #: A soft target guides the posture but never blocks convergence (e.g. an interpolation).
    soft: bool = False

    def rows(self, k: _Kin):
        j = k.s.joint_id(self.joint)
        J = np.zeros((1, k.m.nv))
        J[0, k.m.jnt_dofadr[j]] = 1.0 / self.tol
        return np.array([(k.d.qpos[k.m.jnt_qposadr[j]] - self.value) / self.tol]), J

    def residual(self, k: _Kin) -> float:
        j = k.s.joint_id(self.joint)
        return abs(float(k.d.qpos[k.m.jnt_qposadr[j]]) - self.value)


Constraint = Place | Orient | Look | JointTarget


@dataclasses.dataclass(frozen=True)
class IKProblem:
    """What must hold at one instant.

    Attributes:
      constraints: the constraints, all solved together.
      free_joints: model joints the solver may move; None = every joint that moves a
        constrained body (its ancestors). Other joints keep their warm-start value.
      touching: body pairs that may touch (up to ``CONTACT_ALLOWANCE`` deep) besides those
        that a site-to-site placement of this problem brings together.
      prefer: the posture the mild preference pulls toward (the realizer passes the current
        one, for the least motion); None = the solver's ``natural`` posture (``home``).
    """

    constraints: tuple[Constraint, ...]
    free_joints: tuple[str, ...] | None = None
    #: Body-name pairs allowed to touch (a contact elsewhere in the score holds them).
    touching: tuple[tuple[str, str], ...] = ()
    #: (nq,) the posture to prefer among the solutions; None = the solver's natural one.
    prefer: np.ndarray | None = dataclasses.field(default=None, compare=False)


@dataclasses.dataclass(frozen=True)
class Residual:
    """One constraint's error on the solution, in its unit ([m] or [rad])."""

    label: str
    kind: str
    value: float
    tol: float
    unit: str

    @property
    def ok(self) -> bool:
        return self.value <= self.tol


@dataclasses.dataclass(frozen=True)
class IKResult:
    """A solved posture and how it was reached.

    Attributes:
      qpos: (nq,) the posture.
      converged: every constraint within its tolerance and no penetration over the limit.
      residuals: per constraint, in problem order.
      penetration: deepest penetration between non-neighbouring geoms [m] (>= 0).
      iterations: accepted + rejected LM iterations, over all restarts.
      restarts: how many restarts were needed.
      time: wall time [s].
      history: (iterations,) the cost (sum of squared normalised rows) after each iteration.
    """

    qpos: np.ndarray
    converged: bool
    residuals: tuple[Residual, ...]
    penetration: float
    iterations: int
    restarts: int
    time: float
    history: np.ndarray


# ---------------------------------------------------------------------------------------
# The solver
# ---------------------------------------------------------------------------------------

#: Initial Levenberg-Marquardt damping, relative to the mean diagonal of J^T J.
MU0 = 1e-3
#: Largest change of one joint in one iteration [rad or m] (a trust region).
MAX_STEP = 0.4
#: Weight of the natural-posture rows (per radian; a constraint row is 1 at its tolerance).
POSTURE = 0.3
#: Penetration depth [m] at which a collision row reaches 1 (its "tolerance").
COLLISION_TOL = 1e-4
#: Depth [m] allowed between two bodies that a contact constraint brings together.
CONTACT_ALLOWANCE = 5e-4
#: Deepest penetration [m] a converged posture may have between non-neighbouring geoms.
PENETRATION_LIMIT = 1e-3


class Solver:
    """Solves :class:`IKProblem` s on one signer model.

    The solver compiles its own copy of the model with ``n_targets`` mocap targets and as
    many inactive ``connect`` equalities (see :meth:`configure_equalities`).

    Args:
      model_path: the signer MJCF path or an ``MjSpec`` (default: the bundled signer).
      signer_map: the AZee map of that signer (for joint groups and the natural posture).
      max_iter: LM iterations per attempt.
      restarts: further attempts from other starts when an attempt does not converge.
      margin: collision margin [m] for detecting near contacts.
    """

    def __init__(
        self,
        model_path=None,
        signer_map=None,
        *,
        n_targets: int = 16,
        max_iter: int = 60,
        restarts: int = 3,
        margin: float = 0.004,
        seed: int = 0,
    ):
        from azee_mj.model import MODEL_PATH
        from azee_mj.sites import DEFAULT_MAP

        self.signer_map = signer_map or DEFAULT_MAP
        if isinstance(model_path, mujoco.MjSpec):
            spec = model_path.copy()
        else:
            spec = mujoco.MjSpec.from_file(str(model_path or MODEL_PATH))
        add_target_pool(spec, n_targets)
        self.model = spec.compile()
        self.data = mujoco.MjData(self.model)
        m = self.model
        if m.nq != m.nv:
            raise ValueError("the IK solver needs hinge and slide joints only (nq == nv)")
        m.geom_margin[:] = np.where(m.geom_contype | m.geom_conaffinity, margin, 0.0)
        self.n_targets = n_targets
        self.max_iter = max_iter
        self.restarts = restarts
        self.seed = seed
        self._ids: dict[tuple[int, str], int] = {}
        self.lower = np.where(m.jnt_limited, m.jnt_range[:, 0], -np.inf)[m.dof_jntid]
        self.upper = np.where(m.jnt_limited, m.jnt_range[:, 1], np.inf)[m.dof_jntid]
        key = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, "home")
        self.natural = m.key_qpos[key].copy() if key >= 0 else m.qpos0.copy()
        self.dof_weight = self._dof_weights()

    # -- names ------------------------------------------------------------------------
    def _id(self, obj, name: str) -> int:
        key = (int(obj), name)
        i = self._ids.get(key)
        if i is None:
            i = mujoco.mj_name2id(self.model, obj, name)
            if i < 0:
                raise KeyError(f"the model has no {obj.name[6:].lower()} named {name!r}")
            self._ids[key] = i
        return i

    def site_id(self, name: str) -> int:
        return self._id(mujoco.mjtObj.mjOBJ_SITE, name)

    def body_id(self, name: str) -> int:
        return self._id(mujoco.mjtObj.mjOBJ_BODY, name)

    def joint_id(self, name: str) -> int:
        return self._id(mujoco.mjtObj.mjOBJ_JOINT, name)

    def _dof_weights(self) -> np.ndarray:
        """Per-dof damping: the trunk and neck are dearer to move than the arms."""
        w = np.ones(self.model.nv)
        cost = {"spine": 8.0, "head": 4.0}
        for track, joints in self.signer_map.tracks.items():
            for j in joints:
                jid = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_JOINT, j)
                if jid >= 0:
                    w[self.model.jnt_dofadr[jid]] = cost.get(track, 3.0 if "clav" in j else 1.0)
        return w

    # -- problem set-up ---------------------------------------------------------------
    def _bodies_of(self, c: Constraint) -> set[int]:
        out: set[int] = set()

        def walk(e):
            if isinstance(e, SitePos):
                out.add(int(self.model.site_bodyid[self.site_id(e.site)]))
            elif isinstance(e, (BodyAxis, _BodyOrigin)):
                out.add(self.body_id(e.body))
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
        elif isinstance(c, Orient):
            walk(BodyAxis(c.body, c.local))
            walk(c.vector)
        elif isinstance(c, Look):
            for body, _ in c.eyes:
                out.add(self.body_id(body))
            walk(c.target)
        return out

    def free_dofs(self, problem: IKProblem) -> np.ndarray:
        """Dof indices the solver moves for ``problem`` (sorted)."""
        m = self.model
        if problem.free_joints is not None:
            dofs = {int(m.jnt_dofadr[self.joint_id(j)]) for j in problem.free_joints}
        else:
            dofs = set()
            for c in problem.constraints:
                if isinstance(c, JointTarget):
                    dofs.add(int(m.jnt_dofadr[self.joint_id(c.joint)]))
                for b in self._bodies_of(c):
                    while b > 0:
                        a, n = m.body_dofadr[b], m.body_dofnum[b]
                        dofs.update(range(a, a + n))
                        b = m.body_parentid[b]
        return np.array(sorted(dofs), dtype=int)

    def _joined_bodies(self, problem: IKProblem) -> set[tuple[int, int]]:
        """Body pairs a site-to-site placement brings together (allowed to touch)."""
        pairs = set()
        for a, b in problem.touching:
            pairs |= {(self.body_id(a), self.body_id(b)), (self.body_id(b), self.body_id(a))}
        for c in problem.constraints:
            if isinstance(c, Place):
                bodies = self._bodies_of(c)
                for a in bodies:
                    for b in bodies:
                        if a != b:
                            pairs.add((a, b))
        return pairs

    # -- rows ---------------------------------------------------------------------------
    def _plan(self, problem: IKProblem) -> _Plan:
        """The problem compiled for this solver (rows, buffers, free dofs)."""
        return _Plan(self, problem)

    def _evaluate(self, q, plan: _Plan):
        """Residual rows (k,), Jacobian (k, len(free)), per-constraint row norms, depth."""
        m, d = self.model, self.data
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        r, J = plan.rows()
        norms = [float(np.sqrt(r[a:b] @ r[a:b])) for a, b in plan.hard]
        Jf = J[:, plan.free]
        depth = 0.0
        if plan.collide:
            mujoco.mj_collision(m, d)
        n = d.ncon if plan.collide else 0
        if n:
            dist = d.contact.dist[:n]
            geom = d.contact.geom[:n]
            b1 = m.geom_bodyid[geom[:, 0]]
            b2 = m.geom_bodyid[geom[:, 1]]
            floor = plan.floor[b1, b2]
            hit = np.flatnonzero(dist < floor)
            if hit.size:
                own = dist[hit][floor[hit] == 0.0]
                depth = float(-own.min()) if own.size else 0.0
                normal = d.contact.frame[hit, :3]
                pos = d.contact.pos[hit]
                j1, j2 = plan.cbuf1, plan.cbuf2
                rows = np.empty((hit.size, plan.free.size))
                for r_i, i in enumerate(hit):
                    mujoco.mj_jac(m, d, j1, None, pos[r_i], b1[i])
                    mujoco.mj_jac(m, d, j2, None, pos[r_i], b2[i])
                    rows[r_i] = normal[r_i] @ (j2 - j1)[:, plan.free]
                r = np.concatenate([r, (dist[hit] - floor[hit]) / COLLISION_TOL])
                Jf = np.vstack([Jf, rows / COLLISION_TOL])
        return r, Jf, norms, max(depth, 0.0)

    # -- solve --------------------------------------------------------------------------
    def solve(self, problem: IKProblem, q0: np.ndarray | None = None) -> IKResult:
        """Solve ``problem`` warm-started from ``q0`` (nq,) (default: the natural posture).

        Never raises for geometry: an infeasible problem returns the best posture found
        with ``converged=False``.
        """
        t0 = time.perf_counter()
        q_start = np.clip(self.natural if q0 is None else np.asarray(q0, float),
                          self.lower, self.upper)  # fmt: skip
        cons = problem.constraints
        plan = self._plan(problem)
        free = plan.free
        best = None
        history: list[float] = []
        iters = 0
        attempt = 0
        start = q_start
        while True:
            # First with the natural-posture preference, then without it, so that it picks
            # among the solutions but never biases the constraints.
            if attempt == 1:
                # Self-collision can trap the iteration in a corner: reach the constraints
                # with the body transparent, then let the collision rows push parts apart.
                plan.collide = False
                start, _, _, n_it = self._lm(start, plan, history, POSTURE)
                plan.collide = True
                iters += n_it
            q, cost, ok, n_it = self._lm(start, plan, history, POSTURE)
            iters += n_it
            if not ok:
                q, cost, ok, n_it = self._lm(q, plan, history)
                iters += n_it
            if best is None or cost < best[1]:
                best = (q, cost)
            if ok or attempt >= self.restarts:
                break
            attempt += 1
            start = self._restart_point(attempt, q_start, free)
        q = best[0]
        residuals, depth = plan.report(q)
        hard = [r for r, c in zip(residuals, cons) if not getattr(c, "soft", False)]
        converged = all(r.ok for r in hard) and depth <= PENETRATION_LIMIT
        return IKResult(
            qpos=q, converged=converged, residuals=residuals, penetration=depth,
            iterations=iters, restarts=attempt, time=time.perf_counter() - t0,
            history=np.asarray(history),
        )  # fmt: skip

    def _restart_point(self, attempt, q_start, free):
        """Attempt 1 retries the start with self-collision off at first, attempt 2 starts
        from the natural posture, later ones from random postures halfway between it and a
        uniform sample of the joint ranges."""
        if attempt == 1:
            return q_start.copy()
        q = self.natural.copy()
        if attempt > 2 or np.allclose(q[free], q_start[free]):
            lo = np.maximum(self.lower[free], -np.pi)
            hi = np.minimum(self.upper[free], np.pi)
            # Seeded per attempt: a solve depends only on its problem and start.
            rng = np.random.default_rng((self.seed, attempt))
            q[free] = 0.5 * (q[free] + rng.uniform(lo, hi))
        untouched = np.setdiff1d(np.arange(self.model.nv), free)
        q[untouched] = q_start[untouched]
        return np.clip(q, self.lower, self.upper)

    def _lm(self, q, plan, history, posture=0.0, stop=0.05):
        """One Levenberg-Marquardt run on the constraint rows plus, if ``posture`` > 0, rows
        ``posture * (q - natural)`` weighted per dof. Returns (q, cost, done, iterations),
        ``done`` when every constraint row norm is under ``stop`` (its tolerance fraction)."""
        free = plan.free
        lo, hi = self.lower[free], self.upper[free]
        w = self.dof_weight[free]
        nat = plan.prefer[free]
        q = q.copy()
        r, J, norms, depth = self._evaluate(q, plan)
        cost = float(r @ r)
        if posture:
            cost += posture**2 * float(w @ (q[free] - nat) ** 2)
        mu, nu = MU0, 2.0
        stalls = 0
        diag = np.diag_indices(free.size)
        n = free.size
        res = np.zeros(n)
        R = np.zeros((n, n + 7))
        it = 0
        for it in range(1, self.max_iter + 1):
            if max(norms, default=0.0) <= stop and depth <= 2 * COLLISION_TOL:
                return q, cost, True, it - 1
            H = J.T @ J
            g = J.T @ r
            if posture:
                # The mild preference for the natural posture: rows posture * (q - natural).
                H[diag] += posture**2 * w
                g += posture**2 * w * (q[free] - nat)
            Hd = H.copy()
            Hd[diag] += mu * (np.trace(H) / n + 1.0) * w
            res[:] = 0.0
            lo_step = np.maximum(lo - q[free], -MAX_STEP)
            hi_step = np.minimum(hi - q[free], MAX_STEP)
            mujoco.mju_boxQP(res, R, None, Hd, g, lo_step, hi_step)
            q_new = q.copy()
            q_new[free] = np.clip(q[free] + res, lo, hi)
            r_new, J_new, norms_new, depth_new = self._evaluate(q_new, plan)
            cost_new = float(r_new @ r_new)
            if posture:
                cost_new += posture**2 * float(w @ (q_new[free] - nat) ** 2)
            if cost_new < cost:
                gain = (cost - cost_new) / cost
                # Nielsen's update from the ratio of actual to predicted decrease.
                predicted = -(2.0 * g @ res + res @ H @ res)
                rho = (cost - cost_new) / predicted if predicted > 0 else 0.0
                q, r, J, norms, depth, cost = q_new, r_new, J_new, norms_new, depth_new, cost_new
                mu = max(mu * max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3), 1e-7)
                nu = 2.0
                history.append(cost)
                if gain < (0.02 if posture else 1e-3):
                    stalls += 1
                    if posture or stalls >= 3:
                        break  # preference done (polish without it), or stuck in a minimum
            else:
                mu *= nu
                nu *= 2.0
                history.append(cost)
            if mu > 1e3 or float(res @ res) < 1e-20:
                break
        done = max(norms, default=0.0) <= stop and depth <= 2 * COLLISION_TOL
        return q, cost, done, it

    # -- equality constraints --------------------------------------------------------------
    def configure_equalities(self, problem: IKProblem, data: mujoco.MjData | None = None) -> int:
        """Mirror the problem's placements as MuJoCo ``connect`` equalities.

        A placement at a fixed point uses a mocap target; a site-to-site contact connects
        the two sites directly. Returns how many equalities are active; placements with a
        posture-dependent target other than a bare site are left to the solver's own rows.
        """
        m = self.model
        d = data if data is not None else self.data
        first = m.neq - self.n_targets
        m.eq_active0[first:] = 0
        d.eq_active[first:] = 0
        k = 0
        for c in problem.constraints:
            if not isinstance(c, Place) or k >= self.n_targets:
                continue
            eq = first + k
            m.eq_obj1id[eq] = self.site_id(c.site)
            if isinstance(c.target, SitePos):
                m.eq_obj2id[eq] = self.site_id(c.target.site)
            elif isinstance(c.target, Const):
                m.eq_obj2id[eq] = self.site_id(f"ik_target_{k}")
                d.mocap_pos[m.body_mocapid[self.body_id(f"ik_target_{k}")]] = c.target.value
            else:
                continue
            m.eq_active0[eq] = 1
            d.eq_active[eq] = 1
            k += 1
        return k


def add_target_pool(spec: mujoco.MjSpec, n: int) -> None:
    """Add ``n`` mocap bodies ``ik_target_k`` with a site each, and ``n`` inactive site-based
    ``connect`` equalities ``ik_connect_k`` that :meth:`Solver.configure_equalities` aims."""
    anchor = spec.sites[0].name
    for k in range(n):
        body = spec.worldbody.add_body(name=f"ik_target_{k}", mocap=True)
        body.add_site(name=f"ik_target_{k}", size=[0.006, 0, 0], rgba=[0.1, 0.8, 0.2, 0.6],
                      group=5)  # fmt: skip
        spec.add_equality(
            name=f"ik_connect_{k}", type=mujoco.mjtEq.mjEQ_CONNECT,
            objtype=mujoco.mjtObj.mjOBJ_SITE, name1=anchor, name2=f"ik_target_{k}", active=False,
        )  # fmt: skip


def penetration_depth(m: mujoco.MjModel, d: mujoco.MjData, allowed=frozenset()) -> float:
    """Deepest penetration [m] (>= 0) between colliding geoms of posture ``d.qpos``, ignoring
    body pairs in ``allowed``. Runs ``mj_kinematics`` and ``mj_collision``."""
    mujoco.mj_kinematics(m, d)
    mujoco.mj_collision(m, d)
    n = d.ncon
    if not n:
        return 0.0
    dist = d.contact.dist[:n]
    if allowed:
        b = m.geom_bodyid[d.contact.geom[:n]]
        keep = np.array([(x, y) not in allowed for x, y in b])
        dist = dist[keep]
    return float(max(0.0, -dist.min())) if dist.size else 0.0


class _Plan:
    """A problem compiled for one solver: ids resolved, row blocks laid out, buffers made.

    Common constraint forms (a placement at a fixed point or on another site, an
    orientation toward a fixed vector, a joint target) write their rows straight from
    ``mj_jacSite`` / ``mj_jacBody``; other forms go through the expression evaluator.
    """

    def __init__(self, solver: Solver, problem: IKProblem):
        m = solver.model
        self.s, self.m, self.d = solver, m, solver.data
        self.free = solver.free_dofs(problem)
        self.joined = solver._joined_bodies(problem)
        self.floor = np.zeros((m.nbody, m.nbody))
        for a, b in self.joined:
            self.floor[a, b] = -CONTACT_ALLOWANCE
        self.items: list = []
        self.collide = True
        self.prefer = solver.natural if problem.prefer is None else np.asarray(problem.prefer)
        self.cons = problem.constraints
        self.slide = {c.joint: m.jnt_type[solver.joint_id(c.joint)] == mujoco.mjtJoint.mjJNT_SLIDE
                      for c in problem.constraints if isinstance(c, JointTarget)}  # fmt: skip
        self.hard: list[tuple[int, int]] = []
        inv: list[float] = []
        row = 0
        for c in problem.constraints:
            fn, k, scaled = self._compile(c)
            self.items.append((fn, row, row + k, scaled))
            if not getattr(c, "soft", False):
                self.hard.append((row, row + k))
            inv += [1.0 if scaled else 1.0 / c.tol] * k
            row += k
        self.inv = np.array(inv)
        self.J = np.zeros((row, m.nv))
        self.r = np.zeros(row)
        self.tmp = np.empty((3, m.nv))
        self.cbuf1, self.cbuf2 = np.empty((3, m.nv)), np.empty((3, m.nv))
        for c, (_, a, _, _) in zip(problem.constraints, self.items):
            if isinstance(c, JointTarget):
                self.J[a, m.jnt_dofadr[solver.joint_id(c.joint)]] = 1.0

    def _compile(self, c):
        """(fn(r_block, J_block), number of rows, rows already scaled by 1/tol)."""
        s, m, d = self.s, self.m, self.d
        if isinstance(c, Place) and isinstance(c.target, (Const, SitePos)):
            sid = s.site_id(c.site)
            if isinstance(c.target, Const):
                t = np.asarray(c.target.value, float)

                def place(r, J):
                    mujoco.mj_jacSite(m, d, J, None, sid)
                    r[:] = d.site_xpos[sid] - t

                return place, 3, False
            sid2 = s.site_id(c.target.site)

            def contact(r, J):
                mujoco.mj_jacSite(m, d, J, None, sid)
                mujoco.mj_jacSite(m, d, self.tmp, None, sid2)
                J -= self.tmp
                r[:] = d.site_xpos[sid] - d.site_xpos[sid2]

            return contact, 3, False
        if isinstance(c, Orient) and isinstance(c.vector, Const):
            bid = s.body_id(c.body)
            local = np.asarray(c.local, float)
            v = np.asarray(c.vector.value, float)
            v = v / np.linalg.norm(v) * (-1.0 if c.rel is Rel.OPP else 1.0)
            perp = c.rel is Rel.PERP

            def orient(r, J):
                mujoco.mj_jacBody(m, d, None, self.tmp, bid)
                a = d.xmat[bid].reshape(3, 3) @ local
                da = _skew(-a) @ self.tmp  # da/dq = -[a]x J_rot
                if perp:
                    r[0] = a @ v
                    J[0] = v @ da
                else:
                    r[:] = a - v
                    J[:] = da

            return orient, 1 if perp else 3, False
        if isinstance(c, JointTarget):
            adr = m.jnt_qposadr[s.joint_id(c.joint)]
            value = c.value

            def joint(r, J):
                r[0] = d.qpos[adr] - value

            return joint, 1, False
        if isinstance(c, Look):
            k = 3 * len(c.eyes)
        else:
            k = 1 if isinstance(c, Orient) and c.rel is Rel.PERP else 3

        def generic(r, J):
            r[:], J[:] = c.rows(_Kin(s))

        return generic, k, True

    def rows(self) -> tuple[np.ndarray, np.ndarray]:
        """Scaled residual (k,) and Jacobian (k, nv) on the posture in ``solver.data``."""
        for fn, a, b, _ in self.items:
            fn(self.r[a:b], self.J[a:b])
        return self.r * self.inv, self.J * self.inv[:, None]

    def report(self, q: np.ndarray) -> tuple[tuple[Residual, ...], float]:
        """Per-constraint residuals in their units and the deepest penetration [m] (outside
        the allowed contact pairs) of posture ``q``."""
        m, d = self.m, self.d
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        out = []
        for c, (fn, a, b, generic) in zip(self.cons, self.items):
            fn(self.r[a:b], self.J[a:b])
            r = self.r[a:b]
            if generic:
                value = c.residual(_Kin(self.s))
            elif isinstance(c, Orient):
                if c.rel is Rel.PERP:
                    value = float(np.arcsin(min(1.0, abs(r[0]))))
                else:
                    value = float(2.0 * np.arcsin(min(1.0, np.sqrt(r @ r) / 2.0)))
            else:
                value = float(np.sqrt(r @ r))
            unit = "rad"
            if isinstance(c, Place) or isinstance(c, JointTarget) and self.slide[c.joint]:
                unit = "m"
            out.append(Residual(c.label, type(c).__name__.lower(), value, c.tol, unit))
        return tuple(out), penetration_depth(m, d, self.joined)
