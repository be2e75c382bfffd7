"""Points and vectors on a posture, with or without their Jacobians: the one evaluator.

Score expressions (:mod:`azee_mj.score` records, AZee names) are compiled once onto a model's
names by :func:`compile_point` / :func:`compile_vector` into a small tree (:class:`Const`,
:class:`SitePos`, :class:`BodyAxis`, :class:`BodyOrigin`, :class:`Lin`, :class:`Cross`,
:class:`Unit`). :class:`Kinematics` evaluates a tree on the posture held in an ``MjData``
(after ``mj_kinematics``; Jacobians also need ``mj_comPos``): the IK rows, trills, transpath
routes and the viewer's markers all read points and vectors through it.

Units: metres; vectors in the signer (world) frame.
"""

from __future__ import annotations

import dataclasses
import math

import mujoco
import numpy as np

from azee_mj import score as sc
from azee_mj.sites import SignerMap


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
class BodyOrigin:
    """The world position of a body's frame origin [m] (an eye's centre for a look)."""

    body: str


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
    """``a / |a|`` (zero for a vector shorter than 1e-12)."""

    a: Expr


Expr = Const | SitePos | BodyAxis | BodyOrigin | Lin | Cross | Unit


def skew(v: np.ndarray) -> np.ndarray:
    """The matrix ``[v]x`` with ``[v]x w = v x w``."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def compile_point(e: sc.PointExpr, signer_map: SignerMap) -> Expr:
    """A score point expression on the model of ``signer_map``."""
    if isinstance(e, sc.PSite):
        return SitePos(e.ref.model_site(signer_map))
    if isinstance(e, sc.PLiteral):
        return Const(tuple(e.xyz))
    if isinstance(e, sc.PTranslate):
        return Lin(((1.0, compile_point(e.p, signer_map)), (1.0, compile_vector(e.v, signer_map))))
    if isinstance(e, sc.PMid):
        return Lin(((0.5, compile_point(e.p, signer_map)), (0.5, compile_point(e.q, signer_map))))
    raise TypeError(e)


def compile_vector(e: sc.VectorExpr, signer_map: SignerMap) -> Expr:
    """A score vector expression on the model of ``signer_map``."""
    if isinstance(e, (sc.VAxis, sc.VLiteral)):
        return Const(tuple(e.xyz))
    if isinstance(e, sc.VBoneAxis):
        b = e.bone.bone_map(signer_map)
        return BodyAxis(b.body, b.dir if e.axis is sc.Axis.DIR else b.nrm)
    if isinstance(e, sc.VOpp):
        return Lin(((-1.0, compile_vector(e.v, signer_map)),))
    if isinstance(e, sc.VScale):
        return Lin(((e.k, compile_vector(e.v, signer_map)),))
    if isinstance(e, sc.VAdd):
        return Lin(tuple((1.0, compile_vector(t, signer_map)) for t in e.terms))
    if isinstance(e, sc.VCross):
        return Cross(compile_vector(e.a, signer_map), compile_vector(e.b, signer_map))
    if isinstance(e, sc.VFrom):
        return Lin(((1.0, compile_point(e.q, signer_map)), (-1.0, compile_point(e.p, signer_map))))
    if isinstance(e, sc.VUnit):
        return Unit(compile_vector(e.v, signer_map))
    raise TypeError(e)


class Names:
    """Model ids by name, looked up once (``KeyError`` naming what is missing)."""

    def __init__(self, model: mujoco.MjModel):
        self.model = model
        # one table per kind of object (asked per frame and constraint: a plain dict look-up)
        self._sites: dict[str, int] = {}
        self._bodies: dict[str, int] = {}
        self._joints: dict[str, int] = {}

    def _id(self, obj, ids: dict[str, int], name: str) -> int:
        i = mujoco.mj_name2id(self.model, obj, name)
        if i < 0:
            raise KeyError(f"the model has no {obj.name[6:].lower()} named {name!r}")
        ids[name] = i
        return i

    def site(self, name: str) -> int:
        i = self._sites.get(name)
        return self._id(mujoco.mjtObj.mjOBJ_SITE, self._sites, name) if i is None else i

    def body(self, name: str) -> int:
        i = self._bodies.get(name)
        return self._id(mujoco.mjtObj.mjOBJ_BODY, self._bodies, name) if i is None else i

    def joint(self, name: str) -> int:
        i = self._joints.get(name)
        return self._id(mujoco.mjtObj.mjOBJ_JOINT, self._joints, name) if i is None else i


class Kinematics:
    """Points and vectors of the posture in ``data``, computed on demand and cached.

    Make one per posture: Jacobians are cached. ``names`` shares id look-ups between
    instances (default: a new :class:`Names`).
    """

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, names: Names | None = None):
        self.m, self.d = model, data
        self.names = names or Names(model)
        self._site: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._bodyr: dict[int, np.ndarray] = {}

    def site(self, sid: int) -> tuple[np.ndarray, np.ndarray]:
        """Position (3,) and translational Jacobian (3, nv) of site ``sid``."""
        if sid not in self._site:
            jac = np.empty((3, self.m.nv))
            mujoco.mj_jacSite(self.m, self.d, jac, None, sid)
            self._site[sid] = (self.d.site_xpos[sid].copy(), jac)
        return self._site[sid]

    def body_rot_jac(self, bid: int) -> np.ndarray:
        """Rotational Jacobian (3, nv) of body ``bid``."""
        if bid not in self._bodyr:
            jac = np.empty((3, self.m.nv))
            mujoco.mj_jacBody(self.m, self.d, None, jac, bid)
            self._bodyr[bid] = jac
        return self._bodyr[bid]

    def eval(self, e: Expr, jac: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
        """Value (3,) of ``e`` and, if ``jac``, its Jacobian (3, nv) (None when constant)."""
        if isinstance(e, Const):
            return np.asarray(e.value, float), None
        if isinstance(e, SitePos):
            sid = self.names.site(e.site)
            if not jac:
                return self.d.site_xpos[sid].copy(), None
            return self.site(sid)
        if isinstance(e, BodyOrigin):
            bid = self.names.body(e.body)
            if not jac:
                return self.d.xpos[bid].copy(), None
            jp = np.empty((3, self.m.nv))
            mujoco.mj_jacBody(self.m, self.d, jp, None, bid)
            return self.d.xpos[bid].copy(), jp
        if isinstance(e, BodyAxis):
            bid = self.names.body(e.body)
            a = self.d.xmat[bid].reshape(3, 3) @ np.asarray(e.local, float)
            return a, (-skew(a) @ self.body_rot_jac(bid) if jac else None)
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
                J = -skew(b) @ ja
            if jb is not None:
                J = skew(a) @ jb if J is None else J + skew(a) @ jb
            return np.cross(a, b), J
        if isinstance(e, Unit):
            a, ja = self.eval(e.a, jac)
            n = math.sqrt(float(a @ a))  # np.linalg.norm's value, without its call cost
            if n < 1e-12:
                return np.zeros(3), None if ja is None else np.zeros_like(ja)
            u = a / n
            return u, None if ja is None else (np.eye(3) - np.outer(u, u)) @ ja / n
        raise TypeError(f"not a kinematic expression: {e!r}")

    def value(self, e: Expr) -> np.ndarray:
        """The value (3,) of ``e``, no Jacobian."""
        return self.eval(e, jac=False)[0]
