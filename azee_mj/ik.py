"""Posture solving: constraints on a MuJoCo model, with joint limits and self-collision.

The solver knows nothing of AZee: the caller gives it the model and the per-joint weights
(:func:`azee_mj.schedule.make_solver` builds both for a signer).

An :class:`IKProblem` is everything that must hold at one instant. :class:`Solver` turns it
into residual rows with exact Jacobians from MuJoCo's kinematics (``mj_jacSite``,
``mj_jacBody``, ``mj_jac`` at contact points from ``mj_collision``) and solves them with a
damped least-squares (Levenberg-Marquardt) iteration whose steps are box-constrained QPs
(``mujoco.mju_boxQP``), so joint limits hold exactly.

Placements with a fixed target and site-to-site contacts are also mirrored as MuJoCo
``connect`` equality constraints on a pool of mocap targets in the solver's model
(:meth:`Solver.configure_equalities`), so the viewer can draw them and a simulation can use
them; their rows are the same as MuJoCo's (the tests compare them with ``efc_J``/``efc_pos``).
MuJoCo has no equality for "axis along / opposite / perpendicular"; those rows, and the
self-collision rows, are in :mod:`azee_mj.constraints`.
Infeasible problems are not errors: the solver returns its best posture, ``converged=False``
and every constraint's residual.

Units: metres, radians, seconds.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Mapping

import mujoco
import numpy as np

from azee_mj.constraints import (
    COLLISION_TOL,
    CONTACT_ALLOWANCE,
    PENETRATION_LIMIT,
    Collisions,
    Constraint,
    JointTarget,
    Look,
    Orient,
    Place,
    Rel,
    penetration_depth,
)
from azee_mj.kinematics import (
    BodyAxis,
    BodyOrigin,
    Const,
    Cross,
    Kinematics,
    Lin,
    Names,
    SitePos,
    Unit,
    skew,
)
from azee_mj.natural import Effort, Naturalness
from azee_mj.natural import rows as natural_rows


@dataclasses.dataclass(frozen=True)
class IKProblem:
    """What must hold at one instant.

    Attributes:
      constraints: the constraints, all solved together.
      free_joints: model joints the solver may move; None = every joint that moves a
        constrained body (its ancestors). Other joints keep their warm-start value.
      touching: body pairs that may touch (up to ``CONTACT_ALLOWANCE`` deep) besides those
        that a site-to-site placement of this problem brings together.
      prefer: the posture the guide pulls toward while reaching the constraints (the
        realizer passes the current one, for the least motion); None = ``natural``.
      seeds: postures (nq,) to start from besides the warm start (e.g. analytic arm
        postures); every start is tried and the best result by one cost kept.
      max_change: largest change of any free joint from the warm start [rad or m]: a
        per-frame solve stays on the branch of the frame before (restarts stay inside).
      natural: take the most natural posture among the solutions (False: the first one
        reached, e.g. for an intermediate solve).
      collide: keep the body out of itself (False: a transparent body, for diagnosis).
      preferences: constraints that join the naturalness objective (rows scaled by their
        tolerance), e.g. where two hands meet when nothing else says where.
      restarts: further attempts when none meets everything (None: the solver's own).
    """

    constraints: tuple[Constraint, ...]
    free_joints: tuple[str, ...] | None = None
    #: Body-name pairs allowed to touch (a contact elsewhere in the score holds them).
    touching: tuple[tuple[str, str], ...] = ()
    #: (nq,) the posture to prefer among the solutions; None = the solver's natural one.
    prefer: np.ndarray | None = dataclasses.field(default=None, compare=False)
    seeds: tuple[np.ndarray, ...] = dataclasses.field(default=(), compare=False)
    max_change: float | None = None
    natural: bool = True
    collide: bool = True
    preferences: tuple[Constraint, ...] = ()
    restarts: int | None = None


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
#: Weight of the guide toward the preferred posture while the constraints are being
#: reached (per radian; a constraint row is 1 at its tolerance).
POSTURE = 0.3
#: Singular values below this fraction of the largest span the constraints' null space.
NULL_TOL = 1e-4
#: Most natural-posture steps once the constraints are met.
NATURAL_ITER = 30
#: First trust radius of a natural-posture step [rad].
NATURAL_STEP = 0.2

class Solver:
    """Solves :class:`IKProblem` s on one model.

    The solver compiles its own copy of the model with ``n_targets`` mocap targets and as
    many inactive ``connect`` equalities (see :meth:`configure_equalities`).

    Args:
      model: an MJCF path or an ``MjSpec`` (copied).
      joint_weights: joint name -> how dear moving it is in the damping and the natural-posture
        preference (default 1; names the model lacks are ignored).
      max_iter: LM iterations per attempt.
      restarts: further attempts from other starts when an attempt does not converge.
      margin: collision margin [m] for detecting near contacts.
      on_solve: called with each problem and its result, in solving order (an observer).
      naturalness: what makes a posture natural (:mod:`azee_mj.natural`); among the
        postures that meet the constraints without penetration the solver takes the most
        natural one. None = the first it reaches.
    """

    def __init__(
        self,
        model,
        *,
        joint_weights: Mapping[str, float] | None = None,
        n_targets: int = 16,
        max_iter: int = 60,
        restarts: int = 3,
        margin: float = 0.004,
        seed: int = 0,
        on_solve: Callable[[IKProblem, IKResult], None] | None = None,
        naturalness: Naturalness | None = None,
    ):
        if isinstance(model, mujoco.MjSpec):
            spec = model.copy()
        else:
            spec = mujoco.MjSpec.from_file(str(model))
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
        self.on_solve = on_solve
        self.names = Names(m)
        self.lower = np.where(m.jnt_limited, m.jnt_range[:, 0], -np.inf)[m.dof_jntid]
        self.upper = np.where(m.jnt_limited, m.jnt_range[:, 1], np.inf)[m.dof_jntid]
        key = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, "home")
        self.natural = m.key_qpos[key].copy() if key >= 0 else m.qpos0.copy()
        self.dof_weight = np.ones(m.nv)
        for j, w in (joint_weights or {}).items():
            jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j)
            if jid >= 0:
                self.dof_weight[m.jnt_dofadr[jid]] = w
        self.set_naturalness(naturalness)

    def set_naturalness(self, naturalness: Naturalness | None) -> None:
        """Prefer the most natural posture by ``naturalness`` (None: the first reached)."""
        self.naturalness = naturalness
        self.effort_dofs = (np.flatnonzero(naturalness.strength > 0) if naturalness is not None
                            else np.zeros(0, int))  # fmt: skip

    # -- names ------------------------------------------------------------------------
    def site_id(self, name: str) -> int:
        return self.names.site(name)

    def body_id(self, name: str) -> int:
        return self.names.body(name)

    def joint_id(self, name: str) -> int:
        return self.names.joint(name)

    def kinematics(self) -> Kinematics:
        """A :class:`~azee_mj.kinematics.Kinematics` on the posture in ``self.data``."""
        return Kinematics(self.model, self.data, self.names)

    # -- problem set-up ---------------------------------------------------------------
    def bodies_of(self, c: Constraint) -> set[int]:
        """The bodies whose motion changes constraint ``c``'s rows."""
        out: set[int] = set()

        def walk(e):
            if isinstance(e, SitePos):
                out.add(int(self.model.site_bodyid[self.site_id(e.site)]))
            elif isinstance(e, (BodyAxis, BodyOrigin)):
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
                for b in self.bodies_of(c):
                    while b > 0:
                        a, n = m.body_dofadr[b], m.body_dofnum[b]
                        dofs.update(range(a, a + n))
                        b = m.body_parentid[b]
        return np.array(sorted(dofs), dtype=int)

    def joined_bodies(self, problem: IKProblem) -> set[tuple[int, int]]:
        """Body pairs a site-to-site placement brings together (allowed to touch)."""
        pairs = set()
        for a, b in problem.touching:
            pairs |= {(self.body_id(a), self.body_id(b)), (self.body_id(b), self.body_id(a))}
        for c in problem.constraints:
            if isinstance(c, Place):
                bodies = self.bodies_of(c)
                for a in bodies:
                    for b in bodies:
                        if a != b:
                            pairs.add((a, b))
        return pairs

    # -- rows ---------------------------------------------------------------------------
    def plan(self, problem: IKProblem) -> Plan:
        """The problem compiled for this solver (rows, buffers, free dofs)."""
        return Plan(self, problem)

    def _evaluate(self, q, plan: Plan) -> Rows:
        """The rows of ``plan`` on posture ``q``."""
        m, d = self.model, self.data
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        r, J = plan.rows()
        norms = [float(np.sqrt(r[a:b] @ r[a:b])) for a, b in plan.hard]
        Jf = J[:, plan.free]
        depth = 0.0
        hits = plan.collisions.rows(d) if plan.collide else None
        if hits is not None:
            depth = hits.depth
            r = np.concatenate([r, hits.r])
            Jf = np.vstack([Jf, hits.J])
        return Rows(r, Jf, norms, max(depth, 0.0))

    # -- solve --------------------------------------------------------------------------
    def solve(self, problem: IKProblem, q0: np.ndarray | None = None) -> IKResult:
        """Solve ``problem`` warm-started from ``q0`` (nq,) (default: the natural posture).

        Strict priorities: the constraints, then no penetration, then (with a
        ``naturalness``) the most natural posture among those that meet both.
        Never raises for geometry: an infeasible problem returns the best posture found
        with ``converged=False``.
        """
        t0 = time.perf_counter()
        q_start = np.clip(self.natural if q0 is None else np.asarray(q0, float),
                          self.lower, self.upper)  # fmt: skip
        cons = problem.constraints
        plan = self.plan(problem)
        free = plan.free
        history: list[float] = []
        if problem.max_change is not None:
            plan.lower = np.maximum(plan.lower, q_start - problem.max_change)
            plan.upper = np.minimum(plan.upper, q_start + problem.max_change)
        # Every seed and the warm start, then restarts (inside the max_change box) until one
        # meets everything; the best attempt by one cost is kept.
        best = None
        iters = attempt = 0
        for start in [np.clip(q, plan.lower, plan.upper) for q in problem.seeds] + [q_start]:
            run = self._attempt(start, plan, history)
            iters += run.iterations
            if best is None or run.rank < best.rank:
                best = run
        restarts = self.restarts if problem.restarts is None else problem.restarts
        while best.rank[0] and attempt < restarts:
            attempt += 1
            start = np.clip(self._restart_point(attempt, q_start, free), plan.lower, plan.upper)
            run = self._attempt(start, plan, history, transparent_first=attempt == 1)
            iters += run.iterations
            if run.rank < best.rank:
                best = run
        q = best.q
        residuals, depth = plan.report(q)
        hard = [r for r, c in zip(residuals, cons) if not c.soft]
        converged = all(r.ok for r in hard) and depth <= PENETRATION_LIMIT
        result = IKResult(
            qpos=q, converged=converged, residuals=residuals, penetration=depth,
            iterations=iters, restarts=attempt, time=time.perf_counter() - t0,
            history=np.asarray(history),
        )  # fmt: skip
        if self.on_solve is not None:
            self.on_solve(problem, result)
        return result

    def _attempt(self, start, plan, history, transparent_first=False) -> Attempt:
        """One attempt from ``start``: reach the constraints (guided toward the preferred
        posture, then without the guide), then the most natural posture that keeps them."""
        iters = 0
        if transparent_first:
            # Self-collision can trap the iteration in a corner: reach the constraints
            # with the body transparent, then let the collision rows push parts apart.
            plan.collide = False
            start = self._lm(start, plan, history, POSTURE).q
            plan.collide = plan.problem.collide
        run = self._lm(start, plan, history, POSTURE)
        iters += run.iterations
        if not run.done:
            run = self._lm(run.q, plan, history)
            iters += run.iterations
        if not run.met:
            return Attempt(run.q, (1, run.cost), iters)
        if not plan.natural:
            return Attempt(run.q, (0, 0.0), iters)
        q, nat, n_it = self._polish(run.q, plan, history)
        return Attempt(q, (0, nat), iters + n_it)

    def _natural(self, plan: Plan) -> tuple[np.ndarray, np.ndarray]:
        r, J = natural_rows(self.naturalness, plan.effort, self.data, plan.free)
        if not plan.problem.preferences:
            return r, J
        k = self.kinematics()
        rows = [c.rows(k) for c in plan.problem.preferences]
        return (np.concatenate([r, *(x for x, _ in rows)]),
                np.vstack([J, *(j[:, plan.free] for _, j in rows)]))

    def _polish(self, q, plan, history, stop=0.05) -> tuple[np.ndarray, float, int]:
        """The most natural posture among those that meet the constraints, from ``q`` that
        meets them: Gauss-Newton steps on the naturalness rows in the null space of the
        constraint and collision rows (and of the joints at a limit the step would cross),
        each followed by steps back onto the constraints. A step is kept only if every
        constraint stays within ``stop`` of its tolerance and no contact goes deeper, so
        naturalness never bends a constraint. Returns (q, natural cost, iterations)."""
        free = plan.free
        mov = np.flatnonzero(~plan.pinned)  # a joint target (a hand shape) pins its joint
        if self.naturalness is None or not mov.size:
            return q, 0.0, 0
        lo, hi = plan.lower[free], plan.upper[free]
        n = free.size
        e = self._evaluate(q, plan)
        rn, Jn = self._natural(plan)
        nat = float(rn @ rn)
        radius, stalls, it = NATURAL_STEP, 0, 0
        res = np.zeros(n)
        R = np.zeros((n, n + 7))
        eye = np.eye(mov.size)
        for it in range(1, NATURAL_ITER + 1):
            Jm, Jnm = e.J[:, mov], Jn[:, mov]
            Hn = Jnm.T @ Jnm
            gn = Jnm.T @ rn
            locked = np.zeros(mov.size, bool)
            N = eye
            for _ in range(3):
                A = np.vstack([Jm, eye[locked]]) if locked.any() else Jm
                if A.shape[0]:
                    _, S, Vt = np.linalg.svd(A, full_matrices=True)
                    k = int(np.sum(S > NULL_TOL * S[0])) if S.size and S[0] > 0 else 0
                    N = Vt[k:].T
                if not N.shape[1]:
                    break
                B = N.T @ Hn @ N
                B[np.diag_indices_from(B)] += 1e-3 * (np.trace(B) / N.shape[1] + 1e-12)
                step_m = N @ -np.linalg.solve(B, N.T @ gn)
                qm = q[free[mov]] + step_m
                out = (qm < lo[mov] - 1e-12) | (qm > hi[mov] + 1e-12)
                if not (out & ~locked).any():
                    break
                locked |= out
            if not N.shape[1]:
                break
            step = np.zeros(n)
            step[mov] = step_m
            big = float(np.abs(step).max())
            if big > radius:
                step *= radius / big
            q_new = q.copy()
            q_new[free] = np.clip(q[free] + step, lo, hi)
            e_new = self._evaluate(q_new, plan)
            for _ in range(2):  # back onto the constraints (the step is first-order)
                if not e_new.r.size or max(e_new.norms, default=0.0) <= stop:
                    break
                H = e_new.J.T @ e_new.J
                H[np.diag_indices(n)] += 1e-9 * (np.trace(H) / n + 1.0)
                res[:] = 0.0
                mujoco.mju_boxQP(res, R, None, H, e_new.J.T @ e_new.r, lo - q_new[free],
                                 hi - q_new[free])  # fmt: skip
                q_new[free] = np.clip(q_new[free] + res, lo, hi)
                e_new = self._evaluate(q_new, plan)
            rn_new, Jn_new = self._natural(plan)
            nat_new = float(rn_new @ rn_new)
            # never further from a constraint than the polish started, nor deeper
            bound = max(stop, max(e.norms, default=0.0))
            ok = max(e_new.norms, default=0.0) <= bound and e_new.depth <= max(e.depth, 1e-5)
            if ok and nat_new < nat:
                gain = (nat - nat_new) / max(nat, 1e-12)
                q, e, rn, Jn, nat = q_new, e_new, rn_new, Jn_new, nat_new
                radius = min(2.0 * radius, MAX_STEP)
                stalls = stalls + 1 if gain < 1e-3 else 0
            else:
                radius *= 0.25
                stalls += 1 if radius < 1e-3 else 0
            history.append(float(e.r @ e.r))
            if stalls >= 2:
                break
        return q, nat, it

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

    def _lm(self, q, plan, history, posture=0.0, stop=0.05) -> LMRun:
        """One Levenberg-Marquardt run on the constraint rows plus, if ``posture`` > 0, rows
        ``posture * (q - natural)`` weighted per dof; ``done`` when every constraint row norm is
        under ``stop`` (its tolerance fraction)."""
        free = plan.free
        lo, hi = plan.lower[free], plan.upper[free]
        w = self.dof_weight[free]
        nat = plan.prefer[free]
        q = q.copy()
        e = self._evaluate(q, plan)
        r, J, norms, depth = e.r, e.J, e.norms, e.depth
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
                return LMRun(q, cost, True, it - 1, True)
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
            e = self._evaluate(q_new, plan)
            r_new, J_new, norms_new, depth_new = e.r, e.J, e.norms, e.depth
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
        met = max(norms, default=0.0) <= 1.0 and depth <= 2 * COLLISION_TOL
        return LMRun(q, cost, done, it, done or met)

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


@dataclasses.dataclass(frozen=True)
class Rows:
    """The rows of a plan on one posture: residual (k,), Jacobian (k, free), each hard
    constraint's row norm, and the deepest penetration [m] outside allowed pairs."""

    r: np.ndarray
    J: np.ndarray
    norms: list[float]
    depth: float


@dataclasses.dataclass(frozen=True)
class LMRun:
    """One Levenberg-Marquardt run: its posture, cost, whether every row is within its
    tolerance fraction, and its iterations."""

    q: np.ndarray
    cost: float
    done: bool
    iterations: int
    #: every constraint within its tolerance, nothing deeper than allowed (not ``done``
    #: when it stalled short of the tolerance fraction)
    met: bool = False


@dataclasses.dataclass(frozen=True)
class Attempt:
    """One attempt's posture, ``rank`` ((0, natural cost) when it meets every constraint
    without penetration, else (1, constraint cost): lower is better), and iterations."""

    q: np.ndarray
    rank: tuple[int, float]
    iterations: int


@dataclasses.dataclass(frozen=True)
class RowBlock:
    """One constraint's rows in a plan: ``fn(r_block, J_block)`` writes rows
    ``[start, stop)``; ``scaled`` when they come already divided by the tolerance."""

    fn: Callable[[np.ndarray, np.ndarray], None]
    start: int
    stop: int
    scaled: bool


class Plan:
    """A problem compiled for one solver: ids resolved, row blocks laid out, buffers made.

    Common constraint forms (a placement at a fixed point or on another site, an
    orientation toward a fixed vector, a joint target) write their rows straight from
    ``mj_jacSite`` / ``mj_jacBody``; other forms go through the expression evaluator.
    """

    def __init__(self, solver: Solver, problem: IKProblem):
        m = solver.model
        self.s, self.m, self.d = solver, m, solver.data
        self.free = solver.free_dofs(problem)
        self.joined = solver.joined_bodies(problem)
        self.floor = np.zeros((m.nbody, m.nbody))
        for a, b in self.joined:
            # An attempt is done within 2 COLLISION_TOL of the floor: within the allowance.
            self.floor[a, b] = -(CONTACT_ALLOWANCE - 2 * COLLISION_TOL)
        self.lower, self.upper = solver.lower, solver.upper
        self.effort = Effort(m, solver.effort_dofs)
        self.natural = problem.natural
        self.problem = problem
        self.collide = problem.collide
        self.items: list[RowBlock] = []
        self.prefer = solver.natural if problem.prefer is None else np.asarray(problem.prefer)
        self.cons = problem.constraints
        self.slide = {c.joint: m.jnt_type[solver.joint_id(c.joint)] == mujoco.mjtJoint.mjJNT_SLIDE
                      for c in problem.constraints if isinstance(c, JointTarget)}  # fmt: skip
        self.hard: list[tuple[int, int]] = []
        inv: list[float] = []
        row = 0
        for c in problem.constraints:
            fn, k, scaled = self._compile(c)
            self.items.append(RowBlock(fn, row, row + k, scaled))
            if not c.soft:
                self.hard.append((row, row + k))
            inv += [1.0 if scaled else 1.0 / c.tol] * k
            row += k
        self.inv = np.array(inv)
        self.J = np.zeros((row, m.nv))
        self.r = np.zeros(row)
        self.tmp = np.empty((3, m.nv))
        self.collisions = Collisions(m, self.floor, self.free)
        pinned = set()
        for c, item in zip(problem.constraints, self.items):
            if isinstance(c, JointTarget):
                dof = int(m.jnt_dofadr[solver.joint_id(c.joint)])
                self.J[item.start, dof] = 1.0
                pinned.add(dof)
        #: (len(free),) dofs a joint target sets: the natural-posture steps leave them.
        self.pinned = np.isin(self.free, sorted(pinned))

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
                da = skew(-a) @ self.tmp  # da/dq = -[a]x J_rot
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
            r[:], J[:] = c.rows(s.kinematics())

        return generic, k, True

    def rows(self) -> tuple[np.ndarray, np.ndarray]:
        """Scaled residual (k,) and Jacobian (k, nv) on the posture in ``solver.data``."""
        for it in self.items:
            it.fn(self.r[it.start:it.stop], self.J[it.start:it.stop])
        return self.r * self.inv, self.J * self.inv[:, None]

    def report(self, q: np.ndarray) -> tuple[tuple[Residual, ...], float]:
        """Per-constraint residuals in their units and the deepest penetration [m] (outside
        the allowed contact pairs) of posture ``q``."""
        m, d = self.m, self.d
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        out = []
        for c, it in zip(self.cons, self.items):
            it.fn(self.r[it.start:it.stop], self.J[it.start:it.stop])
            r = self.r[it.start:it.stop]
            if it.scaled:
                value = c.residual(self.s.kinematics())
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
