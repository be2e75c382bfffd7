"""What a posture must satisfy, as rows for the solver.

Every constraint follows one protocol (:class:`Constraint`): ``rows(k)`` gives residual rows
(m,) and Jacobian rows (m, nv) divided by its tolerance, so ``|row| <= 1`` means "within
tolerance"; ``residual(k)`` its error in its own unit ([m] or [rad]); ``tol`` that tolerance;
``soft`` whether it may stay unmet without blocking convergence. ``k`` is a
:class:`~azee_mj.kinematics.Kinematics` on the posture at hand. Self-collision adds one row
per contact deeper than its body pair may go (``dist - floor``, Jacobian
``n . (J2 - J1)`` at the contact point, from ``mj_collision``); the solver's compiled core
(``azee_mj/_ikcore.c``) computes them.

Where each kind's rows are defined: ``rows`` here is the definition of every kind. The
compiled core writes the same rows in C for the common forms (a placement at a linear
combination of fixed points, sites and body origins; an orientation toward a fixed vector,
a body axis or such a combination; a look; a joint target), held equal to ``rows`` by a
test; for any other form it calls ``rows`` itself. The solver's report reads the core's rows
back through :func:`residual_from_rows` (one definition per kind); ``residual`` gives the
same error from the posture directly (used for the general forms and by callers without a
solver).

Orientations and gaze are rows of our own (for a world axis ``a = R u``: ``a - v`` along,
``a . v`` perpendicular, ``da/dq = -[a]x J_rot``).

Units: metres, radians.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import ClassVar, Protocol

import mujoco
import numpy as np

from azee_mj import native
from azee_mj.kinematics import BodyAxis, BodyOrigin, Expr, Kinematics, Lin, Unit
from azee_mj.score import Rel  # along / opp / perp: the score's own relation

#: Penetration depth [m] at which a collision row reaches 1 (its "tolerance").
COLLISION_TOL = 1e-4
#: Depth [m] allowed between two bodies that a contact constraint brings together.
CONTACT_ALLOWANCE = 5e-4
#: Deepest penetration [m] a converged posture may have between non-neighbouring geoms.
PENETRATION_LIMIT = 1e-3


class Constraint(Protocol):
    """The protocol of :class:`Place`, :class:`Orient`, :class:`Look`, :class:`JointTarget`."""

    tol: float
    label: str
    soft: bool

    def rows(self, k: Kinematics) -> tuple[np.ndarray, np.ndarray]: ...

    def residual(self, k: Kinematics) -> float: ...


@dataclasses.dataclass(frozen=True)
class Place:
    """Model site ``site`` at the point ``target``; within ``tol`` [m].

    A site on a round end of the body (a fingertip) touches a surface with whichever point
    of that end faces it, not only head-on: ``shift`` (a vector expression, added to the
    site: from the site to the end's centre and on to where that centre lies when the end
    touches) and ``gap`` (two round ends: the sum of their radii [m], the distance their
    centres keep) say so; :func:`~azee_mj.contact.rolling` makes them. Then the rows are
    ``d = site + shift - target`` (one round end) or ``d - gap d / |d|`` (two), the
    residual how far the touching point is from the target's site; or, where that is
    less (in a crease, the mouth's corner, that the round end cannot fill), the site's own
    distance from the target, the end meeting head-on.
    """

    site: str
    target: Expr
    tol: float = 1e-3
    label: str = ""
    shift: Expr | None = None
    gap: float = 0.0
    soft: ClassVar[bool] = False

    def rows(self, k: Kinematics):
        p, jp = k.site(k.names.site(self.site))
        t, jt = k.eval(self.target)
        d, J = p - t, (jp if jt is None else jp - jt)
        if self.shift is not None or self.gap > 0.0:
            e, Je = self._rolled(k, d, J)
            if e @ e < d @ d:
                d, J = e, Je
        return d / self.tol, J / self.tol

    def _rolled(self, k: Kinematics, d: np.ndarray, J: np.ndarray):
        """The round end's rows from the site's (``d`` and its Jacobian ``J``)."""
        if self.shift is not None:
            s, js = k.eval(self.shift)
            d, J = d + s, (J if js is None else J + js)
        if self.gap > 0.0:
            n = max(float(np.linalg.norm(d)), 1e-9)
            u = d / n
            J = J - (self.gap / n) * (J - np.outer(u, u @ J))
            d = d - self.gap * u
        return d, J

    def residual(self, k: Kinematics) -> float:
        d = k.d.site_xpos[k.names.site(self.site)] - k.eval(self.target, jac=False)[0]
        plain = math.sqrt(float(d @ d))  # np.linalg.norm's value, without its call cost
        if self.shift is not None:
            d = d + k.eval(self.shift, jac=False)[0]
        n = math.sqrt(float(d @ d))
        return min(plain, abs(n - self.gap) if self.gap > 0.0 else n)


@dataclasses.dataclass(frozen=True)
class Orient:
    """Body axis ``local`` (a bone's DIR or NRM) along / opposite / perpendicular to
    ``vector``; within ``tol`` [rad]. ``ranged``: the tolerance is a range the posture may
    use (the score's orientations): in a problem solved with ``IKProblem.ranges`` the
    solver turns the axis only into it, not pulling it toward the middle from within
    ``RANGE_FREE`` of it (see :mod:`azee_mj.posture.contract`); not ranged (a contact's
    facing, head-on), or without ranges, the axis is turned as near to ``vector`` as the
    solver gets."""

    body: str
    local: tuple[float, float, float]
    rel: Rel
    vector: Expr
    tol: float = np.deg2rad(1.0)
    label: str = ""
    ranged: bool = True
    soft: ClassVar[bool] = False

    def _av(self, k: Kinematics, jac: bool):
        a, ja = k.eval(BodyAxis(self.body, self.local), jac)
        v, jv = k.eval(Unit(self.vector), jac)
        if self.rel is Rel.OPP:
            v, jv = -v, (None if jv is None else -jv)
        return a, ja, v, jv

    def rows(self, k: Kinematics):
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

    def residual(self, k: Kinematics) -> float:
        a, _, v, _ = self._av(k, False)
        c = min(max(float(a @ v), -1.0), 1.0)  # np.clip's value, without its call cost
        return abs(np.arcsin(c)) if self.rel is Rel.PERP else float(np.arccos(c))


@dataclasses.dataclass(frozen=True)
class Look:
    """Each eye body's gaze axis ``local`` points at ``target``; within ``tol`` [rad]."""

    eyes: tuple[tuple[str, tuple[float, float, float]], ...]
    target: Expr
    tol: float = np.deg2rad(1.0)
    label: str = ""
    soft: ClassVar[bool] = False

    def _orients(self) -> list[Orient]:
        return [
            Orient(
                body,
                local,
                Rel.ALONG,
                Lin(((1.0, self.target), (-1.0, BodyOrigin(body)))),
                self.tol,
            )
            for body, local in self.eyes
        ]

    def rows(self, k: Kinematics):
        rows = [o.rows(k) for o in self._orients()]
        return np.concatenate([r for r, _ in rows]), np.vstack([j for _, j in rows])

    def residual(self, k: Kinematics) -> float:
        return max(o.residual(k) for o in self._orients())


@dataclasses.dataclass(frozen=True)
class JointTarget:
    """Joint ``joint`` at ``value`` [rad or m], e.g. from a morph; within ``tol``."""

    joint: str
    value: float
    tol: float = 0.02
    label: str = ""
    #: A soft target guides the posture but never blocks convergence (e.g. an interpolation).
    soft: bool = False

    def rows(self, k: Kinematics):
        j = k.names.joint(self.joint)
        J = np.zeros((1, k.m.nv))
        J[0, k.m.jnt_dofadr[j]] = 1.0 / self.tol
        return np.array([(k.d.qpos[k.m.jnt_qposadr[j]] - self.value) / self.tol]), J

    def residual(self, k: Kinematics) -> float:
        j = k.names.joint(self.joint)
        return abs(float(k.d.qpos[k.m.jnt_qposadr[j]]) - self.value)


def residual_from_rows(c: Constraint, r: np.ndarray) -> float:
    """Constraint ``c``'s residual in its unit ([m] or [rad]) from its raw (unscaled) rows
    ``r`` as the solver's compiled core writes them (the report reads these, so the error
    reported is the one the solver saw): a placement's or joint target's distance; an
    orientation's angle from ``|a - v|`` (along) or ``a . v`` (perpendicular); a look's
    largest angle over its eyes."""
    if isinstance(c, Look):  # each eye's rows are a - v: the angle from |a - v|
        eyes = np.sqrt((r.reshape(-1, 3) ** 2).sum(axis=1))
        return float(2.0 * np.arcsin(np.minimum(1.0, eyes / 2.0)).max())
    if isinstance(c, Orient):
        if c.rel is Rel.PERP:
            return float(np.arcsin(min(1.0, abs(r[0]))))
        return float(2.0 * np.arcsin(min(1.0, np.sqrt(r @ r) / 2.0)))
    return float(np.sqrt(r @ r))


def penetration_depth(m: mujoco.MjModel, d: mujoco.MjData, allowed=frozenset()) -> float:
    """Deepest penetration [m] (>= 0) between colliding geoms of posture ``d.qpos``, ignoring
    body pairs in ``allowed``. Runs ``mj_kinematics`` and ``mj_collision``."""
    mujoco.mj_kinematics(m, d)
    return contact_depth(m, d, allowed)


def contact_depth(m: mujoco.MjModel, d: mujoco.MjData, allowed=frozenset()) -> float:
    """:func:`penetration_depth` on a posture whose kinematics ``d`` holds already: runs
    ``mj_collision``, then takes the deepest contact (``dist < 0``: those within the margin
    only are no penetration) but between the body pairs ``allowed``, in the compiled core
    (asked at nearly every frame of a realization)."""
    return native.core().depth(m._address, d._address, _pair_array(allowed))


def pairs_depth(
    m: mujoco.MjModel, d: mujoco.MjData, pairs: np.ndarray, allowed=frozenset()
) -> float:
    """:func:`contact_depth` among geom ``pairs`` (n, 2) int32 alone (as
    :func:`~azee_mj.posture.collision.collision_pairs` lists them), on a posture whose
    kinematics ``d`` holds already: MuJoCo's narrowphase on those pairs, without
    ``mj_collision`` (for a caller that knows the other pairs' depth), in the compiled core."""
    return native.core().pairs_depth(m._address, d._address, pairs, _pair_array(allowed))


def run_pairs_depth(
    m: mujoco.MjModel, d: mujoco.MjData, qs: np.ndarray, pairs: np.ndarray, allowed=frozenset()
) -> np.ndarray:
    """(n,) :func:`pairs_depth` at each posture of ``qs`` (n, nq), its kinematics run, in
    one call of the compiled core (``d`` holds the last posture afterwards)."""
    qs = np.ascontiguousarray(qs, float)
    if qs.ndim != 2 or qs.shape[1] != m.nq:
        raise ValueError(f"postures: expected (n, {m.nq}), got {qs.shape}")
    raw = native.core().pairs_depths(m._address, d._address, qs, pairs, _pair_array(allowed))
    return np.frombuffer(raw)


@functools.lru_cache(maxsize=256)
def _pair_array(allowed: frozenset) -> np.ndarray:
    """Body pairs ``allowed`` as an (n, 2) int32 array (the schedule shares its sets: each
    converted once)."""
    return np.array(sorted(allowed), np.int32).reshape(-1, 2)
