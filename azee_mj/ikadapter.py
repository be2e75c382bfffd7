"""The realizer's one way to the posture solver: an IK problem at a time of the score (the
body pairs its contacts let touch then), solved, and what every solve took kept for the
stats (:class:`SolveLog`, three numbers a solve: not the result, whose residuals and
history would hold memory in proportion to the score's length).

Both passes (key postures and frames) and the trills solve through one :class:`IKAdapter`
on a read-only :class:`~azee_mj.schedule.Schedule`.

Units: seconds, metres, radians.
"""

from __future__ import annotations

import dataclasses
from array import array
from collections.abc import Iterator

import numpy as np

from azee_mj import constraints as cn
from azee_mj import ik
from azee_mj.kinematics import Kinematics
from azee_mj.schedule import Schedule

#: How far a joint held near a posture by :meth:`IKAdapter.soft_targets` may go [rad]
#: before it counts as much as a constraint at its tolerance.
SOFT_TARGET_TOL = 0.3
#: Postures whose penetration depth :meth:`IKAdapter.depth` keeps (about 1 kB each).
DEPTHS_KEPT = 4096


@dataclasses.dataclass(frozen=True)
class Solved:
    """What one solve took: LM ``iterations``, whether it ``converged``, wall ``time`` [s]."""

    iterations: int
    converged: bool
    time: float


class SolveLog:
    """What every solve took, in solving order, as compact columns (17 bytes a solve; a
    :class:`Solved` record each would take about 200, some 20 MB over an hour of score).
    A sequence of :class:`Solved` records; equal to a list of the same records."""

    def __init__(self) -> None:
        self.iterations, self.converged, self.time = array("q"), array("b"), array("d")

    def append(self, s: Solved) -> None:
        self.iterations.append(s.iterations)
        self.converged.append(bool(s.converged))
        self.time.append(s.time)

    def __len__(self) -> int:
        return len(self.time)

    def __getitem__(self, i: int) -> Solved:
        return Solved(int(self.iterations[i]), bool(self.converged[i]), float(self.time[i]))

    def __iter__(self) -> Iterator[Solved]:
        return (self[i] for i in range(len(self)))

    def __eq__(self, other) -> bool:
        return isinstance(other, SolveLog | list) and list(self) == list(other)


class IKAdapter:
    """Solves the realizer's problems on ``schedule``'s solver and keeps what every solve
    took (in solving order) in ``results``."""

    def __init__(self, schedule: Schedule):
        self.schedule = schedule
        self.solver = schedule.solver
        self.results = SolveLog()
        self._dofs: dict[tuple[str, ...], np.ndarray] = {}
        self._depths: dict[tuple[bytes, frozenset], float] = {}  # see depth()
        self._touching: dict[frozenset, tuple[tuple[str, str], ...]] = {}  # see problem()

    def problem(self, cons, free, q0, t: float, seeds=(), **fields) -> ik.IKProblem:
        """The problem of constraints ``cons`` moving joints ``free`` from ``q0`` (nq,)
        (and ``seeds``, other starts) at time ``t`` [s], the body pairs its contacts bring
        together allowed to touch. ``fields`` are the other
        :class:`~azee_mj.ik.IKProblem` fields (``max_change``, ``natural``,
        ``preferences``, ``restarts``, ``bounds``, ``prefer``: ``q0`` unless given)."""
        allowed = self.schedule.allowed_at(t)
        touching = self._touching.get(allowed)
        if touching is None:  # one tuple per set of pairs the contacts allow (their names)
            names = self.schedule.body_names
            touching = tuple((names[a], names[b]) for a, b in allowed if a < b)
            self._touching[allowed] = touching
        fields = {"prefer": q0, **fields}
        if "preferences" in fields:
            fields["preferences"] = tuple(fields["preferences"])
        return ik.IKProblem(tuple(cons), tuple(free), touching, seeds=tuple(seeds), **fields)

    def solve(self, cons, free, q0, t: float, seeds=(), **fields) -> ik.IKResult:
        """Solve :meth:`problem` from ``q0``; what it took is kept in ``results``."""
        res = self.solver.solve(self.problem(cons, free, q0, t, seeds, **fields), q0)
        self.results.append(Solved(res.iterations, res.converged, res.time))
        return res

    def at(self, q: np.ndarray, jacobians: bool = False) -> Kinematics:
        """The solver's kinematics on posture ``q`` (nq,) (see :meth:`~azee_mj.ik.Solver.at`)."""
        return self.solver.at(q, jacobians)

    def penetrates(self, q: np.ndarray, t: float) -> bool:
        """Whether posture ``q`` penetrates deeper than ``COLLISION_TOL`` (0.1 mm, where a
        collision row reaches 1; a solve converges within the looser
        ``PENETRATION_LIMIT``), but for the body pairs the contacts of time ``t`` [s]
        bring together."""
        return self.depth(q, self.schedule.allowed_at(t)) > cn.COLLISION_TOL

    def depth(self, q: np.ndarray, allowed=frozenset(), posed: bool = True) -> float:
        """Deepest penetration [m] (>= 0) of posture ``q`` (nq,) but for the body pairs
        ``allowed`` (:func:`~azee_mj.constraints.penetration_depth`, its kinematics run
        once); the solver's data holds that posture's kinematics afterwards (unless not
        ``posed``, when a depth already known costs no kinematics: a caller that reads only
        the depth). Each depth is kept (:data:`DEPTHS_KEPT` at most): a detour measures the
        same frames as it bends a blend, and the frame solver and the pacing measure many
        of them again."""
        key = (q.tobytes(), allowed)
        out = self._depths.get(key)
        if out is not None:
            if posed:
                self.solver.at(q)
            return out
        k = self.solver.at(q)
        if len(self._depths) >= DEPTHS_KEPT:
            self._depths.clear()
        out = self._depths[key] = cn.contact_depth(k.m, k.d, allowed)
        return out

    def depths(self, qs: np.ndarray, allowed, split) -> np.ndarray:
        """(n,) :meth:`depth` of each posture of ``qs`` (n, nq), not ``posed``, knowing
        ``split``: ``(pairs, rest)``, the geom pairs whose depth the postures may change and
        the deepest penetration [m] of all the others (outside ``allowed``); only those
        pairs are measured, to the same depth, the postures not measured before in one
        call of the compiled core (a detour measures every frame of a blend at each bend).
        The solver's data holds no particular posture afterwards."""
        keys = [(q.tobytes(), allowed) for q in qs]
        out = np.array([self._depths.get(key, np.nan) for key in keys])
        todo = np.flatnonzero(np.isnan(out))
        if todo.size:
            m, d = self.solver.model, self.solver.data
            got = np.maximum(cn.run_pairs_depth(m, d, qs[todo], split[0], allowed), split[1])
            if len(self._depths) + todo.size > DEPTHS_KEPT:
                self._depths.clear()
            for i, value in zip(todo.tolist(), got.tolist()):
                self._depths[keys[i]] = out[i] = value
        return out

    def dofs(self, joints) -> np.ndarray:
        """Dof indices of joint names (in their order; looked up once per sequence)."""
        key = tuple(joints)
        out = self._dofs.get(key)
        if out is None:
            m = self.solver.model
            out = np.array([m.jnt_dofadr[self.solver.joint_id(j)] for j in key], int)
            out.flags.writeable = False
            self._dofs[key] = out
        return out

    def soft_targets(self, q: np.ndarray, joints) -> list[cn.JointTarget]:
        """Soft targets keeping ``joints`` near posture ``q`` (a blend to follow)."""
        adr = self.solver.model.jnt_qposadr
        return [
            cn.JointTarget(
                j, float(q[adr[self.solver.joint_id(j)]]), SOFT_TARGET_TOL, "blend", soft=True
            )
            for j in sorted(joints)
        ]
