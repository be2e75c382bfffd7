"""Transpath route geometry, called directly; the route expressions on the real signer."""

from __future__ import annotations

import numpy as np
import pytest

from azee_mj import score as sc
from azee_mj.routes import arc_through, circle_points, path_points
from azee_mj.sites import DEFAULT_MAP

U = np.linspace(0.0, 1.0, 41)


def _circumcentre(a, b, c):
    """The centre of the circle through three points, from the perpendicular bisectors."""
    n = np.cross(b - a, c - a)
    A = np.array([b - a, c - a, n])
    rhs = np.array([(b @ b - a @ a) / 2, (c @ c - a @ a) / 2, n @ a])
    return np.linalg.solve(A, rhs)


def test_arc_through_three_points_stays_on_their_circle():
    a, b, c = np.array([0.1, 0.0, 1.0]), np.array([0.2, 0.1, 1.05]), np.array([0.3, 0.0, 1.0])
    pts = arc_through(a, b, c, U)
    centre = _circumcentre(a, b, c)
    r = np.linalg.norm(a - centre)
    np.testing.assert_allclose(np.linalg.norm(pts - centre, axis=1), r, atol=1e-12)
    np.testing.assert_allclose(pts[0], a, atol=1e-12)
    np.testing.assert_allclose(pts[-1], c, atol=1e-12)
    assert np.linalg.norm(pts - b, axis=1).min() < 2 * np.pi * r / len(U)  # passes by b
    n = np.cross(b - a, c - a)
    np.testing.assert_allclose((pts - a) @ n, 0.0, atol=1e-12)  # in their plane


def test_arc_through_collinear_points_is_the_straight_line():
    a, c = np.array([0.0, 0.0, 1.0]), np.array([0.2, 0.0, 1.0])
    pts = arc_through(a, 0.5 * (a + c), c, U)
    np.testing.assert_allclose(pts, a + U[:, None] * (c - a))


def test_circle_points_turn_about_the_centre_and_end_at_the_end():
    centre = np.array([0.3, 0.0, 1.2])
    x0 = centre + [0.0, 0.05, 0.0]
    normal = np.array([1.0, 0.0, 0.0])
    pts = circle_points(centre, x0, x0, normal, 1.0, U)  # a whole turn, back to the start
    np.testing.assert_allclose(np.linalg.norm(pts - centre, axis=1), 0.05, atol=1e-12)
    np.testing.assert_allclose((pts - centre) @ normal, 0.0, atol=1e-12)
    np.testing.assert_allclose(pts[-1], x0, atol=1e-12)
    angle = np.unwrap(np.arctan2(pts[:, 2] - centre[2], pts[:, 1] - centre[1]))
    np.testing.assert_allclose(np.diff(angle), 2 * np.pi / (len(U) - 1))  # right-handed
    x1 = centre + [0.0, 0.0, 0.08]  # a quarter turn on, further out: the radius grows
    pts = circle_points(centre, x0, x1, normal, 1.0, U)
    np.testing.assert_allclose(pts[-1], x1, atol=1e-12)
    radius = np.linalg.norm(pts - centre, axis=1)
    np.testing.assert_allclose(radius, 0.05 + U * 0.03, atol=1e-12)


def test_path_points_evaluate_the_route_on_the_signer(solver):
    k = solver.at(solver.natural)
    x0, x1 = np.array([0.3, -0.1, 1.1]), np.array([0.3, 0.1, 1.1])
    straight = path_points(sc.Straight(), x0, x1, U, k, DEFAULT_MAP)
    np.testing.assert_allclose(straight, x0 + U[:, None] * (x1 - x0))
    arc = path_points(sc.Arc(sc.VLiteral((0.0, 0.0, 0.05))), x0, x1, U, k, DEFAULT_MAP)
    np.testing.assert_allclose(arc[len(U) // 2], [0.3, 0.0, 1.15], atol=1e-12)
    head = sc.Circle(sc.PSite(sc.SiteRef("HEAD")), 1.0)
    pts = path_points(head, x0, x1, U, k, DEFAULT_MAP)
    c = solver.at(solver.natural).d.site_xpos[solver.site_id("HEAD")].copy()
    np.testing.assert_allclose(np.linalg.norm(pts[0] - c), np.linalg.norm(x0 - c))
    np.testing.assert_allclose(pts[-1], x1, atol=1e-9)
    with pytest.raises(TypeError):
        path_points("zigzag", x0, x1, U, k, DEFAULT_MAP)
