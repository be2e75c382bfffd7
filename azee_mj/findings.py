"""Findings: where a realized motion leaves the human range or a constraint of its block.

The realizer does not clamp speeds: where the score's own timing fixes a transition, the
signer moves at the speed it needs. :func:`speed_findings` names the block and the speed
wherever a wrist goes faster than :data:`WRIST_LIMIT` or a joint turns faster than
:data:`JOINT_LIMIT`; :func:`constraint_findings` names the frames at which a constraint
stays outside its tolerance. Pure functions on arrays and records.

Units: seconds, metres, radians.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping

import numpy as np

from azee_mj.movement import runs
from azee_mj.rollout import ConstraintTrace, Finding
from azee_mj.schedule import TrackInterval

#: Fastest a wrist moves in signing [m/s].
WRIST_LIMIT = 3.0
#: Fastest a joint turns in signing [rad/s].
JOINT_LIMIT = 25.0
#: The wrist sites checked, and the arm track that moves each.
WRISTS = {"WR_R": "arm_R", "WR_L": "arm_L"}


def frame_speeds(x: np.ndarray, fps: float) -> np.ndarray:
    """(T,) speed of each frame [unit/s]: the larger of the steps into and out of it, over
    the frame period, from positions ``x`` (T, ...) (norm over the rest of the axes)."""
    if len(x) < 2:
        return np.zeros(len(x))
    return _larger_step(np.linalg.norm(np.diff(x, axis=0).reshape(len(x) - 1, -1), axis=1) * fps)


def _larger_step(d: np.ndarray) -> np.ndarray:
    """(T,) each frame's larger of its steps in and out, from the (T - 1,) steps ``d``."""
    step = np.zeros(len(d) + 1)
    step[1:] = d
    step[:-1] = np.maximum(step[:-1], d)
    return step


def block_at(intervals, t: float, score_start: float, end: float) -> str:
    """The block a movement at rollout time ``t`` [s] belongs to among one track's
    ``intervals`` (rollout clock): the one it moves into (the first starting at or after
    it), else the last that started; before the score's start the lead-in, after ``end``
    (the score's end on the rollout clock) with no block left the return to rest."""
    after = [i for i in intervals if i.start >= t - 1e-9]
    if t < score_start - 1e-9 and not any(i.start <= t for i in intervals):
        return "lead-in"
    if after:
        return after[0].block
    if t > end + 1e-9 or not intervals:
        return "return to rest"
    return intervals[-1].block


def site_speeds(site_pos, sites: list[int], fps: float) -> list[np.ndarray]:
    """Per site of ``sites``, its (T,) :func:`frame_speeds` [m/s] from ``site_pos``
    (T, S, 3), a block of frames at a time (a lazy :class:`~azee_mj.frames.Frames` is never
    whole, and no (T, len(sites), 3) copy is made): the same values."""
    blocks = (
        site_pos.blocks()
        if hasattr(site_pos, "blocks")
        else ((a, site_pos[a : a + 4096]) for a in range(0, len(site_pos), 4096))
    )
    d, last, n = [], None, 0
    for _, b in blocks:
        x = np.asarray(b)[:, sites]
        n += len(x)
        if last is not None:
            x = np.concatenate([last, x])
        if len(x) > 1:
            d.append(np.linalg.norm(np.diff(x, axis=0), axis=2) * fps)
        last = x[-1:]
    if n < 2:
        return [np.zeros(n) for _ in sites]
    steps = np.concatenate(d)
    return [_larger_step(steps[:, k]) for k in range(len(sites))]


def speed_findings(
    rollout_time: np.ndarray,
    qpos: np.ndarray,
    site_pos: np.ndarray,
    site_names,
    joints: Mapping[str, tuple[str, np.ndarray]],
    schedule: Mapping[str, tuple[TrackInterval, ...]],
    score_start: float,
    score_end: float,
) -> list[Finding]:
    """Wrists over :data:`WRIST_LIMIT` and joints over :data:`JOINT_LIMIT`, one finding per
    run of frames, at the run's fastest frame. ``joints``: joint name -> (its track, its
    qpos addresses); ``schedule`` the tracks' intervals on the rollout clock; the score
    runs over ``[score_start, score_end]`` on it."""
    if len(rollout_time) < 2:
        return []
    fps = 1.0 / float(rollout_time[1] - rollout_time[0])
    out = []
    wrists = [site for site in WRISTS if site in site_names]
    speeds = site_speeds(site_pos, [site_names.index(site) for site in wrists], fps)
    # one speed series at a time: all of them at once are as large as the postures
    fast = turning_fast(qpos, [adr for _, adr in joints.values()], JOINT_LIMIT / fps)
    checks = itertools.chain(
        ((site, WRISTS[site], v, "m/s") for site, v in zip(wrists, speeds)),
        (
            (j, tr, frame_speeds(qpos[:, adr], fps), "rad/s")
            for (j, (tr, adr)), f in zip(joints.items(), fast)
            if f
        ),
    )
    for what, track, v, unit in checks:
        limit = WRIST_LIMIT if unit == "m/s" else JOINT_LIMIT
        for f0, f1 in runs(v > limit):
            peak = f0 + int(np.argmax(v[f0 : f1 + 1]))
            t = float(rollout_time[peak])
            block = block_at(schedule.get(track, ()), t, score_start, score_end)
            out.append(
                Finding(
                    "speed",
                    block,
                    what,
                    float(v[peak]),
                    limit,
                    unit,
                    float(rollout_time[f0]),
                    float(rollout_time[f1]),
                    f1 - f0 + 1,
                )
            )
    return sorted(out, key=lambda x: (x.start, x.what))


def turning_fast(qpos: np.ndarray, adrs: list, step: float, block: int = 4096) -> np.ndarray:
    """(len(adrs),) whether the joint at each qpos address of ``adrs`` changes by more than
    ``step`` (less a relative 1e-9: a screen, never missing a joint whose speed is over the
    limit by rounding) between some two frames of ``qpos`` (T, nq); a block of frames at a
    time (the columns of every frame at once would be as large as the postures)."""
    out = np.zeros(len(adrs), bool)
    for a in range(0, max(len(qpos) - 1, 0), block):
        part = qpos[a : a + block + 1, adrs]
        out |= (np.abs(np.diff(part, axis=0)) > step * (1.0 - 1e-9)).any(axis=0)
    return out


def leaving(traces) -> np.ndarray:
    """(T,) frames at which some constraint of ``traces`` is outside its tolerance."""
    if not traces:
        return np.zeros(0, bool)
    bad = np.zeros(traces[0].frames, bool)
    for tr in traces:
        a = np.asarray(tr.active)
        bad[tr.first : tr.first + len(a)] |= ~(a <= tr.tol)
    return bad


def constraint_findings(traces: list[ConstraintTrace], rollout_time: np.ndarray) -> list[Finding]:
    """One finding per constraint outside its tolerance at some frame of its block: its
    worst residual and the frames it is out."""
    out = []
    for tr in traces:
        a = np.asarray(tr.active)
        bad = ~(a <= tr.tol)
        if not bad.any():
            continue
        f = tr.first + np.flatnonzero(bad)
        out.append(
            Finding(
                "constraint",
                tr.block,
                f"constraint {tr.index} ({tr.kind})",
                tr.worst,
                tr.tol,
                tr.unit,
                float(rollout_time[f[0]]),
                float(rollout_time[f[-1]]),
                int(bad.sum()),
            )
        )
    return out
