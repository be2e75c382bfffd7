"""Contacts of round ends: a fingertip touches with whichever point of its round end faces
the other side, not only with the point at the end of the finger's axis.

A site on the round end of a capsule (a fingertip: the distal phalanx's capsule, the site
where its axis leaves the skin) meets a surface head-on only: tilted by an angle ``a``, that
site stands ``r (1 - cos a)`` off the surface while the end's skin already touches it (1 mm
at 30 degrees for a 7 mm fingertip). :func:`rolling` makes the placement of such a site
a contact of the whole end: the end's centre at its radius from the other side's site
along that side's outward normal, or two ends' centres at the sum of their radii.

Units: metres.
"""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np

from azee_mj import constraints as cn
from azee_mj.kinematics import BodyAxis, Expr, Lin
from azee_mj.sites import SignerMap

#: How far a site may be from where its capsule's round end meets the capsule's axis, plus
#: the radius along its normal, to count as on that end [m].
END_TOL = 5e-4
#: How nearly a round end's site normal lies along its capsule's axis (cosine).
END_COS = 0.99


@dataclasses.dataclass(frozen=True)
class RoundEnd:
    """A site on a round end: its body, its outward normal in the body frame (unit) and
    the end's radius [m] (its centre lies ``radius`` inside along the normal)."""

    body: str
    normal: tuple[float, float, float]
    radius: float


def round_end(model: mujoco.MjModel, smap: SignerMap, site: str) -> RoundEnd | None:
    """The round end model ``site`` lies on, or None: a colliding capsule of its body whose
    axis end plus its radius along the site's normal is the site."""
    azee = {v: k for k, v in smap.sites.items()}.get(site)
    normal = smap.normals.get(azee) if azee is not None else None
    sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site)
    if normal is None or sid < 0:
        return None
    n = np.asarray(normal, float)
    body = int(model.site_bodyid[sid])
    p = model.site_pos[sid]
    for g in range(model.ngeom):
        if model.geom_bodyid[g] != body or model.geom_type[g] != mujoco.mjtGeom.mjGEOM_CAPSULE:
            continue
        if not (model.geom_contype[g] or model.geom_conaffinity[g]):
            continue
        rot = np.empty(9)
        mujoco.mju_quat2Mat(rot, model.geom_quat[g])
        axis = rot.reshape(3, 3)[:, 2]
        r, half = model.geom_size[g][:2]
        for sign in (1.0, -1.0):
            end = model.geom_pos[g] + sign * half * axis
            if sign * (axis @ n) >= END_COS and np.linalg.norm(end + r * n - p) <= END_TOL:
                return RoundEnd(model.body(body).name, tuple(float(x) for x in n), float(r))
    return None


def rolling(
    model: mujoco.MjModel, smap: SignerMap, site: str, target: str
) -> tuple[Expr, float] | None:
    """(``shift``, ``gap``) of :class:`~azee_mj.constraints.Place` for model ``site`` placed
    at model site ``target`` when either lies on a round end (:func:`round_end`) and the
    other side has an outward normal; None otherwise (the sites themselves meet)."""
    a, b = round_end(model, smap, site), round_end(model, smap, target)
    if a is None and b is None:
        return None
    if a is not None and b is not None:
        shift = Lin(
            ((-a.radius, BodyAxis(a.body, a.normal)), (b.radius, BodyAxis(b.body, b.normal)))
        )
        return shift, a.radius + b.radius
    azee = {v: k for k, v in smap.sites.items()}
    flat = target if a is not None else site
    normal = smap.normals.get(azee.get(flat, ""))
    if normal is None:
        return None
    flat_body = model.body(int(model.site_bodyid[model.site(flat).id])).name
    end = a if a is not None else b
    sign = -1.0 if a is not None else 1.0  # the end's centre: inside the placed site, or past it
    shift = Lin(
        (
            (sign * end.radius, BodyAxis(end.body, end.normal)),
            (sign * end.radius, BodyAxis(flat_body, tuple(float(x) for x in normal))),
        )
    )
    return shift, 0.0


#: How far from head-on a round end may meet its target [deg] when it touches with any
#: point of its end (the face-to-face rule of its placement widened to this): the touching
#: point stays on the end's dome, away from where the finger's side begins (90).
ROLLED_FACING_DEG = 60.0


def widened(constraints) -> tuple:
    """``constraints`` with the face-to-face rule (``Orient`` labelled ``X:facing``) of
    each round-end placement ``X`` widened to :data:`ROLLED_FACING_DEG`, a range: any point
    of the end's dome may touch (:attr:`~azee_mj.constraints.Orient.ranged`)."""
    rolled = {
        f"{c.label}:facing"
        for c in constraints
        if isinstance(c, cn.Place) and (c.shift is not None or c.gap > 0.0)
    }
    tol = float(np.radians(ROLLED_FACING_DEG))
    return tuple(
        dataclasses.replace(c, tol=max(c.tol, tol), ranged=True)
        if isinstance(c, cn.Orient) and c.label in rolled
        else c
        for c in constraints
    )


def head_on(constraints) -> tuple | None:
    """``constraints`` with every round-end placement (a ``shift`` or a ``gap``) made a
    placement of the site itself (the end meeting head-on), or None if there is none."""
    rolled = [isinstance(c, cn.Place) and (c.shift is not None or c.gap > 0.0) for c in constraints]
    if not any(rolled):
        return None
    return tuple(
        dataclasses.replace(c, shift=None, gap=0.0) if r else c for c, r in zip(constraints, rolled)
    )
