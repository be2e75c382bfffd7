"""Trills: a small sinusoidal shake of a site or a bone added on top of the frames, once
every block's posture is realized (pass 3).

:func:`trill_offset` and :func:`least_squares_step` are pure; :func:`add_trills` applies
every trill of a schedule to the frames through the kinematics of each frame.

Units: seconds, metres, radians, hertz.
"""

from __future__ import annotations

import numpy as np

from azee_mj import score as sc
from azee_mj.ikadapter import IKAdapter
from azee_mj.kinematics import compile_vector

#: How long a trill's amplitude takes to ramp up at its start and down at its end [s].
TRILL_RAMP = 0.05
#: Damping of the least-squares step that moves a site or bone by a trill's offset.
TRILL_DAMPING = 1e-6
#: Largest excursion [rad] of a finger joint shaking a trill: the step's damping is chosen
#: from the amplitude so that no step goes further (``|dq| <= |target| / (2 sqrt(damping))``),
#: however folded the finger (a fist's fingertip cannot move up without a large turn).
FINGER_TRILL_MAX = 0.25


def trill_envelope(t: np.ndarray, start: float, end: float) -> np.ndarray:
    """The amplitude fraction (0..1) at times ``t`` [s] of a trill over ``[start, end)``:
    ramped linearly over ``TRILL_RAMP`` at both ends."""
    return np.minimum(1.0, np.minimum(t - start, end - t) / TRILL_RAMP)


def trill_offset(amplitude: float, frequency: float, envelope, t, start: float):
    """The trill's displacement at time ``t`` [s] (in its amplitude's unit, m or rad):
    ``amplitude * envelope * sin(2 pi frequency (t - start))``."""
    return amplitude * envelope * np.sin(2 * np.pi * frequency * (t - start))


def least_squares_step(
    J: np.ndarray, target: np.ndarray, damping: float = TRILL_DAMPING
) -> np.ndarray:
    """The least-norm joint step ``dq`` with ``J dq = target`` (damped by ``damping``,
    lambda): ``J^T (J J^T + lambda I)^-1 target``."""
    return J.T @ np.linalg.solve(J @ J.T + damping * np.eye(J.shape[0]), target)


def held_step(
    J: np.ndarray, H: np.ndarray, target: np.ndarray, damping: float = TRILL_DAMPING
) -> np.ndarray:
    """The least-norm joint step ``dq`` with ``J dq = target`` among those with ``H dq = 0``
    (rows ``H``: placements held meanwhile): the least-squares step of ``J N`` (damped by
    ``damping``) with ``N`` the projector onto the null space of ``H``. Without rows in
    ``H``, :func:`least_squares_step`."""
    if not len(H):
        return least_squares_step(J, target, damping)
    N = np.eye(J.shape[1]) - least_squares_step(H, np.eye(len(H))) @ H
    return N @ least_squares_step(J @ N, target, damping)


def holders(sched, block: sc.Block) -> list[tuple[float, float, object, frozenset]]:
    """(start, end [s], constraint, tracks it drives) of every placement and orientation
    of the cstr blocks other than ``block``: what may hold a trill's limb while it shakes."""
    return [
        (b.start, b.end, dc.con, frozenset(dc.tracks))
        for b in sched.blocks
        if b is not block and b.kind is sc.BlockKind.CSTR
        for dc in sched.block_constraints(b)
        if dc.con is not None
    ]


def held_rows(k, held, dofs: np.ndarray) -> np.ndarray:
    """(k, len(dofs)) the Jacobian rows, over ``dofs``, of the constraints ``held`` on
    kinematics ``k``: a trill shakes its site without moving them (a fingertip flickering
    while its hand is placed and oriented: the fingers, not the arm)."""
    rows = [con.rows(k)[1][:, dofs] for con in held]
    return np.concatenate(rows) if rows else np.zeros((0, len(dofs)))


def add_trills(adapter: IKAdapter, q: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Every trill of the adapter's schedule added on top of the frames ``q`` (T, nq) at
    ``times`` [s], in place: the trilled site or bone moves by the trill's offset along its
    vector, a least-squares step of the tracks it drives within the joint ranges; when
    other blocks then active hold those tracks (:func:`holders`), a step that keeps them
    the site's hand free to move too (a fingertip flickers with its finger); a
    frame the shake would push through the body is solved back out, near the shake."""
    sched, solver = adapter.schedule, adapter.solver
    comp, smap = sched.comp, sched.smap
    for b in sched.blocks:
        if b.kind is not sc.BlockKind.CSTR:
            continue
        for c in b.constraints:
            if not isinstance(c, sc.Trill):
                continue
            tracks = sorted(comp.tracks_of(c))
            dofs = np.concatenate([sched.track_dofs[t] for t in tracks])
            sid = solver.site_id(comp.site(c.site)) if c.site is not None else None
            body = (
                int(solver.model.site_bodyid[sid])
                if sid is not None
                else solver.body_id(c.bone.model_body(smap))
            )
            hand = {t for t in comp.body_tracks(body, own_only=False) if t.startswith("hand")}
            fingers = np.concatenate([sched.track_dofs[t] for t in sorted(hand)]) if hand else None
            others = holders(sched, b) if hand else []
            finger_damping = (c.amplitude / (2.0 * FINGER_TRILL_MAX)) ** 2
            sel = np.flatnonzero((times >= b.start) & (times < b.end))
            vector = compile_vector(c.vector, smap)
            for f, env in zip(sel, trill_envelope(times[sel], b.start, b.end)):
                k = adapter.at(q[f], jacobians=True)
                v = k.value(vector)
                v = v / np.linalg.norm(v)
                a = trill_offset(c.amplitude, c.frequency, env, times[f], b.start)
                if sid is not None:
                    jac = k.site(sid)[1]
                else:
                    jac = k.body_rot_jac(body)
                now = [(con, tr) for t0, t1, con, tr in others if t0 <= times[f] < t1]
                shake = dofs
                if any(tr.intersection(tracks) for _, tr in now):
                    # another block holds the limb: the fingers shake the site
                    shake = fingers
                    held = held_rows(k, [con for con, tr in now if tr & hand], shake)
                    dq = held_step(jac[:, shake], held, a * v, finger_damping)
                else:
                    dq = least_squares_step(jac[:, shake], a * v)
                q[f, shake] = np.clip(q[f, shake] + dq, solver.lower[shake], solver.upper[shake])
                if adapter.penetrates(q[f], times[f]):  # the shake must not go through
                    joints = {j for t in tracks for j in sched.track_joints[t]}
                    soft = adapter.soft_targets(q[f], joints)
                    q[f] = adapter.solve(soft, sorted(joints), q[f], times[f]).qpos
    return q
