"""The geometry of a transpath's route: points along a straight line, an arc or a circle
between the site's position at the path's start and at its end.

:func:`path_points` evaluates a route's score expressions (bulge, centre, normal) on the
posture at the path's start; the rest are pure functions of points.

Units: metres, radians.
"""

from __future__ import annotations

import numpy as np

from azee_mj import score as sc
from azee_mj.kinematics import Kinematics, compile_point, compile_vector
from azee_mj.sites import SignerMap


def path_points(
    route, x0: np.ndarray, x1: np.ndarray, u, kin: Kinematics, smap: SignerMap
) -> np.ndarray:
    """Points (len(u), 3) [m] of a transpath ``route`` from ``x0`` to ``x1`` at path
    parameters ``u`` (0 at ``x0``, 1 at ``x1``); ``kin`` is the posture at the path's start,
    where the route's expressions are evaluated (names of ``smap``)."""
    u = np.asarray(u)
    if isinstance(route, sc.Straight):
        return x0 + u[:, None] * (x1 - x0)
    if isinstance(route, sc.Arc):
        bulge = kin.value(compile_vector(route.bulge, smap))
        return arc_through(x0, 0.5 * (x0 + x1) + bulge, x1, u)
    if isinstance(route, sc.Circle):
        centre = kin.value(compile_point(route.center, smap))
        normal = None if route.normal is None else kin.value(compile_vector(route.normal, smap))
        return circle_points(centre, x0, x1, normal, route.turns, u)
    raise TypeError(route)


def arc_through(a, b, c, u) -> np.ndarray:
    """Points (len(u), 3) of the circular arc from ``a`` through ``b`` to ``c`` at fractions
    ``u`` of its angle (a straight line when the three are collinear)."""
    ab, ac = b - a, c - a
    n = np.cross(ab, ac)
    if np.linalg.norm(n) < 1e-12:
        return a + u[:, None] * (c - a)
    # Circumcentre of the triangle.
    cc = a + (np.cross(n, ab) * (ac @ ac) + np.cross(ac, n) * (ab @ ab)) / (2 * (n @ n))
    n = n / np.linalg.norm(n)
    e1 = (a - cc) / np.linalg.norm(a - cc)
    e2 = np.cross(n, e1)
    r = np.linalg.norm(a - cc)

    def ang(p):
        v = p - cc
        return np.arctan2(v @ e2, v @ e1) % (2 * np.pi)

    total = ang(c)  # a is at angle 0; going through b in the +n sense reaches c at ang(c)
    return cc + r * (np.cos(u * total)[:, None] * e1 + np.sin(u * total)[:, None] * e2)


def circle_points(centre, x0, x1, normal, turns: int, u) -> np.ndarray:
    """Points (len(u), 3) going ``turns`` full turns about ``centre`` from ``x0`` on to
    ``x1`` (its angle, radius and height along the axis interpolated), about ``normal``
    (right-handed; None: the normal of the plane through ``centre``, ``x0``, ``x1``)."""
    r0, r1 = x0 - centre, x1 - centre
    n = np.cross(r0, r1) if normal is None else normal
    n = n / max(np.linalg.norm(n), 1e-12)
    e1 = r0 - n * (r0 @ n)
    e2 = np.cross(n, e1)
    rad0 = np.linalg.norm(e1)
    e1, e2 = e1 / rad0, e2 / np.linalg.norm(e2)
    p1 = r1 - n * (r1 @ n)
    end_angle = np.arctan2(p1 @ e2, p1 @ e1) % (2 * np.pi)
    total = 2 * np.pi * turns + (end_angle if np.linalg.norm(p1) > 1e-9 else 0.0)
    if end_angle < 1e-6:
        total = 2 * np.pi * turns
    ang = u * total
    rad = rad0 + u * (np.linalg.norm(p1) - rad0)
    h = (r0 @ n) + u * ((r1 @ n) - (r0 @ n))
    return (
        centre
        + rad[:, None] * (np.cos(ang)[:, None] * e1 + np.sin(ang)[:, None] * e2)
        + h[:, None] * n
    )
