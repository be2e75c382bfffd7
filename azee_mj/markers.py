"""What to draw over a frame, without a window or a GL context.

:class:`Clip` is a motion to show (a rollout, with or without its score), read by
:func:`load_clip` from a score or a rollout file. :func:`markers` lists what to draw over one
frame (constraint targets, red where a constraint is over its tolerance, penetrating
contacts) as :class:`Marker` records, and :func:`add_markers` turns them into ``mjvGeom`` s
of an ``mjvScene``. Units: metres, seconds.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import mujoco
import numpy as np

from azee_mj import constraints as cn
from azee_mj import ik
from azee_mj import score as sc
from azee_mj.errors import AzeeError
from azee_mj.kinematics import Unit
from azee_mj.model import load_model
from azee_mj.rollout_io import load_rollout, realized_score
from azee_mj.schedule import Compiler, TrackInterval, make_solver, schedule, shifted
from azee_mj.sites import DEFAULT_MAP, SignerMap
from azee_mj.timeline import realize
from azee_mj.timing import DEFAULT_FPS

#: Contacts deeper than this are drawn red [m] (the IK solver's penetration limit).
PENETRATION = cn.PENETRATION_LIMIT
#: Length of an orientation arrow [m].
ARROW_LENGTH = 0.12

_GREEN = (0.15, 0.85, 0.25, 0.7)
_BLUE = (0.2, 0.45, 1.0, 0.8)
_YELLOW = (1.0, 0.85, 0.1, 0.8)
_RED = (1.0, 0.1, 0.1, 0.9)


# ---------------------------------------------------------------------------------------
# What is played: a rollout, with or without its score
# ---------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Clip:
    """A motion to show.

    Attributes:
      time: (T,) frame times [s]; ``qpos`` (T, nq) postures; ``fps`` frames per second.
      schedule: per track, the intervals blocks drive it (empty without a score).
      score: the realized score, or None (then no targets are drawn).
      name: a label (the input file's stem).
      score_start: the time [s] of the score's time 0 on the clip's clock (the lead-in from
        rest before it); ``schedule`` is on the clip's clock.
    """

    time: np.ndarray
    qpos: np.ndarray
    fps: float
    schedule: Mapping[str, tuple[TrackInterval, ...]]
    score: sc.Score | None = None
    name: str = ""
    score_start: float = 0.0

    @property
    def duration(self) -> float:
        """Time of the last frame [s]."""
        return float(self.time[-1]) if len(self.time) else 0.0

    @classmethod
    def from_rollout(cls, rollout, score: sc.Score | None = None, name: str = "") -> Clip:
        """A clip of a :class:`~azee_mj.timeline.Rollout`."""
        r = rollout
        return cls(r.time, r.qpos, float(r.fps), r.schedule, score, name, float(r.score_start))

    def frame_at(self, t: float) -> int:
        """Index of the frame nearest to time ``t`` [s]."""
        return int(np.clip(round(t * self.fps), 0, len(self.time) - 1))

    def active_blocks(self, frame: int) -> dict[str, str]:
        """Per track, the block driving it at ``frame`` ('' when none)."""
        t = float(self.time[frame])
        out = {}
        for track, ivs in self.schedule.items():
            names = [
                i.block
                for i in ivs
                if i.start - 1e-9 <= t < i.end - 1e-9
                or (t >= i.end - 1e-9 and i.end >= self.duration - 1e-9 and i.start <= t)
            ]
            out[track] = names[-1] if names else ""
        return out


def schedule_of(score: sc.Score) -> dict[str, tuple[TrackInterval, ...]]:
    """Per track, the intervals blocks of ``score`` drive it, without solving anything."""
    return schedule(score, shared_solver())


_SOLVER: ik.Solver | None = None


def shared_solver() -> ik.Solver:
    global _SOLVER
    if _SOLVER is None:
        _SOLVER = make_solver()
    return _SOLVER


def load_clip(
    path: str | os.PathLike,
    *,
    score: str | os.PathLike | None = None,
    fps: float = DEFAULT_FPS,
    progress: Callable[[float], None] | None = None,
    blinks: int | None = None,
    blink_rate: float | None = None,
) -> Clip:
    """A clip from ``SCORE.json`` (realized at ``fps`` [frames/s], with automatic blinks
    drawn from seed ``blinks`` if given, ``blink_rate`` a minute) or ``ROLLOUT.npz`` (with
    an optional ``score`` for targets and the schedule)."""
    path = Path(path)
    if path.suffix.lower() == ".json":
        s = sc.load_score(path)
        if blinks is not None:
            from azee_mj.blinks import add_blinks

            s = add_blinks(s, blinks, **({} if blink_rate is None else {"rate": blink_rate}))
        rollout = realize(s, fps=fps, solver=shared_solver(), progress=progress)
        return Clip.from_rollout(rollout, s, path.stem)
    if path.suffix.lower() != ".npz":
        raise AzeeError(
            f"{path}: expected a SCORE.json or a ROLLOUT.npz, got suffix {path.suffix!r}"
        )
    r = load_rollout(path, load_model().nq)
    given = realized_score(sc.load_score(Path(score)), path) if score else None
    sched = shifted(schedule_of(given), r.score_start) if given is not None else {}
    return Clip(r.time, r.qpos, r.fps, sched, given, path.stem, r.score_start)


# ---------------------------------------------------------------------------------------
# Decorations: pure functions, no window
# ---------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Marker:
    """One thing drawn over a frame.

    Attributes:
      kind: ``sphere`` (a place target), ``arrow`` (an orient vector, from the bone's
        origin), ``line`` (gaze, from between the eyes to the looked-at point) or
        ``contact`` (a penetrating contact).
      label: ``BLOCK#index`` of the constraint, or ``geom1|geom2`` of a contact.
      pos: (3,) sphere centre, or where the arrow / line starts [m].
      end: (3,) where the arrow / line ends (None for spheres) [m].
      residual: the constraint's error in its unit ([m] or [rad]); a contact's depth [m].
      violated: over tolerance (drawn red).
    """

    kind: str
    label: str
    pos: np.ndarray
    end: np.ndarray | None
    residual: float
    violated: bool


@dataclasses.dataclass(frozen=True)
class _Target:
    block: str
    index: int
    start: float
    end: float
    con: cn.Place | cn.Orient | cn.Look


class Targets:
    """The place / orient / look constraints of a score, as IK constraints with their
    blocks' intervals (compiled once by :class:`~azee_mj.schedule.Compiler`)."""

    def __init__(
        self, score: sc.Score, solver: ik.Solver | None = None, signer_map: SignerMap = DEFAULT_MAP
    ):
        self.solver = solver or shared_solver()
        comp = Compiler(self.solver.model, signer_map)
        out = []
        for b in score.blocks():
            if b.kind is not sc.BlockKind.CSTR:
                continue
            for c in b.constraints:
                ic = comp.constraint(c, f"{b.path}#{c.index}")
                if ic is not None:
                    out.append(_Target(b.path, c.index, b.start, b.end, ic))
        self.items: tuple[_Target, ...] = tuple(out)
        self.duration = score.duration

    def active(self, t: float) -> list[_Target]:
        """Targets whose block holds at time ``t`` [s] (the last frame keeps its blocks)."""
        eps = 1e-9
        return [
            x
            for x in self.items
            if x.start - eps <= t < x.end - eps
            or (t >= self.duration - eps and x.end >= self.duration - eps)
        ]


def markers(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    clip: Clip,
    frame: int,
    targets: Targets | None = None,
) -> list[Marker]:
    """What to draw over ``frame``: one marker per active constraint target, then one per
    penetrating contact. Sets ``data.qpos`` to the frame and runs kinematics and collision
    on ``model`` (the scene); targets are evaluated on ``targets.solver``'s own data."""
    q = clip.qpos[frame]
    out: list[Marker] = []
    if targets is not None:
        s = targets.solver
        s.data.qpos[:] = q
        mujoco.mj_kinematics(s.model, s.data)
        kin = s.kinematics()
        for x in targets.active(float(clip.time[frame]) - clip.score_start):
            c = x.con
            res = c.residual(kin)
            bad = res > c.tol
            label = f"{x.block}#{x.index}"
            if isinstance(c, cn.Place):
                p = kin.value(c.target)
                out.append(Marker("sphere", label, p, None, res, bad))
            elif isinstance(c, cn.Orient):
                v = kin.value(Unit(c.vector))
                if c.rel is cn.Rel.OPP:
                    v = -v
                o = s.data.xpos[s.body_id(c.body)].copy()
                out.append(Marker("arrow", label, o, o + ARROW_LENGTH * v, res, bad))
            else:  # Look
                eyes = np.mean([s.data.xpos[s.body_id(b)] for b, _ in c.eyes], axis=0)
                p = kin.value(c.target)
                out.append(Marker("line", label, eyes, p, res, bad))
    data.qpos[:] = q
    mujoco.mj_kinematics(model, data)
    mujoco.mj_collision(model, data)
    for i in range(data.ncon):
        con = data.contact[i]
        if con.dist < -PENETRATION:
            g1 = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, con.geom[0]) or str(con.geom[0])
            g2 = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, con.geom[1]) or str(con.geom[1])
            out.append(
                Marker("contact", f"{g1}|{g2}", con.pos.copy(), None, -float(con.dist), True)
            )
    return out


def add_markers(scn: mujoco.MjvScene, items: Sequence[Marker]) -> int:
    """Append ``mjvGeom`` s for ``items`` to ``scn`` (while it has room); returns how many."""
    n = 0
    for mk in items:
        if scn.ngeom >= scn.maxgeom:
            break
        g = scn.geoms[scn.ngeom]
        if mk.kind in ("sphere", "contact"):
            size = 0.012 if mk.kind == "sphere" else 0.008
            rgba = _RED if mk.violated else (_GREEN if mk.kind == "sphere" else _RED)
            mujoco.mjv_initGeom(
                g,
                mujoco.mjtGeom.mjGEOM_SPHERE,
                np.array([size, 0, 0]),
                np.asarray(mk.pos, float),
                np.eye(3).ravel(),
                np.array(rgba, np.float32),
            )
        else:
            rgba = _RED if mk.violated else (_BLUE if mk.kind == "arrow" else _YELLOW)
            typ = mujoco.mjtGeom.mjGEOM_ARROW if mk.kind == "arrow" else mujoco.mjtGeom.mjGEOM_LINE
            mujoco.mjv_initGeom(
                g, typ, np.zeros(3), np.zeros(3), np.eye(3).ravel(), np.array(rgba, np.float32)
            )
            width = 0.006 if mk.kind == "arrow" else 3.0
            mujoco.mjv_connector(
                g, typ, width, np.asarray(mk.pos, float), np.asarray(mk.end, float)
            )
        g.category = mujoco.mjtCatBit.mjCAT_DECOR
        scn.ngeom += 1
        n += 1
    return n


def frame_text(clip: Clip, frame: int, speed: float = 1.0, paused: bool = False) -> tuple[str, str]:
    """The overlay of a frame: (left column, right column), one line per row."""
    left = ["time", "frame"]
    right = [f"{clip.time[frame]:.3f} / {clip.duration:.3f} s", f"{frame} / {len(clip.time) - 1}"]
    left.append("speed")
    right.append(f"{speed:g}x" + (" (paused)" if paused else ""))
    for track, block in clip.active_blocks(frame).items():
        left.append(track)
        right.append(block or "-")
    return "\n".join(left), "\n".join(right)
