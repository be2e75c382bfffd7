"""A realized score: frames, site positions, residual traces and solve statistics.

:class:`Rollout` is what :func:`azee_mj.timeline.realize` returns; :func:`constraint_traces`
measures every place / orient / look constraint of a schedule over its block's frames.

Units: seconds, metres, radians.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np

from azee_mj import constraints as cn
from azee_mj import ik
from azee_mj import score as sc
from azee_mj.frames import Frames, SitePositions
from azee_mj.intervals import IntervalIndex
from azee_mj.schedule import Mode, Schedule, TrackInterval
from azee_mj.sites import SignerMap
from azee_mj.timing import frame_range

__all__ = [
    "ConstraintTrace",
    "Finding",
    "ResidualTable",
    "Rollout",
    "SolveStats",
    "constraint_traces",
    "site_positions",
    "solve_stats",
]


@dataclasses.dataclass(frozen=True)
class ConstraintTrace:
    """The residual of one constraint over the frames of its block's interval.

    Stored sparsely: ``active`` holds the residuals of frames ``first .. first +
    len(active) - 1`` (those inside ``[start, end)``) of ``frames``; :attr:`values` is the
    dense (frames,) view, NaN outside. Unit ``m`` or ``rad``.
    """

    block: str
    index: int
    kind: str
    tol: float
    unit: str
    start: float
    end: float
    first: int
    active: np.ndarray
    frames: int
    #: Why a constraint its key posture could not meet misses ("" if it was met).
    reason: str = ""

    @property
    def values(self) -> np.ndarray:
        """(frames,) residuals, NaN outside the block's frames (built on demand)."""
        out = np.full(self.frames, np.nan)
        out[self.first : self.first + len(self.active)] = self.active
        return out

    @property
    def worst(self) -> float:
        """The largest residual (NaN if a frame's residual is not finite: never ``ok``)."""
        if not np.isfinite(self.active).all():
            return float("nan")
        return float(self.active.max()) if self.active.size else 0.0

    @property
    def ok(self) -> bool:
        return self.worst <= self.tol

    def describe(self) -> str:
        """``BLOCK constraint i (kind): worst X mm (tol Y mm)``, in mm or degrees."""
        k, u = (1000.0, "mm") if self.unit == "m" else (float(np.degrees(1.0)), "deg")
        why = f": {self.reason}" if self.reason and not self.ok else ""
        return (
            f"{self.block} constraint {self.index} ({self.kind}): worst {self.worst * k:.2f}"
            f" {u} (tol {self.tol * k:.2f} {u}){why}"
        )


@dataclasses.dataclass(frozen=True)
class Finding:
    """What the realized motion does that a person would not, and where.

    ``kind`` is ``speed`` (the score's timing makes a transition faster than the human
    range: a wrist above 3 m/s, a joint above 25 rad/s) or ``constraint`` (frames of a block
    where a constraint stays outside its tolerance after the realizer's repairs); ``block``
    the score block it concerns; ``what`` the site, joint or constraint; ``value`` and
    ``limit`` in ``unit``; ``start``, ``end`` [s] the rollout times of the frames concerned
    and ``frames`` how many."""

    kind: str
    block: str
    what: str
    value: float
    limit: float
    unit: str
    start: float
    end: float
    frames: int

    def describe(self) -> str:
        """One line, e.g. ``speed: WR_R 4.20 m/s (limit 3.00) in s2 at 1.10-1.30 s``."""
        k, u = (1000.0, "mm") if self.unit == "m" else (1.0, self.unit)
        if self.unit == "rad":
            k, u = float(np.degrees(1.0)), "deg"
        return (
            f"{self.kind}: {self.what} {self.value * k:.2f} {u} (limit {self.limit * k:.2f}) "
            f"in {self.block} at {self.start:.2f}-{self.end:.2f} s ({self.frames} frame(s))"
        )

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


@dataclasses.dataclass(frozen=True)
class SolveStats:
    """IK work done for a rollout: problems solved, iterations, and wall times [s]."""

    problems: int
    key_problems: int
    iterations: int
    not_converged: int
    solve_time: float
    total_time: float
    per_problem_iterations: np.ndarray


@dataclasses.dataclass(frozen=True)
class Rollout:
    """A realized score.

    Attributes:
      time: (T,) frame times [s], ``k / fps``: the rollout's clock.
      score_start: the rollout time [s] of the score's time 0: frames before it are the
        lead-in from rest (0 without one). Schedule intervals and traces are on the
        rollout's clock (the score's times plus ``score_start``).
      qpos: (T, nq) postures in ``signer.xml`` joint order.
      site_names: (S,) AZee site names; ``site_pos`` (T, S, 3) their positions [m], a
        :class:`~azee_mj.frames.Frames` (computed, or read from a file, a block at a time).
      schedule: per track, the intervals blocks drive it.
      traces: residual of every place / orient / look constraint over its interval.
      findings: what the motion does that a person would not (:class:`Finding`).
    """

    fps: float
    mode: Mode
    time: np.ndarray
    qpos: np.ndarray
    site_names: tuple[str, ...]
    site_pos: np.ndarray | Frames
    schedule: Mapping[str, tuple[TrackInterval, ...]]
    traces: tuple[ConstraintTrace, ...]
    stats: SolveStats
    score_start: float = 0.0
    findings: tuple[Finding, ...] = ()

    def report(self) -> dict:
        """The JSON report: residuals per constraint and block, and timings."""
        s = self.stats
        return {
            "fps": self.fps,
            "mode": self.mode.value,
            "frames": len(self.time),
            "duration_s": float(self.time[-1]) if len(self.time) else 0.0,
            "score_start_s": float(self.score_start),
            "constraints": [
                {
                    "block": t.block,
                    "index": t.index,
                    "kind": t.kind,
                    "unit": t.unit,
                    "tol": float(t.tol),
                    "worst": t.worst if np.isfinite(t.worst) else None,
                    "ok": bool(t.ok),
                    "reason": t.reason,
                }
                for t in self.traces
            ],
            "all_within_tolerance": bool(all(t.ok for t in self.traces)),
            "findings": [f.as_dict() for f in self.findings],
            "schedule": {
                k: [{"block": i.block, "start": i.start, "end": i.end} for i in v]
                for k, v in self.schedule.items()
            },
            "stats": {
                "ik_problems": s.problems,
                "key_problems": s.key_problems,
                "iterations": s.iterations,
                "not_converged": s.not_converged,
                "solve_time_s": s.solve_time,
                "total_time_s": s.total_time,
            },
        }


def constraint_traces(
    schedule: Schedule,
    q: np.ndarray,
    times: np.ndarray,
    fps: float,
    reasons=None,
    lead_frames: int = 0,
    blocks=None,
) -> tuple[ConstraintTrace, ...]:
    """The residual of every place / orient / look constraint of ``schedule`` over the
    frames ``q`` (T, nq) inside its block; ``reasons`` (constraint label -> why its key
    posture misses it) is said on the traces. The score's time 0 is frame ``lead_frames``
    (the traces' times are on the rollout's clock); ``blocks``: only these block paths."""
    return ResidualTable(schedule, q[: len(times)], fps, lead_frames, blocks).traces(reasons)


class ResidualTable:
    """The residual of every place / orient / look constraint of ``schedule``'s blocks (or
    of the block paths ``blocks`` only) at each frame of ``q`` (T, nq) inside its block, the
    score's time 0 at frame ``lead_frames``; kept with the constraints, so that the frames
    the realizer checks (:meth:`misses`) and the traces it reports (:meth:`traces`) are one
    measurement, taken again only at the frames that change (:meth:`update`)."""

    def __init__(self, schedule: Schedule, q: np.ndarray, fps: float, lead_frames=0, blocks=None):
        self.schedule, self.frames, self.shift = schedule, len(q), lead_frames / fps
        comp, self.items = schedule.comp, []
        for b in schedule.blocks:
            if b.kind is not sc.BlockKind.CSTR or (blocks is not None and b.path not in blocks):
                continue
            span = frame_range(b.start, b.end, fps, len(q) - lead_frames)
            frames = range(span.start + lead_frames, span.stop + lead_frames)
            for c in b.constraints:
                ic = comp.constraint(c, f"{b.path}#{c.index}")
                if ic is not None:
                    self.items.append((b, c, ic, frames))
        self.values = residuals(schedule.solver, q, [(ic, f) for _, _, ic, f in self.items])

    def misses(self) -> dict[int, list]:
        """Frame -> the (constraint, tracks it drives) outside their tolerance at that frame,
        in block order, then constraint order; frames ascending."""
        out: dict[int, list] = {}
        for (b, c, ic, span), vals in zip(self.items, self.values):
            for f in (span.start + np.flatnonzero(~(vals <= ic.tol))).tolist():
                out.setdefault(f, []).append((ic, self.schedule.block_tracks(b, c)))
        return dict(sorted(out.items()))

    def update(self, q: np.ndarray, frames) -> None:
        """The residuals at ``frames`` of ``q`` (T, nq) measured again (frames that changed)."""
        spans = IntervalIndex((span.start, span.stop) for _, _, _, span in self.items)
        for f in sorted(frames):
            held = spans.at(f)  # (every constraint asked at every frame: quadratic)
            k = self.schedule.solver.at(q[f]) if held else None
            for i in held:
                span = self.items[i][3]
                self.values[i][f - span.start] = self.items[i][2].residual(k)

    def traces(self, reasons=None) -> tuple[ConstraintTrace, ...]:
        """The traces of the residuals; ``reasons`` (constraint label -> why its key posture
        misses it) is said on them."""
        reasons = reasons or {}
        return tuple(
            ConstraintTrace(
                b.path,
                c.index,
                type(c).__name__.lower(),
                ic.tol,
                "m" if isinstance(ic, cn.Place) else "rad",
                b.start + self.shift,
                b.end + self.shift,
                span.start,
                vals,
                self.frames,
                reasons.get(ic.label, ""),
            )
            for (b, c, ic, span), vals in zip(self.items, self.values)
        )


def residuals(solver: ik.Solver, q: np.ndarray, items) -> list[np.ndarray]:
    """Per ``(constraint, frames)`` of ``items``, its residual at each of those frames of
    ``q`` (T, nq): the kinematics of each frame run once for every constraint. A sweep over
    the frames in order with the constraints whose frames hold them (a table of every
    frame's constraints took about 200 bytes a frame, 36 MB for an hour at 50 fps)."""
    out = [np.empty(len(span)) for _, span in items]
    spans = sorted((span.start, j) for j, (_, span) in enumerate(items) if len(span))
    active: list[int] = []
    nxt, f = 0, 0
    while nxt < len(spans) or active:
        if not active:
            f = max(f, spans[nxt][0])
        while nxt < len(spans) and spans[nxt][0] <= f:
            active.append(spans[nxt][1])
            nxt += 1
        active = sorted(j for j in active if f < items[j][1].stop)
        if not active:
            continue
        k = solver.at(q[f])
        for j in active:
            ic, span = items[j]
            out[j][f - span.start] = ic.residual(k)
        f += 1
    return out


def site_positions(solver: ik.Solver, smap: SignerMap, q: np.ndarray) -> SitePositions:
    """(T, S, 3) world positions [m] of the AZee sites of ``smap`` (in its order) at the
    frames ``q`` (T, nq): computed a block of frames at a time when read or saved, never
    whole in memory (about 16 MB per minute of score at 50 fps)."""
    sids = np.array([solver.site_id(s) for s in smap.sites.values()])
    return SitePositions(solver.model, q, sids)


def solve_stats(results, key_problems: int, total_time: float) -> SolveStats:
    """The statistics of IK ``results`` (anything with ``iterations``, ``converged`` and
    ``time``: :class:`~azee_mj.ik.IKResult`, :class:`~azee_mj.ikadapter.Solved`; the
    first ``key_problems`` of them for key postures), over a realization that took
    ``total_time`` [s]."""
    return SolveStats(
        problems=len(results),
        key_problems=key_problems,
        iterations=sum(x.iterations for x in results),
        not_converged=sum(not x.converged for x in results),
        solve_time=sum(x.time for x in results),
        total_time=total_time,
        per_problem_iterations=np.array([x.iterations for x in results]),
    )
