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

This module keeps the solving strategy (starts, attempts, restarts, settling the best); the
parts are in :mod:`azee_mj.posture` (records, the compiled plan and its contract with the C
core, collision pairs, equalities, restart points).
Infeasible problems are not errors: the solver returns its best posture, ``converged=False``
and every constraint's residual.

Units: metres, radians, seconds.
"""

from __future__ import annotations

import dataclasses
import functools
import time
from collections.abc import Callable, Iterable, Mapping

import mujoco
import numpy as np

from azee_mj.constraints import PENETRATION_LIMIT, Constraint, Place
from azee_mj.contact import head_on, widened
from azee_mj.kinematics import Kinematics, Names
from azee_mj.natural import Effort, Naturalness, rows
from azee_mj.posture import equalities, starts
from azee_mj.posture.collision import collision_pairs, geom_clusters, moving_pairs
from azee_mj.posture.contract import (
    FAR_COST,
    FAR_GAIN,
    MAX_STEP,
    MET_GAIN,
    MU0,
    NATURAL_ITER,
    NATURAL_STEP,
    NULL_TOL,
)
from azee_mj.posture.equalities import add_target_pool
from azee_mj.posture.plan import Plan
from azee_mj.posture.problem import Attempt, IKProblem, IKResult, LMRun, Residual, Stop
from azee_mj.posture.scope import Scope

__all__ = [
    "FAR_COST",
    "FAR_GAIN",
    "MAX_STEP",
    "MET_GAIN",
    "MU0",
    "NATURAL_ITER",
    "NATURAL_STEP",
    "NULL_TOL",
    "POSTURE",
    "IKProblem",
    "IKResult",
    "Plan",
    "Residual",
    "Solver",
    "Stop",
    "add_target_pool",
]

#: Weight of the guide toward the preferred posture while the constraints are being
#: reached (per radian; a constraint row is 1 at its tolerance).
POSTURE = 0.3
#: The most a meet from a start over the whole joint ranges may break the problem's
#: preferences (their sum of squares, 1 = one row at its tolerance) to be kept.
WIDE_PREFERENCE = 1.0


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
        self.scope = Scope(m, self.names)
        #: (n, 2) every geom pair ``mj_collision`` tests, in its order
        self.all_pairs = collision_pairs(m)
        self.at(self.natural)
        #: (ngeom,) each colliding geom's cluster (see :func:`~azee_mj.posture.collision.geom_clusters`)
        self.clusters = geom_clusters(m, self.data.geom_xpos, self.data.xpos)
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
        return self.scope.joint_info(name)

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
        return self.scope.bodies_of(c)

    def free_dofs(self, problem: IKProblem) -> np.ndarray:
        """Dof indices the solver moves for ``problem`` (sorted)."""
        return self.scope.free_dofs(problem)

    def joined_bodies(self, problem: IKProblem) -> set[tuple[int, int]]:
        """Body pairs a site-to-site placement brings together (allowed to touch)."""
        return self.scope.joined_bodies(problem)

    def collision_pairs(self, free: np.ndarray) -> np.ndarray:
        """(n, 2) geom pairs whose distance the dofs ``free`` can change: those
        ``mj_collision`` tests, without the pairs joined by no free dof (within a hand whose
        shape is fixed, within the unmoved rest of the body); in ``mj_collision``'s order,
        each pair's geoms in the type order of its narrowphase function."""
        key = free.tobytes()
        if key not in self._pairs:
            self._pairs[key] = moving_pairs(self.model, self.all_pairs, free)
        return self._pairs[key]

    def plan(self, problem: IKProblem) -> Plan:
        """The problem compiled for this solver (rows, buffers, free dofs)."""
        return Plan(self, problem)

    def configure_equalities(self, problem: IKProblem, data: mujoco.MjData | None = None) -> int:
        """Mirror the problem's placements as MuJoCo ``connect`` equalities.

        A placement at a fixed point uses a mocap target; a site-to-site contact connects
        the two sites directly. Returns how many equalities are active; placements with a
        posture-dependent target other than a bare site are left to the solver's own rows.
        """
        d = data if data is not None else self.data
        return equalities.configure(self.model, d, self.names, self.n_targets, problem)

    # -- solve --------------------------------------------------------------------------
    def solve(self, problem: IKProblem, q0: np.ndarray | None = None) -> IKResult:
        """Solve ``problem`` warm-started from ``q0`` (nq,) (default: the natural posture).

        Strict priorities: the constraints, then no penetration, then (with a
        ``naturalness``) the most natural posture among those that meet both.
        Never raises for geometry: an infeasible problem returns the best posture found
        with ``converged=False``. Fingertips that may touch with any point of their round
        end are tried head-on first (:func:`head_on_first`).
        """
        solve_once = self._solve_once
        if _wide_allowed(self, problem):
            solve_once = functools.partial(self._solve_once, wide=True)
        result = head_on_first(solve_once, problem, q0, self.preference_cost)
        if self.on_solve is not None:
            self.on_solve(problem, result)
        return result

    def preference_cost(self, problem: IKProblem, q: np.ndarray) -> float:
        """The sum of squares of ``problem``'s preference rows (each 1 at its tolerance) on
        posture ``q`` (nq,)."""
        if not problem.preferences:
            return 0.0
        k = self.at(q, jacobians=True)
        return float(sum(np.sum(c.rows(k)[0] ** 2) for c in problem.preferences))

    def _solve_once(
        self, problem: IKProblem, q0, wide: bool = False
    ) -> tuple[IKResult, tuple[int, float]]:
        """:meth:`solve` as posed, and the kept attempt's rank (see :class:`Attempt`);
        ``wide``: from starts with the limbs anywhere in their ranges only (see
        :func:`_wide_allowed`)."""
        t0 = time.perf_counter()
        q_start = np.clip(
            self.natural if q0 is None else np.asarray(q0, float), self.lower, self.upper
        )
        plan = self.plan(problem)
        q_start = _narrow(plan, problem, q_start, self.upper)
        history: list[float] = []
        if wide:
            best, iters, attempt = _wide_attempts(self, plan, problem, q_start, history)
        else:
            # Every seed and the warm start, then restarts (inside the max_change box) until
            # one meets everything; the best attempt by one cost is kept.
            best, iters = self._first_attempts(plan, problem, q_start, history)
            best, n_it, attempt = self._restarts(best, plan, problem, q_start, history)
            iters += n_it
        restarts = self.restarts if problem.restarts is None else problem.restarts
        if best.rank[0] and restarts >= 2 and not wide:
            # Nothing met everything: converge the best attempt fully (no early stop),
            # so that an infeasible problem gets its least residual (a per-frame solve,
            # with fewer restarts, keeps its step).
            run = self._settle(self._lm(best.q, plan, history, early=False), plan, history)
            iters += run.iterations
            if run.rank < best.rank:
                best = run
        residuals, depth = plan.report(best.q)
        hard = [r for r, c in zip(residuals, problem.constraints) if not c.soft]
        result = IKResult(
            qpos=best.q,
            converged=all(r.ok for r in hard) and depth <= PENETRATION_LIMIT,
            residuals=residuals,
            penetration=depth,
            iterations=iters,
            restarts=attempt,
            time=time.perf_counter() - t0,
            history=np.asarray(history),
            stop=best.stop,
            polish=best.polish,
        )
        return result, best.rank

    def _first_attempts(self, plan, problem, q_start, history) -> tuple[Attempt, int]:
        """The best attempt from every seed and the warm start (in that order, the first
        of equal ranks), and their iterations."""
        best, iters = None, 0
        for start in [np.clip(q, plan.lower, plan.upper) for q in problem.seeds] + [q_start]:
            run = self._attempt(start, plan, history)
            iters += run.iterations
            if best is None or run.rank < best.rank:
                best = run
            if best.rank == (0, 0.0):
                break  # met, and nothing is more natural: no later start can be better
        return best, iters

    def _restarts(self, best, plan, problem, q_start, history) -> tuple[Attempt, int, int]:
        """Restarts while nothing meets everything: (best attempt, iterations, restarts)."""
        restarts = self.restarts if problem.restarts is None else problem.restarts
        points = _restart_points(self, problem, q_start, plan.free, restarts)
        iters = attempt = 0
        # the next start is drawn only when needed: the seeder's starts cost a search each
        while best.rank[0] and (nxt := next(points, None)) is not None:
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
        return best, iters, attempt

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
        """The attempt an LM run ends: unmet as it is, met and then polished to the most
        natural posture that keeps the constraints (see :meth:`Plan.polish`)."""
        if not run.met:
            return Attempt(run.q, (1, run.cost), run.iterations, run.stop)
        if not plan.natural or self.naturalness is None:
            return Attempt(run.q, (0, 0.0), run.iterations, run.stop)
        q, nat, n_it, polish = plan.polish(run.q, history)
        return Attempt(q, (0, nat), run.iterations + n_it, run.stop, polish)

    def _lm(self, q, plan, history, posture=0.0, stop=0.05, early=True) -> LMRun:
        """One Levenberg-Marquardt run (see :meth:`Plan.lm`) with this solver's joint
        weights and iteration budget."""
        return plan.lm(q, self.dof_weight, self.max_iter, history, posture, stop, early)


def head_on_first(solve_once, problem: IKProblem, q0, preference_cost=None) -> IKResult:
    """Solve ``problem`` with ``solve_once`` (problem, start -> (result, rank)); when it
    places a round end (:func:`~azee_mj.contact.head_on`) and may restart, also with the
    ends meeting head-on only, keeping the better: a meet before a miss, then the more
    natural (a fingertip that can touch head-on, the temple, the brow, comes at it as
    before and does not take another arm branch for the freedom its roundness gives),
    and of two misses the rolled one (its residual is the contact's own) unless it breaks
    the problem's preferences (``preference_cost(problem, q)``, a unit a row at its
    tolerance) more than twice as much as the head-on one and by over a unit: a miss
    keeps the posture natural."""
    plain = head_on(problem.constraints)
    if plain is None:
        return solve_once(problem, q0)[0]
    rolled = dataclasses.replace(problem, constraints=widened(problem.constraints))
    if problem.restarts is not None and problem.restarts < 2:
        return solve_once(rolled, q0)[0]  # a frame or a step: on the branch it starts on
    a, rank_a = solve_once(dataclasses.replace(problem, constraints=plain), q0)
    b, rank_b = solve_once(rolled, q0)
    kept = a if rank_a[0] == 0 and (rank_b[0] != 0 or rank_a[1] <= rank_b[1]) else b
    if rank_a[0] and rank_b[0] and preference_cost is not None:
        pa, pb = preference_cost(problem, a.qpos), preference_cost(problem, b.qpos)
        if pb > max(2.0 * pa, pa + 1.0):
            kept = a  # of two misses, the one that keeps the posture natural
    return dataclasses.replace(kept, iterations=a.iterations + b.iterations, time=a.time + b.time)


def natural_cost(solver: Solver, problem: IKProblem, q: np.ndarray) -> float:
    """What the solver minimises among the postures that meet ``problem``, on posture ``q``
    (nq,): the sum of squares of the effort rows, the comfort rows of the problem's free
    dofs and its preference rows (0 without a naturalness). Two postures that meet one
    problem compare by it (lower: more natural)."""
    if solver.naturalness is None:
        return 0.0
    solver.at(q, jacobians=True)
    r, _ = rows(solver.naturalness, solver.effort, solver.data, solver.free_dofs(problem))
    return float(r @ r) + solver.preference_cost(problem, q)


def _wide_allowed(solver: Solver, problem: IKProblem) -> bool:
    """Whether ``problem`` is solved from starts with the limbs anywhere in their ranges
    (``problem.wide``, a key posture's last resort: a hand behind the head or on the nape
    lies in a basin that neither the natural posture nor the arm seeds reach); only for
    a problem that may restart and collides."""
    restarts = solver.restarts if problem.restarts is None else problem.restarts
    return problem.wide and restarts >= 2 and problem.collide


def _wide_attempts(solver: Solver, plan, problem, q_start, history) -> tuple[Attempt, int, int]:
    """(the best attempt, iterations, 0) from :func:`~azee_mj.posture.starts.wide_starts`
    over the free limb joints (weight 1: the dear ones, the spine and the clavicles, stay
    at the start); only a meet that keeps the problem's preferences within
    :data:`WIDE_PREFERENCE` counts. None when a placement's target moves with those
    joints (the other hand): drawn with the placed hand, it would not hold still."""
    best = Attempt(q_start, (1, np.inf), 0, None)
    limbs = plan.free[solver.dof_weight[plan.free] <= 1.0]
    k = solver.at(q_start, jacobians=True)
    for c in problem.constraints:
        jac = k.eval(c.target)[1] if isinstance(c, Place) else None
        if jac is not None and np.abs(jac[:, limbs]).max(initial=0.0) > 0.0:
            return best, 0, 0
    points = starts.wide_starts(plan.lower, plan.upper, solver.seed, q_start, limbs)
    best, iters = starts.wide_search(
        lambda q: solver._attempt(q, plan, history),
        best,
        points,
        lambda q: solver.preference_cost(problem, q) <= WIDE_PREFERENCE,
    )
    return best, iters, 0


def _restart_points(solver: Solver, problem: IKProblem, q_start, free, restarts):
    """(start, from the seeder) of the restarts (see
    :func:`~azee_mj.posture.starts.restart_points`): the seeder is asked only when the
    problem has no ``seeds`` of its own (the realizer's have their starts chosen)."""
    seeder = None
    if solver.seeder is not None and not problem.seeds:
        seeder = lambda: solver.seeder(solver, problem, q_start)
    generic = starts.generic_starts(
        solver.natural, solver.lower, solver.upper, solver.seed, q_start, free
    )
    return starts.restart_points(q_start, restarts, seeder, generic)


def _narrow(plan: Plan, problem: IKProblem, q_start: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Narrow the plan's bounds by the problem's ``max_change`` and ``bounds``, and the start
    into them (``upper``: the joints' own upper limits)."""
    if problem.max_change is not None:
        plan.lower = np.maximum(plan.lower, q_start - problem.max_change)
        plan.upper = np.minimum(plan.upper, q_start + problem.max_change)
    if problem.bounds is not None:
        plan.lower = np.maximum(plan.lower, problem.bounds[0])
        plan.upper = np.maximum(plan.lower, np.minimum(plan.upper, problem.bounds[1]))
        # a bound that pins a joint: the least width the box QP takes, inside the range
        pinned = plan.upper - plan.lower < 1e-9
        up = pinned & (plan.upper + 1e-9 <= upper)
        plan.upper[up] = plan.lower[up] + 1e-9
        plan.lower[pinned & ~up] = plan.upper[pinned & ~up] - 1e-9
    if problem.max_change is not None or problem.bounds is not None:
        q_start = np.clip(q_start, plan.lower, plan.upper)
    return q_start
