"""Walkers over point and vector expressions: what an expression reads. Evaluating one on a
posture is :class:`azee_mj.kinematics.Kinematics`' job."""

from __future__ import annotations

from collections.abc import Callable, Iterator

import numpy as np

from azee_mj.score.records import (
    Axis,
    BoneRef,
    PLiteral,
    PMid,
    PointExpr,
    PSite,
    PTranslate,
    SiteRef,
    VAdd,
    VAxis,
    VBoneAxis,
    VCross,
    VectorExpr,
    VFrom,
    VLiteral,
    VOpp,
    VScale,
    VUnit,
)


def children(expr: PointExpr | VectorExpr) -> tuple[PointExpr | VectorExpr, ...]:
    """The direct sub-expressions of ``expr``."""
    if isinstance(expr, (PTranslate,)):
        return (expr.p, expr.v)
    if isinstance(expr, (PMid, VFrom)):
        return (expr.p, expr.q)
    if isinstance(expr, (VOpp, VScale, VUnit)):
        return (expr.v,)
    if isinstance(expr, VAdd):
        return expr.terms
    if isinstance(expr, VCross):
        return (expr.a, expr.b)
    return ()


def walk(expr: PointExpr | VectorExpr) -> Iterator[PointExpr | VectorExpr]:
    """``expr`` and all its sub-expressions, depth first."""
    yield expr
    for child in children(expr):
        yield from walk(child)


def depends_on_body(expr: PointExpr | VectorExpr) -> bool:
    """Whether the expression reads the posture (any site, locus or bone axis in it)."""
    return any(isinstance(e, (PSite, VBoneAxis)) for e in walk(expr))


def referenced_sites(expr: PointExpr | VectorExpr) -> tuple[SiteRef, ...]:
    """The sites and loci an expression reads, each once, in order of appearance."""
    return tuple(dict.fromkeys(e.ref for e in walk(expr) if isinstance(e, PSite)))


def referenced_bones(expr: PointExpr | VectorExpr) -> tuple[BoneRef, ...]:
    """The bones whose axes an expression reads, each once, in order of appearance."""
    return tuple(dict.fromkeys(e.bone for e in walk(expr) if isinstance(e, VBoneAxis)))


SitePos = Callable[[SiteRef], np.ndarray]
BoneAxisFn = Callable[[BoneRef, Axis], np.ndarray]


def eval_point(expr: PointExpr, site_pos: SitePos, bone_axis: BoneAxisFn) -> np.ndarray:
    """The value (3,) [m] of a point expression in the signer frame.

    ``site_pos(ref)`` gives a site's or locus' position (3,) and ``bone_axis(bone, axis)``
    a bone's unit DIR / NRM axis (3,), both in the signer frame on the posture at hand.
    """
    if isinstance(expr, PSite):
        return np.asarray(site_pos(expr.ref), dtype=float).reshape(3)
    if isinstance(expr, PLiteral):
        return np.array(expr.xyz, dtype=float)
    if isinstance(expr, PTranslate):
        return eval_point(expr.p, site_pos, bone_axis) + eval_vector(expr.v, site_pos, bone_axis)
    if isinstance(expr, PMid):
        p = eval_point(expr.p, site_pos, bone_axis)
        return 0.5 * (p + eval_point(expr.q, site_pos, bone_axis))
    raise TypeError(f"not a point expression: {expr!r}")


def eval_vector(expr: VectorExpr, site_pos: SitePos, bone_axis: BoneAxisFn) -> np.ndarray:
    """The value (3,) of a vector expression in the signer frame (see :func:`eval_point`).

    ``VUnit`` of a zero vector evaluates to zero; callers that need a direction check the
    norm (constant zero directions are already rejected by :func:`load_score`).
    """
    if isinstance(expr, (VAxis, VLiteral)):
        return np.array(expr.xyz, dtype=float)
    if isinstance(expr, VBoneAxis):
        return np.asarray(bone_axis(expr.bone, expr.axis), dtype=float).reshape(3)
    if isinstance(expr, VOpp):
        return -eval_vector(expr.v, site_pos, bone_axis)
    if isinstance(expr, VScale):
        return expr.k * eval_vector(expr.v, site_pos, bone_axis)
    if isinstance(expr, VAdd):
        total = np.zeros(3)
        for term in expr.terms:
            total = total + eval_vector(term, site_pos, bone_axis)
        return total
    if isinstance(expr, VCross):
        a = eval_vector(expr.a, site_pos, bone_axis)
        return np.cross(a, eval_vector(expr.b, site_pos, bone_axis))
    if isinstance(expr, VFrom):
        p = eval_point(expr.p, site_pos, bone_axis)
        return eval_point(expr.q, site_pos, bone_axis) - p
    if isinstance(expr, VUnit):
        v = eval_vector(expr.v, site_pos, bone_axis)
        n = float(np.linalg.norm(v))
        return v / n if n > 0.0 else np.zeros(3)
    raise TypeError(f"not a vector expression: {expr!r}")
