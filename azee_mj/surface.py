"""The skin of a MuJoCo signer: signed distance to its collision geoms and outward normals.

Collision geoms of the bundled signer are primitives (spheres, capsules, ellipsoids, boxes),
so the distance from a point to one of them and the outward normal at its closest point are
computed exactly here (an ellipsoid's closest point by bisection on its Lagrange
multiplier). A body's skin is the surface of the union of its collision geoms. Used to check
that the catalogue's surface sites lie on the skin with the catalogue's normals.

Units: metres.
"""

from __future__ import annotations

import mujoco
import numpy as np

_G = mujoco.mjtGeom


def _ellipsoid(p: np.ndarray, r: np.ndarray) -> tuple[float, np.ndarray]:
    f = float(np.sum((p / r) ** 2))
    if f == 0.0:  # the centre: the nearest surface point is at the smallest semi-axis
        n = np.zeros(3)
        n[int(np.argmin(r))] = 1.0
        return -float(np.min(r)), n

    def g(t):  # > 0 while t is below the closest point's multiplier
        return np.sum((r * p / (r * r + t)) ** 2) - 1.0

    if f < 1.0:
        lo, hi = -(float(np.min(r)) ** 2), 0.0
    else:
        lo, hi = 0.0, float(np.linalg.norm(p) * np.max(r))
        while g(hi) > 0:
            hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if g(mid) > 0:
            lo = mid
        else:
            hi = mid
    t = 0.5 * (lo + hi)
    x = r * r * p / (r * r + t)
    n = x / (r * r)
    d = float(np.linalg.norm(p - x))
    return (d if f >= 1.0 else -d), n / np.linalg.norm(n)


def local_distance(geom_type: int, size, p) -> tuple[float, np.ndarray]:
    """Signed distance [m] (negative inside) from ``p`` (in the geom's frame) to a sphere,
    capsule, ellipsoid or box of MuJoCo ``size``, and the outward unit normal of the
    surface at the closest point (the distance's gradient), in the geom's frame."""
    p = np.asarray(p, float)
    size = np.asarray(size, float)
    if geom_type == _G.mjGEOM_SPHERE:
        n = float(np.linalg.norm(p))
        return n - size[0], p / n
    if geom_type == _G.mjGEOM_CAPSULE:
        q = p.copy()
        q[2] -= np.clip(p[2], -size[1], size[1])
        n = float(np.linalg.norm(q))
        return n - size[0], q / n
    if geom_type == _G.mjGEOM_ELLIPSOID:
        return _ellipsoid(p, size)
    if geom_type == _G.mjGEOM_BOX:
        q = np.abs(p) - size[:3]
        out = np.maximum(q, 0.0)
        if np.any(out > 0):
            n = out * np.sign(p)
            return float(np.linalg.norm(out)), n / np.linalg.norm(n)
        i = int(np.argmax(q))
        n = np.zeros(3)
        n[i] = np.sign(p[i]) or 1.0
        return float(q[i]), n
    raise ValueError(f"geom type {geom_type} is not a sphere, capsule, ellipsoid or box")


def geom_distance(
    model: mujoco.MjModel, data: mujoco.MjData, geom: int, point
) -> tuple[float, np.ndarray]:
    """Signed distance [m] from the world ``point`` to geom ``geom`` on the posture in
    ``data`` (after ``mj_kinematics``), and the outward unit normal (world)."""
    R = data.geom_xmat[geom].reshape(3, 3)
    d, n = local_distance(
        model.geom_type[geom],
        model.geom_size[geom],
        R.T @ (np.asarray(point, float) - data.geom_xpos[geom]),
    )
    return d, R @ n


def collision_geoms(model: mujoco.MjModel, body: int) -> list[int]:
    """The geoms of ``body`` that collide (``contype`` or ``conaffinity`` set)."""
    return [
        g
        for g in range(model.ngeom)
        if model.geom_bodyid[g] == body and (model.geom_contype[g] or model.geom_conaffinity[g])
    ]


def skin_distance(
    model: mujoco.MjModel, data: mujoco.MjData, body: int, point
) -> tuple[float, np.ndarray, int]:
    """Signed distance [m] from the world ``point`` to the skin of ``body`` (the union of its
    collision geoms: the least of their distances, exact outside, a bound inside), the
    outward unit normal there (world) and the geom it is on. Raises ValueError for a body
    without collision geoms."""
    best = None
    for g in collision_geoms(model, body):
        d, n = geom_distance(model, data, g, point)
        if best is None or d < best[0]:
            best = (d, n, g)
    if best is None:
        raise ValueError(f"body {model.body(body).name!r} has no collision geom")
    return best
