"""Trills: a small sinusoidal shake of a site or a bone added on top of the frames, once
every block's posture is realized (pass 3).

:func:`trill_offset`, :func:`least_squares_step` and :func:`protected_step` are pure;
:func:`add_trills` applies every trill of a schedule to the frames through the kinematics
of each frame. A trill never moves what another block holds at the same time: its step
keeps, to first order, every place, orient and look constraint of the other blocks active
on that frame (a finger trill under a wrist placement is made by the fingers alone).

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
#: Singular values of the held constraints' rows below this fraction of the largest count
#: as zero (their directions stay free).
HELD_RCOND = 1e-9
#: Directions of the protected step whose gain is below this fraction of the trill's
#: unprotected gain are not used (a step along them would be huge).
STEP_RCOND = 1e-3


def trill_envelope(t: np.ndarray, start: float, end: float) -> np.ndarray:
    """The amplitude fraction (0..1) at times ``t`` [s] of a trill over ``[start, end)``:
    ramped linearly over ``TRILL_RAMP`` at both ends."""
    return np.minimum(1.0, np.minimum(t - start, end - t) / TRILL_RAMP)


def trill_offset(amplitude: float, frequency: float, envelope, t, start: float):
    """The trill's displacement at time ``t`` [s] (in its amplitude's unit, m or rad):
    ``amplitude * envelope * sin(2 pi frequency (t - start))``."""
    return amplitude * envelope * np.sin(2 * np.pi * frequency * (t - start))


def least_squares_step(J: np.ndarray, target: np.ndarray) -> np.ndarray:
    """The least-norm joint step ``dq`` with ``J dq = target`` (damped by
    ``TRILL_DAMPING``): ``J^T (J J^T + lambda I)^-1 target``."""
    return J.T @ np.linalg.solve(J @ J.T + TRILL_DAMPING * np.eye(J.shape[0]), target)


def protected_step(J: np.ndarray, A: np.ndarray, target: np.ndarray) -> np.ndarray:
    """The least-norm joint step ``dq`` with ``J dq`` as near ``target`` as it can be while
    ``A dq = 0`` (the rows ``A`` of constraints held elsewhere stay put, to first order):
    ``dq`` in the null space of ``A``, by the pseudo-inverse of ``J`` restricted to it,
    leaving out directions whose gain is under ``STEP_RCOND`` of ``J``'s largest. With no
    rows, :func:`least_squares_step`."""
    if A.shape[0] == 0:
        return least_squares_step(J, target)
    _, s, vt = np.linalg.svd(A)
    rank = int(np.sum(s > HELD_RCOND * s[0])) if s.size else 0
    null = np.eye(J.shape[1]) - vt[:rank].T @ vt[:rank]
    u, g, wt = np.linalg.svd(J @ null, full_matrices=False)
    full = np.linalg.svd(J, compute_uv=False)
    keep = g > STEP_RCOND * max(full[0], 1e-12)
    return wt[keep].T @ ((u[:, keep].T @ target) / g[keep])


def held_constraints(schedule, block, time: float) -> list:
    """The place, orient and look constraints (solver records) of the blocks other than
    ``block`` active at ``time`` [s]: what a trill there must leave where it is."""
    out = []
    for b in schedule.blocks:
        if b is block or b.kind is not sc.BlockKind.CSTR or not b.start <= time < b.end:
            continue
        for c in b.constraints:
            ic = schedule.comp.constraint(c, f"{b.path}#{c.index}")
            if ic is not None:
                out.append(ic)
    return out


def _trill_dofs(sched, c, held: bool) -> tuple[list[str], np.ndarray]:
    """The tracks a trill moves and their dofs: those of its site or bone; when other
    blocks hold something then (``held``), the tracks of the trilled body itself instead
    (a finger trill under a held wrist is made by the fingers, not by turning the hand)."""
    tracks = set(sched.comp.tracks_of(c))
    if held:
        solver = sched.solver
        body = (
            int(solver.model.site_bodyid[solver.site_id(sched.comp.site(c.site))])
            if c.site is not None
            else solver.body_id(c.bone.model_body(sched.smap))
        )
        tracks = sched.comp.body_tracks(body, own_only=True) or tracks
    tracks = sorted(tracks)
    return tracks, np.concatenate([sched.track_dofs[t] for t in tracks])


def add_trills(adapter: IKAdapter, q: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Every trill of the adapter's schedule added on top of the frames ``q`` (T, nq) at
    ``times`` [s], in place: the trilled site or bone moves by the trill's offset along its
    vector (a least-squares step of the tracks it drives that keeps what other blocks hold
    then, :func:`protected_step`, within the joint ranges); a frame the shake would push
    through the body is solved back out, near the shake, still keeping what is held."""
    sched, solver = adapter.schedule, adapter.solver
    comp, smap = sched.comp, sched.smap
    for b in sched.blocks:
        if b.kind is not sc.BlockKind.CSTR:
            continue
        for c in b.constraints:
            if not isinstance(c, sc.Trill):
                continue
            sel = np.flatnonzero((times >= b.start) & (times < b.end))
            vector = compile_vector(c.vector, smap)
            for f, env in zip(sel, trill_envelope(times[sel], b.start, b.end)):
                held = held_constraints(sched, b, times[f])
                tracks, dofs = _trill_dofs(sched, c, bool(held))
                k = adapter.at(q[f], jacobians=True)
                v = k.value(vector)
                v = v / np.linalg.norm(v)
                a = trill_offset(c.amplitude, c.frequency, env, times[f], b.start)
                if c.site is not None:
                    jac = k.site(solver.site_id(comp.site(c.site)))[1]
                else:
                    jac = k.body_rot_jac(solver.body_id(c.bone.model_body(smap)))
                rows = [ic.rows(k)[1][:, dofs] for ic in held]
                A = np.vstack(rows) if rows else np.zeros((0, len(dofs)))
                dq = protected_step(jac[:, dofs], A, a * v)
                q[f, dofs] = np.clip(q[f, dofs] + dq, solver.lower[dofs], solver.upper[dofs])
                if adapter.penetrates(q[f], times[f]):  # the shake must not go through
                    joints = {j for t in tracks for j in sched.track_joints[t]}
                    soft = adapter.soft_targets(q[f], joints)
                    q[f] = adapter.solve([*held, *soft], sorted(joints), q[f], times[f]).qpos
    return q
