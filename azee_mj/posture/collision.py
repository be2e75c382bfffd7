"""The geom pairs the solver's compiled core collides, and the clusters it skips them by.

Units: metres.
"""

from __future__ import annotations

import mujoco
import numpy as np


def collision_pairs(m: mujoco.MjModel) -> np.ndarray:
    """(n, 2) the geom pairs ``mj_collision`` tests on model ``m`` (contype/conaffinity,
    not welded together, not parent and child unless the parent is the world, not excluded),
    in its order (by body pair, then geom pair), each pair's geoms in the type order of its
    ``mjCOLLISIONFUNC``."""
    geoms = np.flatnonzero((m.geom_contype | m.geom_conaffinity) != 0)
    i, j = np.triu_indices(geoms.size, 1)
    g1, g2 = geoms[i], geoms[j]
    ok = (
        (m.geom_contype[g1] & m.geom_conaffinity[g2])
        | (m.geom_contype[g2] & m.geom_conaffinity[g1])
    ) != 0
    w1, w2 = m.body_weldid[m.geom_bodyid[g1]], m.body_weldid[m.geom_bodyid[g2]]
    ok &= w1 != w2
    if not m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_FILTERPARENT:
        p1, p2 = m.body_weldid[m.body_parentid[w1]], m.body_weldid[m.body_parentid[w2]]
        ok &= ~((w1 != 0) & (w2 != 0) & ((w1 == p2) | (w2 == p1)))
    b1, b2 = m.geom_bodyid[g1], m.geom_bodyid[g2]
    lo, hi = np.minimum(b1, b2), np.maximum(b1, b2)
    ok &= ~np.isin((lo << 16) + hi, m.exclude_signature)
    planar = (mujoco.mjtGeom.mjGEOM_PLANE, mujoco.mjtGeom.mjGEOM_HFIELD)
    ok &= ~(np.isin(m.geom_type[g1], planar) & np.isin(m.geom_type[g2], planar))
    swap = m.geom_type[g1] > m.geom_type[g2]
    a1, a2 = np.where(swap, g2, g1)[ok], np.where(swap, g1, g2)[ok]
    order = np.lexsort((a2, a1, hi[ok], lo[ok]))
    return np.ascontiguousarray(np.stack([a1[order], a2[order]], axis=1), np.int32)


def geom_clusters(
    m: mujoco.MjModel, geom_xpos: np.ndarray, xpos: np.ndarray, radius: float = 0.25
) -> np.ndarray:
    """(ngeom,) int32 the cluster of each colliding geom (-1 for the others): the highest
    body whose subtree holds two colliding geoms or more, all within ``radius`` [m] of its
    origin in the posture of ``geom_xpos`` (ngeom, 3) and ``xpos`` (nbody, 3) (a hand, the head), or the geom alone. The compiled core skips
    the pairs of two clusters whose bounding spheres are apart."""
    geoms = np.flatnonzero((m.geom_contype | m.geom_conaffinity) != 0)
    members: dict[int, list[int]] = {}
    for g in geoms:
        b = m.geom_bodyid[g]
        while b > 0:
            members.setdefault(b, []).append(g)
            b = m.body_parentid[b]

    small = {}
    for b, gs in members.items():
        reach = np.linalg.norm(geom_xpos[gs] - xpos[b], axis=1) + m.geom_rbound[gs]
        small[b] = len(gs) >= 2 and bool(np.all(m.geom_rbound[gs] > 0)) and reach.max() <= radius

    out = np.full(m.ngeom, -1, np.int32)
    roots: dict[int, int] = {}
    for g in geoms:
        b, root = m.geom_bodyid[g], None
        while b > 0:
            if small[b]:
                root = b
            b = m.body_parentid[b]
        key = -1 - g if root is None else root
        out[g] = roots.setdefault(key, len(roots))
    return out


def moving_pairs(m: mujoco.MjModel, pairs: np.ndarray, free: np.ndarray) -> np.ndarray:
    """(n, 2) of geom ``pairs`` those whose distance the dofs ``free`` can change: without
    the pairs joined by no free dof (within a hand whose shape is fixed, within the unmoved
    rest of the body); in the order of ``pairs``."""
    moving = np.zeros(m.nbody, bool)
    moving[m.dof_bodyid[free]] = True
    group = np.arange(m.nbody)  # rigid group: the body's moving ancestor, or itself
    for b in range(1, m.nbody):  # parents come before children
        if not moving[b]:
            group[b] = group[m.body_parentid[b]]
    bodies = m.geom_bodyid[pairs]
    keep = group[bodies[:, 0]] != group[bodies[:, 1]]
    return np.ascontiguousarray(pairs[keep])


def pair_coordinates(m: mujoco.MjModel, pairs: np.ndarray) -> np.ndarray:
    """(n, nq) bool: the posture coordinates that move geom pair ``pairs[i]``'s geoms (the
    joints from the world to either body). A pair none of whose coordinates changes keeps
    its distance, to the bit."""
    chain = np.zeros((m.nbody, m.nq), bool)  # the coordinates that move each body
    for b in range(1, m.nbody):  # parents come before children
        chain[b] = chain[m.body_parentid[b]]
        for j in range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b]):
            a = m.jnt_qposadr[j]
            chain[b, a : m.jnt_qposadr[j + 1] if j + 1 < m.njnt else m.nq] = True
    bodies = m.geom_bodyid[pairs]
    return chain[bodies[:, 0]] | chain[bodies[:, 1]]


def still_pairs(coordinates: np.ndarray, postures: np.ndarray) -> np.ndarray:
    """(n,) bool: which pairs of :func:`pair_coordinates` ``coordinates`` (n, nq) keep their
    geoms where they are over every posture of ``postures`` (k, nq)."""
    changed = (postures != postures[:1]).any(axis=0)
    return ~coordinates[:, changed].any(axis=1)
