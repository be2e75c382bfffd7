"""Pass 2: frames from the key postures.

Each track holds its key posture while driven and moves between postures with a
minimum-jerk blend (:mod:`azee_mj.blend`); frames where a blending track still has
constraints (an overlapping block, a transpath path point, a permanent hand shape) are
solved by the :class:`~azee_mj.framesolver.FrameSolver`; trills are added last
(:mod:`azee_mj.trills`). ``Mode.FLATTENED`` (the 2018 method) instead adds keyframes along
each transpath and blends the whole body between them.

Units: seconds, metres, radians.
"""

from __future__ import annotations

import itertools

import numpy as np

from azee_mj import score as sc
from azee_mj.blend import (
    BLEND_SPEED,
    MAX_BLEND,
    MAX_JOINT_SPEED,
    MIN_BLEND,
    MINJERK_PEAK,
    SAME_POSTURE,
    Hold,
    Key,
    minjerk,
    track_curve,
)
from azee_mj.framesolver import (
    CURVE_TOL,
    FRAME_RESTARTS,
    CurvePreference,
    FrameSolver,
    transpath,
)
from azee_mj.ikadapter import IKAdapter
from azee_mj.routes import arc_through, path_points
from azee_mj.schedule import FLAT_FIXED, Mode
from azee_mj.timing import frame_count
from azee_mj.trills import add_trills

__all__ = [
    "BLEND_SPEED",
    "CURVE_TOL",
    "FLAT_PATH_KEYS",
    "FRAME_RESTARTS",
    "MAX_BLEND",
    "MAX_JOINT_SPEED",
    "MINJERK_PEAK",
    "MIN_BLEND",
    "SAME_POSTURE",
    "CurvePreference",
    "Hold",
    "Key",
    "Mode",
    "Motion",
    "arc_through",
    "minjerk",
    "path_points",
]

#: Keyframes the flattened mode puts along a transpath (the 2018 method).
FLAT_PATH_KEYS = 6


class Motion:
    """Frames (pass 2) and trills (pass 3) of the adapter's schedule laid out by ``mode``
    at ``fps`` frames per second."""

    def __init__(self, adapter: IKAdapter, mode: Mode, fps: float):
        self.adapter, self.schedule = adapter, adapter.schedule
        self.mode, self.fps = mode, fps

    def times(self) -> np.ndarray:
        """(T,) frame times [s], ``k / fps``."""
        return np.arange(frame_count(self.schedule.score.duration, self.fps)) / self.fps

    def frames(self, keys: dict[str, list[Key]]) -> np.ndarray:
        """(T, nq) frames through the key postures ``keys`` (per track)."""
        sched = self.schedule
        times = self.times()
        q = np.tile(sched.home, (len(times), 1))
        names = list(sched.track_joints)
        moving = np.zeros((len(times), len(names)), bool)
        flattened = self.mode is Mode.FLATTENED
        for ti, t in enumerate(names):
            d = sched.track_dofs[t]
            carried = self.carried(t, keys)
            q[:, d], moving[:, ti] = track_curve(keys[t], times, d, sched.home, flattened, carried)
        if flattened:
            return self.flat_transpaths(q, times)
        return FrameSolver(self.adapter, self.fps).solve(q, times, moving, names, keys)

    def carried(self, track: str, keys: dict[str, list[Key]]) -> list[float]:
        """End times [s] of other tracks' keys with a constraint that names a body this
        track moves (a hand held in front of the chin is carried by the head track)."""
        return sorted(
            k.end
            for t, tk in keys.items()
            if t != track
            for k in tk
            if any(track in self.schedule.moved_by(c) for c in k.cons)
        )

    def flat_transpaths(self, q: np.ndarray, times: np.ndarray) -> np.ndarray:
        """Flattened mode: a transpath adds keyframes along its path (the 2018 method),
        the whole body blended between them (in place)."""
        ad, sched = self.adapter, self.schedule
        free = tuple(j for t, js in sched.track_joints.items() if t not in FLAT_FIXED for j in js)
        for b in sched.blocks:
            if b.kind is not sc.BlockKind.TRANSPATH:
                continue
            path = transpath(ad, b, q, times)  # on the frames the paths before it left
            sel = np.flatnonzero((times >= b.start) & (times < b.end))
            if not sel.size:
                continue
            n = min(FLAT_PATH_KEYS, sel.size)
            kq = {}
            for f in sel[np.linspace(0, sel.size - 1, n).round().astype(int)]:
                cons = [path.place(f), *ad.soft_targets(q[f], free)]
                kq[f] = ad.solve(cons, free, q[f], times[f]).qpos
            fr = sorted(kq)
            for f0, f1 in itertools.pairwise(fr):
                for f in range(f0, f1):
                    u = minjerk((f - f0) / (f1 - f0))
                    q[f] = kq[f0] + u * (kq[f1] - kq[f0])
            q[fr[-1]] = kq[fr[-1]]
        return q

    def trills(self, q: np.ndarray, times: np.ndarray) -> np.ndarray:
        """Pass 3: every trill added on top of the frames ``q`` (T, nq), in place."""
        return add_trills(self.adapter, q, times)
