"""A posture problem compiled for one solver: ids resolved, row blocks laid out as
:data:`~azee_mj.posture.contract.BLOCK` records, buffers made, and the compiled core
(``azee_mj._ikcore.Core``) that evaluates them and runs the iteration.

The core writes the rows of the common forms itself from ``mj_jacSite`` / ``mj_jacBody``: a
placement at a linear combination of fixed points, sites and body origins; an orientation
toward a fixed vector, a body axis (along, opposite, perpendicular) or such a combination; a
look made of such orientations; a joint target. Other forms (a computed vector) it asks of
the expression evaluator (:meth:`Constraint.rows`) through a callback.

Units: metres, radians.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import TYPE_CHECKING

import numpy as np

from azee_mj import native
from azee_mj.constraints import (
    COLLISION_TOL,
    CONTACT_ALLOWANCE,
    Constraint,
    JointTarget,
    Look,
    Orient,
    Place,
    Rel,
    residual_from_rows,
)
from azee_mj.kinematics import BodyAxis, BodyOrigin, Const, Lin, SitePos
from azee_mj.posture import contract
from azee_mj.posture.contract import (
    BLOCK,
    GENERIC,
    HARD_CHORD,
    HARD_LINEAR,
    HARD_RANGE,
    HARD_SINE,
    JOINT,
    ORIENT,
    POINT,
    TERM,
)
from azee_mj.posture.problem import IKProblem, LMRun, Residual, Stop

if TYPE_CHECKING:
    from azee_mj.ik import Solver


def flat_point(e, coef: float = 1.0):
    """``e`` as (constant (3,), [(coef, kind, name)]) if it is a linear combination of
    constants, sites and body origins, else None."""
    if isinstance(e, Const):
        return coef * np.asarray(e.value, float), []
    if isinstance(e, SitePos):
        return np.zeros(3), [(coef, contract.SITE, e.site)]
    if isinstance(e, BodyOrigin):
        return np.zeros(3), [(coef, contract.BODY, e.body)]
    if isinstance(e, Lin):
        const, terms = np.zeros(3), []
        for c, t in e.terms:
            f = flat_point(t, coef * c)
            if f is None:
                return None
            const += f[0]
            terms += f[1]
        return const, terms
    return None


def axis_target(e):
    """``Unit(e)`` for the core: ("const", unit vector), ("axis", body, unit local, sign) for
    a scaled body axis, or ("point", constant, terms) for a linear combination of constants,
    sites and body origins (see :func:`flat_point`); None for other forms."""
    if isinstance(e, Lin) and len(e.terms) == 1:
        c, t = e.terms[0]
        f = axis_target(t)
        if f is not None and c != 0.0 and f[0] == "axis":
            return "axis", f[1], f[2], f[3] * np.sign(c)
    if isinstance(e, BodyAxis):
        n = math.hypot(*e.local)
        return ("axis", e.body, np.asarray(e.local, float) / n, 1.0) if n >= 1e-12 else None
    flat = flat_point(e)
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


def _block(kind: int, k: int, **fields) -> dict:
    """One block's fields (the others zero; ``id2`` -1), without its start and hardness."""
    return {"kind": kind, "k": k, "id2": -1, **fields}


class BlockCompiler:
    """Turns constraints into :data:`BLOCK` field dicts and :data:`TERM` records, resolving
    names on one solver."""

    def __init__(self, solver: Solver):
        self.s = solver
        self.terms: list[tuple[int, int, float]] = []

    def _terms(self, terms) -> dict:
        t0 = len(self.terms)
        for coef, kind, name in terms:
            i = self.s.site_id(name) if kind == contract.SITE else self.s.body_id(name)
            self.terms.append((kind, i, coef))
        return {"t0": t0, "nt": len(terms)}

    def _orient(self, body, local, rel, vector) -> dict | None:
        tgt = axis_target(vector)
        if tgt is None:
            return None
        perp = 1 if rel is Rel.PERP else 0
        sign = -1.0 if rel is Rel.OPP else 1.0
        common = {"perp": perp, "id": self.s.body_id(body), "local": [float(x) for x in local]}
        k = 1 if perp else 3
        if tgt[0] == "const":
            return _block(ORIENT, k, **common, c=sign * tgt[1])
        if tgt[0] == "axis":
            _, b2, loc2, sgn = tgt
            return _block(
                ORIENT, k, **common, id2=self.s.body_id(b2), local2=loc2, value=sign * sgn
            )
        _, const, terms = tgt
        return _block(ORIENT, k, **common, **self._terms(terms), c=const, value=sign)

    def blocks(self, c: Constraint) -> list[dict]:
        """Constraint ``c``'s blocks (a general form is one ``GENERIC`` block)."""
        s = self.s
        if isinstance(c, JointTarget):  # most of a realization's constraints: first
            qadr, dof, _ = s.joint_info(c.joint)
            return [_block(JOINT, 1, id=qadr, dof=dof, value=float(c.value))]
        if isinstance(c, Place):
            flat = flat_point(c.target) if c.shift is None and not c.gap else None
            if flat is not None:
                const, terms = flat
                return [_block(POINT, 3, id=s.site_id(c.site), **self._terms(terms), c=const)]
        elif isinstance(c, Orient):
            b = self._orient(c.body, c.local, c.rel, c.vector)
            if b is not None:
                return [b]
        elif isinstance(c, Look):
            n_terms = len(self.terms)
            eyes = [
                self._orient(
                    body, local, Rel.ALONG, Lin(((1.0, c.target), (-1.0, BodyOrigin(body))))
                )
                for body, local in c.eyes
            ]
            if all(b is not None for b in eyes):
                return eyes
            del self.terms[n_terms:]
        if isinstance(c, Look):
            k = 3 * len(c.eyes)
        else:
            k = 1 if isinstance(c, Orient) and c.rel is Rel.PERP else 3
        return [_block(GENERIC, k)]


@functools.cache
def _zero_row(dtype: np.dtype) -> dict:
    """Each field of ``dtype`` at zero (a tuple for an array field)."""
    return {
        n: (0.0,) * dtype.fields[n][0].shape[0] if dtype.fields[n][0].shape else 0
        for n in dtype.names
    }


def _record(dtype: np.dtype, row: dict) -> tuple:
    """``row`` (field -> value; missing fields zero) as a record tuple of ``dtype``."""
    return tuple({**_zero_row(dtype), **row}.values())


def _joint_record(start: int, hard: int, qadr: int, dof: int, value: float) -> tuple:
    """The BLOCK record of a joint target's row: what :meth:`BlockCompiler.blocks` gives
    for it (``_block(JOINT, 1, id=qadr, dof=dof, value=value)``) at row ``start``."""
    zero3 = (0.0, 0.0, 0.0)
    return (JOINT, start, 1, hard, 0, qadr, -1, dof, 0, 0, zero3, zero3, zero3, value)


@functools.cache
def _one_row(start: int) -> RowBlock:
    """The row block of a one-row constraint (a joint target) at row ``start`` (one shared
    record per row)."""
    return RowBlock(start, start + 1, False)


def _hard_kind(c: Constraint, ranges: bool) -> int:
    """Constraint ``c``'s ``HARD_*`` kind (with ``HARD_RANGE`` for a ranged orientation of
    a problem solved with ``ranges``)."""
    if isinstance(c, Look):
        return HARD_CHORD
    if isinstance(c, Orient):
        kind = HARD_SINE if c.rel is Rel.PERP else HARD_CHORD
        return kind | HARD_RANGE if ranges and c.ranged else kind
    return HARD_LINEAR


#: A joint target's kind and unit (by whether its joint slides) in a Residual.
_JOINT_NAMED = {False: ("jointtarget", "rad"), True: ("jointtarget", "m")}


def _named(solver: Solver, c: Constraint) -> tuple[str, str]:
    """Constraint ``c``'s kind (its class's name in lower case) and unit in a
    :class:`~azee_mj.posture.problem.Residual`: "m" for a placement or a slide joint's
    target, else "rad"."""
    slide = isinstance(c, JointTarget) and solver.joint_info(c.joint)[2]
    return type(c).__name__.lower(), "m" if isinstance(c, Place) or slide else "rad"


class Plan:
    """A problem compiled for one solver (see the module docstring); ``core`` is its compiled
    core, ``items`` each constraint's rows, ``free`` the dofs it moves."""

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
        self.prefer = solver.natural if problem.prefer is None else np.asarray(problem.prefer)
        self.cons = problem.constraints
        blocks, terms = self._layout(solver, problem)
        self.J = np.zeros((self.inv.size, m.nv))
        self.r = np.zeros(self.inv.size)
        self.core = native.core().Core(
            m._address,
            self.d._address,
            (m, self.d),
            blocks,
            terms,
            contract.tunables(),
            self.inv,
            self.free.astype(np.int32),
            np.ascontiguousarray(self.floor),
            self.r,
            self.J,
            self._generic_rows if self.generic else None,
            np.array(self.hard, float).reshape(-1),
            solver.collision_pairs(self.free),
            solver.clusters,
        )
        #: (len(free),) dofs a joint target sets: the natural-posture steps leave them.
        pinned = set(blocks["dof"][blocks["kind"] == JOINT].tolist())
        self.pinned = np.array([f in pinned for f in self.free.tolist()], bool)
        # What every run passes the core unchanged, made once: the preferred posture on the
        # free dofs, and the free dofs the polish moves (a joint target - a hand shape -
        # pins its joint).
        self._prefer_free = np.ascontiguousarray(self.prefer[self.free], float)
        self._mov = np.flatnonzero(~self.pinned).astype(np.int32)
        if solver.naturalness is not None:
            self._set_natural(solver, problem)

    def _layout(self, solver: Solver, problem: IKProblem) -> tuple[np.ndarray, np.ndarray]:
        """The BLOCK and TERM records of the problem; sets ``items``, ``hard`` (row ranges
        of the hard constraints), ``generic``, ``inv`` (1 / tolerance per row) and
        ``_named`` (each constraint's kind and unit, for :meth:`report`). A joint target
        (most of a realization's constraints) is laid out here directly: its one row is
        asked of every problem, many times a frame."""
        compiler = BlockCompiler(solver)
        joint_info = solver.scope.joint_info
        self.items: list[RowBlock] = []
        self.hard: list[tuple[int, int, int, float]] = []
        self.generic: list[tuple[Constraint, int, int]] = []
        self._named: list[tuple[str, str]] = []
        inv: list[float] = []
        rows: list[tuple] = []
        row = 0
        for c in problem.constraints:
            if type(c) is JointTarget:
                qadr, dof, slide = joint_info(c.joint)
                hard = 0 if c.soft else 1
                rows.append(_joint_record(row, hard, qadr, dof, float(c.value)))
                self.items.append(_one_row(row))
                self._named.append(_JOINT_NAMED[slide])
                if hard:
                    self.hard.append((row, row + 1, HARD_LINEAR, c.tol))
                inv.append(1.0 / c.tol)
                row += 1
                continue
            blocks = compiler.blocks(c)
            k = sum(b["k"] for b in blocks)
            generic = blocks[0]["kind"] == GENERIC
            if generic:
                self.generic.append((c, row, row + k))
            self.items.append(RowBlock(row, row + k, generic))
            self._named.append(_named(solver, c))
            if not c.soft:
                self.hard.append((row, row + k, _hard_kind(c, problem.ranges), c.tol))
            start, hard = row, 0 if c.soft else 1
            for b in blocks:
                rows.append(_record(BLOCK, {**b, "start": start, "hard": hard}))
                start += b["k"]
            inv += [1.0 if generic else 1.0 / c.tol] * k
            row += k
        self.inv = np.array(inv)
        terms = [
            _record(TERM, {"kind": kind, "id": i, "coef": coef}) for kind, i, coef in compiler.terms
        ]
        return np.array(rows, BLOCK), np.array(terms, TERM)

    def _set_natural(self, solver: Solver, problem: IKProblem) -> None:
        prefs = problem.preferences
        k = sum(c.rows(solver.kinematics())[0].size for c in prefs) if prefs else 0
        self.pref_r, self.pref_J = np.zeros(k), np.zeros((k, self.m.nv))
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

    def _generic_rows(self) -> None:
        """The core's callback: rows of the general forms on the posture in ``solver.data``."""
        k = self.s.kinematics()
        for c, a, b in self.generic:
            self.r[a:b], self.J[a:b] = c.rows(k)

    def lm(
        self,
        q: np.ndarray,
        weight: np.ndarray,
        max_iter: int,
        history: list[float],
        posture: float = 0.0,
        stop: float = 0.05,
        early: bool = True,
    ) -> LMRun:
        """One Levenberg-Marquardt run on the constraint rows plus, if ``posture`` > 0, rows
        ``posture * (q - prefer)`` weighted per dof by ``weight`` (nv,); ``done`` when every constraint row norm is
        under ``stop`` (its tolerance fraction).

        The run is compiled code (``azee_mj._ikcore``): damping relative to the mean diagonal
        of ``J^T J`` (``MU0``) times the joint weights, steps from ``mju_boxQP`` inside the
        joint ranges and a ``MAX_STEP`` trust region, Nielsen's damping update; it stops when
        done, after three steps of little gain (one with the guide on), or when the damping
        or the step vanish; with ``early`` also once met and slow (``MET_GAIN``) or slow far
        from the tolerances (``FAR_COST``, ``FAR_GAIN``). The run says why it stopped
        (:class:`Stop`)."""
        free = self.free
        q_out, cost, done, it, met, hist, why = self.core.lm(
            np.ascontiguousarray(q, float),
            self.lower[free],
            self.upper[free],
            weight[free],
            self._prefer_free,
            float(posture),
            float(stop),
            int(max_iter),
            self.collide,
            early,
        )
        history.extend(hist)
        return LMRun(np.frombuffer(q_out).copy(), cost, bool(done), it, bool(met), Stop(why))

    def polish(
        self, q, history: list[float], stop=0.05
    ) -> tuple[np.ndarray, float, int, Stop | None]:
        """The most natural posture among those that meet the constraints, from ``q`` that
        meets them: Gauss-Newton steps on the naturalness rows in the null space of the
        constraint and collision rows (and of the joints at a limit the step would cross),
        each followed by steps back onto the constraints. A step is kept only if every
        constraint stays within ``stop`` of its tolerance and no contact goes deeper, so
        naturalness never bends a constraint. Returns (q, natural cost, iterations, why it
        stopped (None: no polish)).

        Compiled code (``azee_mj._ikcore``): each step minimises the naturalness model
        plus ``|A s|^2 / (NULL_TOL^2 trace(A^T A))`` times its mean curvature (``A`` the
        constraint and collision rows), one Cholesky factorisation: directions of ``A``
        with a singular value over ``NULL_TOL`` of the rows' scale are held still, the rest
        is the null space; a trust radius from ``NATURAL_STEP``
        doubling on success up to ``MAX_STEP`` and quartered on failure, at most
        ``NATURAL_ITER`` steps; two stalls end it (steps that gain under 0.1 %, or no step
        down to a milliradian that gains)."""
        free = self.free
        if not self._mov.size:
            return q, 0.0, 0, None
        q_out, nat, it, hist, why = self.core.polish(
            np.ascontiguousarray(q, float),
            self.lower[free],
            self.upper[free],
            self._mov,
            float(stop),
            self.collide,
        )
        history.extend(hist)
        return np.frombuffer(q_out).copy(), nat, it, Stop(why)

    def rows(self) -> tuple[np.ndarray, np.ndarray]:
        """Scaled residual (k,) and Jacobian (k, nv) on the posture in ``solver.data``
        (after ``mj_kinematics`` and ``mj_comPos``)."""
        self.core.rows()
        return self.r * self.inv, self.J * self.inv[:, None]

    def report(self, q: np.ndarray) -> tuple[tuple[Residual, ...], float]:
        """Per-constraint residuals in their units and the deepest penetration [m] (outside
        the allowed contact pairs) of posture ``q``: each from the rows the core wrote
        (:func:`~azee_mj.constraints.residual_from_rows`), the general forms from the
        expression evaluator."""
        k = self.s.at(q, jacobians=True)
        self.core.rows()
        out = []
        r = self.r
        for c, it, (kind, unit) in zip(self.cons, self.items, self._named):
            if it.scaled:
                value = c.residual(k)
            elif kind == "jointtarget":  # most of them: residual_from_rows on one row, inline
                x = float(r[it.start])
                value = math.sqrt(x * x)
            else:
                value = residual_from_rows(c, r[it.start : it.stop])
            out.append(Residual(c.label, kind, value, c.tol, unit))
        return tuple(out), self.core.deepest(self.s.all_pairs)
