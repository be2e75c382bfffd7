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
import itertools
import math
import time
from collections.abc import Callable, Iterable, Mapping

import mujoco
import numpy as np

from azee_mj import native
from azee_mj.constraints import (
    COLLISION_TOL,
    CONTACT_ALLOWANCE,
    PENETRATION_LIMIT,
    Constraint,
    JointTarget,
    Look,
    Orient,
    Place,
    Rel,
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
)
from azee_mj.natural import Effort, Naturalness


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
      restarts: further generic attempts when none meets everything (None: the solver's
        own); from 2 up, the solver's ``seeder`` adds its starts to them.
      bounds: (lower, upper), each (nq,): further bounds of the joints inside their ranges
        [rad or m] (e.g. within reach of a later posture), None = none.
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
    bounds: tuple[np.ndarray, np.ndarray] | None = dataclasses.field(default=None, compare=False)


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
#: Once every constraint is within its tolerance, an LM step that lowers the cost by less
#: than this fraction ends the run: a limit or a contact holds a row short of the 5 % stop,
#: and the polish starts from there (compiled; the core's ``MET_GAIN``).
MET_GAIN = 0.25
#: Far from the tolerances (cost over ``FAR_COST``, rows scaled to 1 at their tolerance) a
#: step gaining less than ``FAR_GAIN`` counts as a stall: a local minimum that crawls is left
#: for the next start (compiled; the best unmet attempt is then converged without it).
FAR_COST = 4.0
FAR_GAIN = 1e-2
#: Weight of the guide toward the preferred posture while the constraints are being
#: reached (per radian; a constraint row is 1 at its tolerance).
POSTURE = 0.3
#: Directions in which the constraint rows change by less than this fraction of their
#: scale (root of the trace of A^T A) count as the constraints' null space.
NULL_TOL = 1e-4
#: Most natural-posture steps once the constraints are met.
NATURAL_ITER = 30
#: First trust radius of a natural-posture step [rad].
NATURAL_STEP = 0.2
#: Restarts from the seeder's starts between two generic (natural, random) ones.
SEEDS_PER_GENERIC = 4


class Solver:
    """Solves :class:`IKProblem` s on one model.

    The solver compiles its own copy of the model with ``n_targets`` mocap targets and as
    many inactive ``connect`` equalities (see :meth:`configure_equalities`), without the
    geoms that only show (MuJoCo's ``discardvisual``: no contact, no mass).

    Args:
      model: an MJCF path or an ``MjSpec`` (copied).
      joint_weights: joint name -> how dear moving it is in the damping and the natural-posture
        preference (default 1; names the model lacks are ignored).
      max_iter: LM iterations per attempt.
      restarts: further generic attempts from other starts when an attempt does not
        converge (the ``seeder``'s starts come on top, from 2 up).
      margin: collision margin [m] for detecting near contacts in the reports and the
        diagnosis (the solve itself needs the penetrations only).
      on_solve: called with each problem and its result, in solving order (an observer).
      naturalness: what makes a posture natural (:mod:`azee_mj.natural`); among the
        postures that meet the constraints without penetration the solver takes the most
        natural one. None = the first it reaches.
      seeder: ``seeder(solver, problem, q_start)`` gives further starts (nq,) for the
        restarts of a problem without ``seeds`` of its own, tried after the first (e.g. the
        arms on other elbow-swivel branches); an iterator is drawn only as far as needed.
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
        seeder: Callable[[Solver, IKProblem, np.ndarray], Iterable[np.ndarray]] | None = None,
    ):
        if isinstance(model, mujoco.MjSpec):
            spec = model.copy()
        else:
            spec = mujoco.MjSpec.from_file(str(model))
        add_target_pool(spec, n_targets)
        spec.compiler.discardvisual = True  # geoms that only show: kinematics skips them
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
        self.seeder = seeder
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
        self._joint_info: dict[str, tuple[int, int, bool]] = {}
        self._all_pairs = _collision_pairs(m)
        self._clusters = _geom_clusters(m, self.data, self.natural)
        self._pairs: dict[bytes, np.ndarray] = {}
        self.set_naturalness(naturalness)

    def set_naturalness(self, naturalness: Naturalness | None) -> None:
        """Prefer the most natural posture by ``naturalness`` (None: the first reached)."""
        self.naturalness = naturalness
        self.effort_dofs = (
            np.flatnonzero(naturalness.strength > 0)
            if naturalness is not None
            else np.zeros(0, int)
        )
        self.effort = Effort(self.model, self.effort_dofs)
        edof = self.effort.dofs
        #: The compiled core's naturalness arguments (see ``Plan``): effort dofs, their
        #: scales, comfort weights, neutral posture and the dofs' ancestry.
        self.natural_terms = (
            None
            if naturalness is None
            else (
                edof.astype(np.int32),
                np.sqrt(naturalness.effort_weight) / naturalness.strength[edof],
                np.ascontiguousarray(naturalness.comfort, float),
                np.ascontiguousarray(naturalness.neutral, float),
                self.effort.anc_u8,
            )
        )

    # -- names ------------------------------------------------------------------------
    def site_id(self, name: str) -> int:
        return self.names.site(name)

    def body_id(self, name: str) -> int:
        return self.names.body(name)

    def joint_id(self, name: str) -> int:
        return self.names.joint(name)

    def joint_info(self, name: str) -> tuple[int, int, bool]:
        """(qpos address, dof address, is a slide joint) of joint ``name`` (looked up once)."""
        info = self._joint_info.get(name)
        if info is None:
            j = self.joint_id(name)
            m = self.model
            info = (
                int(m.jnt_qposadr[j]),
                int(m.jnt_dofadr[j]),
                bool(m.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE),
            )
            self._joint_info[name] = info
        return info

    def kinematics(self) -> Kinematics:
        """A :class:`~azee_mj.kinematics.Kinematics` on the posture in ``self.data``."""
        return Kinematics(self.model, self.data, self.names)

    def at(self, q: np.ndarray, jacobians: bool = False) -> Kinematics:
        """Set posture ``q`` (nq,) [rad] and run the kinematics (and ``mj_comPos`` when
        ``jacobians``): the one place outside the core that writes the solver's ``MjData``.
        Returns the evaluator on that posture; it is valid until the next call."""
        self.data.qpos[:] = q
        mujoco.mj_kinematics(self.model, self.data)
        if jacobians:
            mujoco.mj_comPos(self.model, self.data)
        return self.kinematics()

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

    def collision_pairs(self, free: np.ndarray) -> np.ndarray:
        """(n, 2) geom pairs whose distance the dofs ``free`` can change: those
        ``mj_collision`` tests, without the pairs joined by no free dof (within a hand whose
        shape is fixed, within the unmoved rest of the body); in ``mj_collision``'s order,
        each pair's geoms in the type order of its narrowphase function."""
        key = free.tobytes()
        if key not in self._pairs:
            m = self.model
            moving = np.zeros(m.nbody, bool)
            moving[m.dof_bodyid[free]] = True
            group = np.arange(m.nbody)  # rigid group: the body's moving ancestor, or itself
            for b in range(1, m.nbody):  # parents come before children
                if not moving[b]:
                    group[b] = group[m.body_parentid[b]]
            bodies = m.geom_bodyid[self._all_pairs]
            keep = group[bodies[:, 0]] != group[bodies[:, 1]]
            self._pairs[key] = np.ascontiguousarray(self._all_pairs[keep])
        return self._pairs[key]

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

    # -- solve --------------------------------------------------------------------------
    def solve(self, problem: IKProblem, q0: np.ndarray | None = None) -> IKResult:
        """Solve ``problem`` warm-started from ``q0`` (nq,) (default: the natural posture).

        Strict priorities: the constraints, then no penetration, then (with a
        ``naturalness``) the most natural posture among those that meet both.
        Never raises for geometry: an infeasible problem returns the best posture found
        with ``converged=False``.
        """
        t0 = time.perf_counter()
        q_start = np.clip(
            self.natural if q0 is None else np.asarray(q0, float), self.lower, self.upper
        )
        cons = problem.constraints
        plan = self.plan(problem)
        free = plan.free
        history: list[float] = []
        if problem.max_change is not None:
            plan.lower = np.maximum(plan.lower, q_start - problem.max_change)
            plan.upper = np.minimum(plan.upper, q_start + problem.max_change)
        if problem.bounds is not None:
            plan.lower = np.maximum(plan.lower, problem.bounds[0])
            plan.upper = np.maximum(plan.lower, np.minimum(plan.upper, problem.bounds[1]))
            # a bound that pins a joint: the least width the box QP takes, inside the range
            pinned = plan.upper - plan.lower < 1e-9
            up = pinned & (plan.upper + 1e-9 <= self.upper)
            plan.upper[up] = plan.lower[up] + 1e-9
            plan.lower[pinned & ~up] = plan.upper[pinned & ~up] - 1e-9
        if problem.max_change is not None or problem.bounds is not None:
            q_start = np.clip(q_start, plan.lower, plan.upper)
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
        starts = self._restart_points(problem, q_start, free, restarts)
        # the next start is drawn only when needed: the seeder's starts cost a search each
        while best.rank[0] and (nxt := next(starts, None)) is not None:
            start, seeded = nxt
            attempt += 1
            start = np.clip(start, plan.lower, plan.upper)
            # the first restart and the seeder's starts begin with collisions off
            run = self._attempt(start, plan, history, transparent_first=attempt == 1 or seeded)
            iters += run.iterations
            # A seeder's start counts only if it meets everything: an infeasible problem
            # keeps its best posture from the generic starts, not a far branch.
            if run.rank < best.rank and not (seeded and run.rank[0]):
                best = run
        if best.rank[0] and restarts >= 2:
            # Nothing met everything: converge the best attempt fully (no early stop),
            # so that an infeasible problem gets its least residual (a per-frame solve,
            # with fewer restarts, keeps its step).
            run = self._settle(self._lm(best.q, plan, history, early=False), plan, history)
            iters += run.iterations
            if run.rank < best.rank:
                best = run
        q = best.q
        residuals, depth = plan.report(q)
        hard = [r for r, c in zip(residuals, cons) if not c.soft]
        converged = all(r.ok for r in hard) and depth <= PENETRATION_LIMIT
        result = IKResult(
            qpos=q,
            converged=converged,
            residuals=residuals,
            penetration=depth,
            iterations=iters,
            restarts=attempt,
            time=time.perf_counter() - t0,
            history=np.asarray(history),
        )
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
        out = self._settle(run, plan, history)
        return dataclasses.replace(out, iterations=out.iterations + iters - run.iterations)

    def _settle(self, run: LMRun, plan, history) -> Attempt:
        """The attempt an LM run ends: unmet as it is, met and then polished."""
        if not run.met:
            return Attempt(run.q, (1, run.cost), run.iterations)
        if not plan.natural:
            return Attempt(run.q, (0, 0.0), run.iterations)
        q, nat, n_it = self._polish(run.q, plan, history)
        return Attempt(q, (0, nat), run.iterations + n_it)

    def _polish(self, q, plan, history, stop=0.05) -> tuple[np.ndarray, float, int]:
        """The most natural posture among those that meet the constraints, from ``q`` that
        meets them: Gauss-Newton steps on the naturalness rows in the null space of the
        constraint and collision rows (and of the joints at a limit the step would cross),
        each followed by steps back onto the constraints. A step is kept only if every
        constraint stays within ``stop`` of its tolerance and no contact goes deeper, so
        naturalness never bends a constraint. Returns (q, natural cost, iterations).

        Compiled code (``azee_mj._ikcore``): each step minimises the naturalness model
        plus ``|A s|^2 / (NULL_TOL^2 trace(A^T A))`` times its mean curvature (``A`` the
        constraint and collision rows), one Cholesky factorisation: directions of ``A``
        with a singular value over ``NULL_TOL`` of the rows' scale are held still, the rest
        is the null space; a trust radius from ``NATURAL_STEP``
        doubling on success up to ``MAX_STEP`` and quartered on failure, at most
        ``NATURAL_ITER`` steps; two stalls end it (steps that gain under 0.1 %, or no step
        down to a milliradian that gains)."""
        free = plan.free
        mov = np.flatnonzero(~plan.pinned)  # a joint target (a hand shape) pins its joint
        if self.naturalness is None or not mov.size:
            return q, 0.0, 0
        q_out, nat, it, hist = plan.core.polish(
            np.ascontiguousarray(q, float),
            plan.lower[free],
            plan.upper[free],
            mov.astype(np.int32),
            float(stop),
            plan.collide,
            NATURAL_ITER,
            NATURAL_STEP,
            NULL_TOL,
            MAX_STEP,
        )
        history.extend(hist)
        return np.frombuffer(q_out).copy(), nat, it

    def _restart_points(self, problem, q_start, free, restarts):
        """(start, from the seeder) of the restarts, in order: the start again (with
        self-collision off at first); then, from two restarts up, ``restarts - 1`` generic
        starts with every start of the ``seeder`` (other arm branches; asked for only now,
        and only when the problem has no ``seeds`` of its own) between them, a generic one
        after every ``SEEDS_PER_GENERIC`` seeds. The generic starts are the natural posture,
        then random postures halfway between it and a uniform sample of the joint ranges."""
        if restarts < 1:
            return
        yield q_start.copy(), False
        if restarts < 2:
            return
        # A problem with seeds of its own (the realizer's) has its starts chosen already.
        ask = self.seeder is not None and not problem.seeds
        seeds = self.seeder(self, problem, q_start) if ask else ()
        generic = (
            (q, False) for q in itertools.islice(self._generic_starts(q_start, free), restarts - 1)
        )
        for k, q in enumerate(seeds, 1):
            yield q, True
            if k % SEEDS_PER_GENERIC == 0:
                yield from itertools.islice(generic, 1)
        yield from generic

    def _generic_starts(self, q_start, free):
        """The natural posture (unless it is the start), then random postures (endless)."""
        untouched = np.setdiff1d(np.arange(self.model.nv), free)
        attempt = 1
        while True:
            attempt += 1
            q = self.natural.copy()
            if attempt > 2 or np.allclose(q[free], q_start[free]):
                lo = np.maximum(self.lower[free], -np.pi)
                hi = np.minimum(self.upper[free], np.pi)
                # Seeded per attempt: a solve depends only on its problem and start.
                rng = np.random.default_rng((self.seed, attempt))
                q[free] = 0.5 * (q[free] + rng.uniform(lo, hi))
            q[untouched] = q_start[untouched]
            yield np.clip(q, self.lower, self.upper)

    def _lm(self, q, plan, history, posture=0.0, stop=0.05, early=True) -> LMRun:
        """One Levenberg-Marquardt run on the constraint rows plus, if ``posture`` > 0, rows
        ``posture * (q - prefer)`` weighted per dof; ``done`` when every constraint row norm is
        under ``stop`` (its tolerance fraction).

        The run is compiled code (``azee_mj._ikcore``): damping relative to the mean diagonal
        of ``J^T J`` (``MU0``) times the joint weights, steps from ``mju_boxQP`` inside the
        joint ranges and a ``MAX_STEP`` trust region, Nielsen's damping update; it stops when
        done, after three steps of little gain (one with the guide on), or when the damping
        or the step vanish; with ``early`` also once met and slow (``MET_GAIN``) or slow far
        from the tolerances (``FAR_COST``, ``FAR_GAIN``)."""
        free = plan.free
        q_out, cost, done, it, met, hist = plan.core.lm(
            np.ascontiguousarray(q, float),
            plan.lower[free],
            plan.upper[free],
            self.dof_weight[free],
            np.ascontiguousarray(plan.prefer[free], float),
            float(posture),
            float(stop),
            int(self.max_iter),
            plan.collide,
            early,
        )
        history.extend(hist)
        return LMRun(np.frombuffer(q_out).copy(), cost, bool(done), it, bool(met))

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


def _collision_pairs(m: mujoco.MjModel) -> np.ndarray:
    """(n, 2) the geom pairs ``mj_collision`` tests on model ``m`` (contype/conaffinity,
    not welded together, not parent and child unless the parent is the world, not excluded),
    in its order (by body pair, then geom pair), each pair's geoms in the type order of its
    ``mjCOLLISIONFUNC``."""
    geoms = np.flatnonzero((m.geom_contype | m.geom_conaffinity) != 0)
    i, j = np.triu_indices(geoms.size, 1)
    g1, g2 = geoms[i], geoms[j]
    ok = (
        (m.geom_contype[g1] & m.geom_conaffinity[g2])
        | (m.geom_contype[g2] & m.geom_conaffinity[g1])
    ) != 0
    w1, w2 = m.body_weldid[m.geom_bodyid[g1]], m.body_weldid[m.geom_bodyid[g2]]
    ok &= w1 != w2
    if not m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_FILTERPARENT:
        p1, p2 = m.body_weldid[m.body_parentid[w1]], m.body_weldid[m.body_parentid[w2]]
        ok &= ~((w1 != 0) & (w2 != 0) & ((w1 == p2) | (w2 == p1)))
    b1, b2 = m.geom_bodyid[g1], m.geom_bodyid[g2]
    lo, hi = np.minimum(b1, b2), np.maximum(b1, b2)
    ok &= ~np.isin((lo << 16) + hi, m.exclude_signature)
    planar = (mujoco.mjtGeom.mjGEOM_PLANE, mujoco.mjtGeom.mjGEOM_HFIELD)
    ok &= ~(np.isin(m.geom_type[g1], planar) & np.isin(m.geom_type[g2], planar))
    swap = m.geom_type[g1] > m.geom_type[g2]
    a1, a2 = np.where(swap, g2, g1)[ok], np.where(swap, g1, g2)[ok]
    order = np.lexsort((a2, a1, hi[ok], lo[ok]))
    return np.ascontiguousarray(np.stack([a1[order], a2[order]], axis=1), np.int32)


def _geom_clusters(
    m: mujoco.MjModel, d: mujoco.MjData, q: np.ndarray, radius: float = 0.25
) -> np.ndarray:
    """(ngeom,) int32 the cluster of each colliding geom (-1 for the others): the highest
    body whose subtree holds two colliding geoms or more, all within ``radius`` [m] of its
    origin in posture ``q`` (a hand, the head), or the geom alone. The compiled core skips
    the pairs of two clusters whose bounding spheres are apart."""
    d.qpos[:] = q
    mujoco.mj_kinematics(m, d)
    geoms = np.flatnonzero((m.geom_contype | m.geom_conaffinity) != 0)
    members: dict[int, list[int]] = {}
    for g in geoms:
        b = m.geom_bodyid[g]
        while b > 0:
            members.setdefault(b, []).append(g)
            b = m.body_parentid[b]

    small = {}
    for b, gs in members.items():
        reach = np.linalg.norm(d.geom_xpos[gs] - d.xpos[b], axis=1) + m.geom_rbound[gs]
        small[b] = len(gs) >= 2 and bool(np.all(m.geom_rbound[gs] > 0)) and reach.max() <= radius

    out = np.full(m.ngeom, -1, np.int32)
    roots: dict[int, int] = {}
    for g in geoms:
        b, root = m.geom_bodyid[g], None
        while b > 0:
            if small[b]:
                root = b
            b = m.body_parentid[b]
        key = -1 - g if root is None else root
        out[g] = roots.setdefault(key, len(roots))
    return out


def add_target_pool(spec: mujoco.MjSpec, n: int) -> None:
    """Add ``n`` mocap bodies ``ik_target_k`` with a site each, and ``n`` inactive site-based
    ``connect`` equalities ``ik_connect_k`` that :meth:`Solver.configure_equalities` aims."""
    anchor = spec.sites[0].name
    for k in range(n):
        body = spec.worldbody.add_body(name=f"ik_target_{k}", mocap=True)
        body.add_site(name=f"ik_target_{k}", size=[0.006, 0, 0], rgba=[0.1, 0.8, 0.2, 0.6], group=5)
        spec.add_equality(
            name=f"ik_connect_{k}",
            type=mujoco.mjtEq.mjEQ_CONNECT,
            objtype=mujoco.mjtObj.mjOBJ_SITE,
            name1=anchor,
            name2=f"ik_target_{k}",
            active=False,
        )


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


#: Row block kinds of the compiled core (azee_mj/_ikcore.c).
_POINT, _ORIENT, _JOINT, _GENERIC = 0, 1, 2, 3
#: Terms of a point target.
_SITE, _BODY = 0, 1


def _flat_point(e, coef: float = 1.0):
    """``e`` as (constant (3,), [(coef, kind, name)]) if it is a linear combination of
    constants, sites and body origins, else None."""
    if isinstance(e, Const):
        return coef * np.asarray(e.value, float), []
    if isinstance(e, SitePos):
        return np.zeros(3), [(coef, _SITE, e.site)]
    if isinstance(e, BodyOrigin):
        return np.zeros(3), [(coef, _BODY, e.body)]
    if isinstance(e, Lin):
        const, terms = np.zeros(3), []
        for c, t in e.terms:
            f = _flat_point(t, coef * c)
            if f is None:
                return None
            const += f[0]
            terms += f[1]
        return const, terms
    return None


def _axis_target(e):
    """``Unit(e)`` for the core: ("const", unit vector), ("axis", body, unit local, sign) for
    a scaled body axis, or ("point", constant, terms) for a linear combination of constants,
    sites and body origins (see :func:`_flat_point`); None for other forms."""
    if isinstance(e, Lin) and len(e.terms) == 1:
        c, t = e.terms[0]
        f = _axis_target(t)
        if f is not None and c != 0.0 and f[0] == "axis":
            return "axis", f[1], f[2], f[3] * np.sign(c)
    if isinstance(e, BodyAxis):
        n = math.hypot(*e.local)
        return ("axis", e.body, np.asarray(e.local, float) / n, 1.0) if n >= 1e-12 else None
    flat = _flat_point(e)
    if flat is None:
        return None
    const, terms = flat
    if terms:
        return "point", const, terms
    n = math.hypot(*const.tolist())
    return "const", (const / n if n >= 1e-12 else np.zeros(3))


@dataclasses.dataclass(frozen=True)
class RowBlock:
    """One constraint's rows in a plan, ``[start, stop)``; ``scaled`` when they come already
    divided by the tolerance (the general forms, written by the expression evaluator)."""

    start: int
    stop: int
    scaled: bool


class Plan:
    """A problem compiled for one solver: ids resolved, row blocks laid out, buffers made,
    and the compiled core (``azee_mj._ikcore.Core``) that evaluates them and runs the
    iteration.

    The core writes the rows of the common forms itself from ``mj_jacSite`` /
    ``mj_jacBody``: a placement at a linear combination of fixed points, sites and body
    origins; an orientation toward a fixed vector or a body axis (along, opposite,
    perpendicular); a joint target. Other forms (a look, a computed vector) it asks of the
    expression evaluator (:meth:`Constraint.rows`).
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
        self.effort = solver.effort
        self.natural = problem.natural
        self.problem = problem
        self.collide = problem.collide
        self.items: list[RowBlock] = []
        self.prefer = solver.natural if problem.prefer is None else np.asarray(problem.prefer)
        self.cons = problem.constraints
        self.hard: list[tuple[int, int]] = []
        inv: list[float] = []
        ints: list[list[int]] = []
        dbls: list[list[float]] = []
        term_i: list[int] = []
        term_d: list[float] = []
        self.generic: list[tuple[Constraint, int, int]] = []
        hard: list[int] = []
        row = 0
        pinned = set()
        for c in problem.constraints:
            blocks = self._compile(c, term_i, term_d)
            k = sum(x[1] for x in blocks)
            generic = blocks[0][0] == _GENERIC
            if generic:
                self.generic.append((c, row, row + k))
            self.items.append(RowBlock(row, row + k, generic))
            if not c.soft:
                self.hard.append((row, row + k))
                hard += [row, row + k]
            start = row
            for kind, kb, i, x in blocks:
                if kind == _JOINT:
                    pinned.add(i[3])
                ints.append([kind, start, kb, 0 if c.soft else 1, *i])
                dbls.append(x)
                start += kb
            inv += [1.0 if generic else 1.0 / c.tol] * k
            row += k
        self.inv = np.array(inv)
        self.J = np.zeros((row, m.nv))
        self.r = np.zeros(row)
        self.core = native.core().Core(
            m._address,
            self.d._address,
            (m, self.d),
            np.array(ints, np.int32).reshape(-1),
            np.array(dbls, float).reshape(-1),
            np.array(term_i, np.int32),
            np.array(term_d, float),
            self.inv,
            self.free.astype(np.int32),
            np.ascontiguousarray(self.floor),
            self.r,
            self.J,
            self._generic_rows if self.generic else None,
            np.array(hard, np.int32),
            solver.collision_pairs(self.free),
            solver._clusters,
        )
        #: (len(free),) dofs a joint target sets: the natural-posture steps leave them.
        self.pinned = np.array([f in pinned for f in self.free.tolist()], bool)
        nat = solver.naturalness
        if nat is not None:
            prefs = problem.preferences
            k = sum(c.rows(solver.kinematics())[0].size for c in prefs) if prefs else 0
            self.pref_r, self.pref_J = np.zeros(k), np.zeros((k, m.nv))
            self.core.set_natural(
                *solver.natural_terms,
                self.pref_r,
                self.pref_J,
                self._preference_rows if k else None,
            )

    def _preference_rows(self) -> None:
        """The core's callback: the preferences' rows on the posture in ``solver.data``."""
        k, row = self.s.kinematics(), 0
        for c in self.problem.preferences:
            r, J = c.rows(k)
            self.pref_r[row : row + r.size], self.pref_J[row : row + r.size] = r, J
            row += r.size

    def _compile(self, c, term_i: list[int], term_d: list[float]) -> list:
        """The core's blocks [(kind, rows, 6 ints [perp, id, id2, dof, first term, terms],
        11 floats [const 3, local 3, local2 3, value, 0])] of constraint ``c``; appends point
        terms to ``term_i`` (kind, id) / ``term_d`` (coefficient). A general form is one
        ``_GENERIC`` block."""
        s = self.s
        zero = [0.0] * 11

        def terms_of(terms):
            t0 = len(term_d)
            for coef, kind, name in terms:
                term_i.extend([kind, s.site_id(name) if kind == _SITE else s.body_id(name)])
                term_d.append(coef)
            return t0, len(terms)

        def orient(body, local, rel, vector):
            tgt = _axis_target(vector)
            if tgt is None:
                return None
            perp = 1 if rel is Rel.PERP else 0
            sign = -1.0 if rel is Rel.OPP else 1.0
            local = [float(x) for x in local]
            k = 1 if perp else 3
            bid = s.body_id(body)
            if tgt[0] == "const":
                return (_ORIENT, k, [perp, bid, -1, 0, 0, 0], [*(sign * tgt[1]), *local, *zero[:5]])
            if tgt[0] == "axis":
                _, b2, loc2, sgn = tgt
                return (
                    _ORIENT,
                    k,
                    [perp, bid, s.body_id(b2), 0, 0, 0],
                    [0.0, 0.0, 0.0, *local, *loc2, sign * sgn, 0.0],
                )
            _, const, terms = tgt
            return (
                _ORIENT,
                k,
                [perp, bid, -1, 0, *terms_of(terms)],
                [*const, *local, 0.0, 0.0, 0.0, sign, 0.0],
            )

        if isinstance(c, Place):
            flat = _flat_point(c.target)
            if flat is not None:
                const, terms = flat
                return [
                    (
                        _POINT,
                        3,
                        [0, s.site_id(c.site), -1, 0, *terms_of(terms)],
                        [*const, *zero[3:]],
                    )
                ]
        elif isinstance(c, Orient):
            b = orient(c.body, c.local, c.rel, c.vector)
            if b is not None:
                return [b]
        elif isinstance(c, Look):
            n_terms = len(term_d)
            eyes = [
                orient(body, local, Rel.ALONG, Lin(((1.0, c.target), (-1.0, BodyOrigin(body)))))
                for body, local in c.eyes
            ]
            if all(b is not None for b in eyes):
                return eyes
            del term_i[2 * n_terms :], term_d[n_terms:]
        elif isinstance(c, JointTarget):
            qadr, dof, _ = s.joint_info(c.joint)
            return [(_JOINT, 1, [0, qadr, -1, dof, 0, 0], [*zero[:9], float(c.value), 0.0])]
        if isinstance(c, Look):
            k = 3 * len(c.eyes)
        else:
            k = 1 if isinstance(c, Orient) and c.rel is Rel.PERP else 3
        return [(_GENERIC, k, [0, -1, -1, 0, 0, 0], zero)]

    def _generic_rows(self) -> None:
        """The core's callback: rows of the general forms on the posture in ``solver.data``."""
        k = self.s.kinematics()
        for c, a, b in self.generic:
            self.r[a:b], self.J[a:b] = c.rows(k)

    def rows(self) -> tuple[np.ndarray, np.ndarray]:
        """Scaled residual (k,) and Jacobian (k, nv) on the posture in ``solver.data``
        (after ``mj_kinematics`` and ``mj_comPos``)."""
        self.core.rows()
        return self.r * self.inv, self.J * self.inv[:, None]

    def report(self, q: np.ndarray) -> tuple[tuple[Residual, ...], float]:
        """Per-constraint residuals in their units and the deepest penetration [m] (outside
        the allowed contact pairs) of posture ``q``."""
        m, d = self.m, self.d
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        out = []
        self.core.rows()
        for c, it in zip(self.cons, self.items):
            r = self.r[it.start : it.stop]
            if it.scaled:
                value = c.residual(self.s.kinematics())
            elif isinstance(c, Look):  # each eye's rows are a - v: the angle from |a - v|
                eyes = np.sqrt((r.reshape(-1, 3) ** 2).sum(axis=1))
                value = float(2.0 * np.arcsin(np.minimum(1.0, eyes / 2.0)).max())
            elif isinstance(c, Orient):
                if c.rel is Rel.PERP:
                    value = float(np.arcsin(min(1.0, abs(r[0]))))
                else:
                    value = float(2.0 * np.arcsin(min(1.0, np.sqrt(r @ r) / 2.0)))
            else:
                value = float(np.sqrt(r @ r))
            unit = "rad"
            if isinstance(c, Place) or isinstance(c, JointTarget) and self.s.joint_info(c.joint)[2]:
                unit = "m"
            out.append(Residual(c.label, type(c).__name__.lower(), value, c.tol, unit))
        return tuple(out), self.core.deepest(self.s._all_pairs)
