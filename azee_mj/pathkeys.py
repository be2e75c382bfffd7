"""A key posture that leads into a path takes the hand's orientation of the key the path
leads into.

A ``transpath`` moves a site of a hand (a fingertip) from where the arm's key before it
holds it to where the key after it does; the frames in between follow the joint blend of
the two keys, solved onto the path. When the score leaves the first key's hand orientation
free, that key is solved for its placement alone, and its most natural orientation can be
far from the one the second key asks for (*penser* as first written: the index up along the
cheek before the circle, level into the temple after it, 82 degrees apart). The hand then turns over while
the fingertip traces its path: a small fingertip circle becomes a raise and turn of the
whole hand, and the wrist moves with two speed peaks. A signer forms the orientation
before the path and moves the hand along it. So, once every key is solved, such a key is
solved again from the posture of the key after the path, preferring that key's hand
orientation (:class:`HandOrientation`), and kept if it still meets its constraints.

Units: metres, radians.
"""

from __future__ import annotations

import bisect
import dataclasses

import numpy as np

from azee_mj import constraints as cn
from azee_mj import score as sc
from azee_mj.anatomy import descends
from azee_mj.blend import EPS, Key
from azee_mj.ikadapter import IKAdapter
from azee_mj.kinematics import SitePos

#: How far [rad] the hand may turn from the orientation preferred for it before the pull
#: back counts as much as a constraint at its tolerance (a row of 1).
ORIENTATION_TOL = 0.05
#: The hand's local axes whose world directions fix its orientation.
HAND_AXES = ((1.0, 0.0, 0.0), (0.0, 0.0, 1.0))
_LOCAL = np.array(HAND_AXES)
#: Farthest apart [m] the two keys may hold the path's site (about a hand's length) for the
#: first to take the second's hand orientation: between nearby places the arm hardly
#: moves and a signer keeps the hand as it is; across a wide sweep the forearm turns and
#: the hand turns with it.
NEAR_ENDS = 0.1


@dataclasses.dataclass(frozen=True, eq=False)
class HandOrientation:
    """Hand ``body`` turned with its local :data:`HAND_AXES` along ``axes`` (2, 3) (unit
    world directions), as a preference of an IK problem (rows ``(axis - want) / tol``,
    joining the naturalness objective)."""

    body: str
    axes: np.ndarray
    tol: float = ORIENTATION_TOL

    def rows(self, k) -> tuple[np.ndarray, np.ndarray]:
        """Rows (6,) and their Jacobian (6, nv) on the posture of kinematics ``k`` (an
        axis ``a`` turns as ``w x a`` with the body's angular velocity ``w``; asked at
        every iteration of a path's frame solves, so worked out here in one go)."""
        axes = hand_axes(k, self.body)
        w0, w1, w2 = k.body_rot_jac(k.names.body(self.body))  # (3, nv)
        # w x a per column, written out (np.cross's value, without its call cost)
        J = np.vstack(
            [(w1 * a2 - w2 * a1, w2 * a0 - w0 * a2, w0 * a1 - w1 * a0) for a0, a1, a2 in axes]
        )
        return (axes - self.axes).ravel() / self.tol, J / self.tol


def hand_axes(k, body: str) -> np.ndarray:
    """(2, 3) the world directions of hand ``body``'s :data:`HAND_AXES` on kinematics ``k``."""
    return _LOCAL @ body_rotation(k, body).T  # (2, 3): R @ local, per axis


def hand_turn(R0: np.ndarray, R1: np.ndarray, u: np.ndarray) -> np.ndarray:
    """(F, 2, 3) the world directions of :data:`HAND_AXES` of a hand turned from rotation
    ``R0`` to ``R1`` (3, 3; body to world) a fraction ``u`` (F,) of the way, about one
    fixed axis (the shortest turn)."""
    rel = R1 @ R0.T
    w = np.array([rel[2, 1] - rel[1, 2], rel[0, 2] - rel[2, 0], rel[1, 0] - rel[0, 1]])
    sin2 = float(np.linalg.norm(w))  # 2 sin(angle)
    angle = float(np.arctan2(0.5 * sin2, 0.5 * (np.trace(rel) - 1.0)))
    if sin2 > 1e-9:
        n = w / sin2
    elif angle > 0.5 * np.pi:  # half a turn: the axis is the column of rel + I that is not 0
        c = rel + np.eye(3)
        n = c[:, int(np.argmax(np.linalg.norm(c, axis=0)))]
        n = n / np.linalg.norm(n)
    else:
        n = np.zeros(3)
    K = np.array([[0.0, -n[2], n[1]], [n[2], 0.0, -n[0]], [-n[1], n[0], 0.0]])
    local = R0 @ _LOCAL.T  # (3, 2): the axes at the start
    a = np.asarray(u, float)[:, None, None] * angle
    turns = np.eye(3) + np.sin(a) * K + (1.0 - np.cos(a)) * (K @ K)  # (F, 3, 3)
    return np.swapaxes(turns @ local, 1, 2)


def body_rotation(k, body: str) -> np.ndarray:
    """(3, 3) the rotation of ``body`` (body to world) on kinematics ``k``."""
    return k.d.xmat[k.names.body(body)].reshape(3, 3).copy()


def around(keys: list[Key], start: float, end: float) -> tuple[int, int] | None:
    """Indices ``(i, i + 1)`` of a track's ``keys`` (in time order) around a path over
    ``[start, end)`` [s]: key ``i`` ends by the path's start and key ``i + 1`` starts at
    or after its end (no key of the track inside the path); None if there are not two
    such keys, or key ``i`` holds no constraint of its own (a hold, a return to rest)."""
    j = bisect.bisect_left(keys, end - EPS, key=lambda k: k.start)
    if j == 0 or j >= len(keys):
        return None
    before = keys[j - 1]
    if before.end > start + EPS or not before.cons or before.relax:
        return None
    return j - 1, j


def orients(cons, model, arm_root: int) -> bool:
    """Whether constraints ``cons`` orient a bone of the arm whose upper arm is body
    ``arm_root`` of ``model`` (the forearm, the hand, a finger)."""
    return any(
        isinstance(c, cn.Orient) and descends(model, model.body(c.body).id, arm_root) for c in cons
    )


def lead_into_paths(adapter: IKAdapter, keys: dict[str, list[Key]]) -> dict[str, list[Key]]:
    """``keys`` (per track) with each arm key that leads into a transpath of its hand's
    site, leaves the hand's orientation free and holds the site within
    :data:`NEAR_ENDS` of where the key after the path holds it, solved again: from the
    posture of that key, preferring its hand orientation (in place; returned).
    Every track whose key shares the re-solved posture (its group) takes the new one."""
    sched, solver = adapter.schedule, adapter.solver
    model = solver.model
    for b in sched.blocks:
        if b.kind is not sc.BlockKind.TRANSPATH or not b.transpath_site:
            continue
        site = sched.comp.site(b.transpath_site)
        arm = sched.anatomy.hand_of(site)
        if arm is None:
            continue
        for track in sorted(t for t in sched.comp.site_tracks(site) if t.startswith("arm_")):
            pair = around(keys[track], b.start, b.end)
            if pair is None:
                continue
            before, after = (keys[track][i] for i in pair)
            if orients(before.cons, model, model.body(arm.upper).id):
                continue
            ends = [adapter.at(k.q).value(SitePos(site)) for k in (before, after)]
            if np.linalg.norm(ends[1] - ends[0]) > NEAR_ENDS:
                continue
            q = turned(adapter, before, after, arm.hand)
            if q is not None:
                share(keys, before, q)
    return keys


def turned(adapter: IKAdapter, before: Key, after: Key, hand: str) -> np.ndarray | None:
    """Key ``before``'s constraints solved from ``after``'s posture (``before``'s joints),
    preferring ``after``'s orientation of hand body ``hand``: the posture, or None when
    that misses a constraint."""
    d = adapter.dofs(before.free)
    q0 = before.q.copy()
    q0[d] = after.q[d]
    want = HandOrientation(hand, hand_axes(adapter.at(after.q), hand))
    res = adapter.solve(before.cons, before.free, q0, before.start, preferences=(want,))
    return res.qpos if res.converged else None


def share(keys: dict[str, list[Key]], old: Key, q: np.ndarray) -> None:
    """Every key of ``keys`` that holds posture ``old.q`` over ``old``'s span (the keys of
    one group share it) given posture ``q`` instead (in place)."""
    for ks in keys.values():
        i = bisect.bisect_left(ks, old.start - EPS, key=lambda k: k.start)
        if i < len(ks) and ks[i].q is old.q:
            ks[i] = dataclasses.replace(ks[i], q=q)
