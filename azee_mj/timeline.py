"""Blocks scheduled per articulator track, postures solved per segment, frames rolled out.

The realizer (:func:`realize`) works in three steps.

1. **Schedule.** Every constraint drives some tracks of the signer (``spine``, ``head``,
   ``eyes``, ``face``, ``arm_X``, ``hand_X``; see :mod:`azee_mj.schedule`). The block
   boundaries cut the score into segments; in each segment the active constraints are
   grouped into components of tracks they couple (a contact couples both arms).
2. **Key postures.** Segments are solved in time order, each warm-started from the
   postures the tracks hold (rule 1: a later block starts from the posture the earlier one
   set); a component where a block starts with placements and orientations solves the
   placements first (rule 2); a ``hold`` keeps the posture its block reached, as joint
   targets on the tracks that block drove (rule 4: it is solved once that block is).
   Tracks no block drives are not touched.
3. **Frames.** Each track holds its key posture while driven and moves between postures
   with a minimum-jerk blend (continuous velocity, no stop at other tracks' keys), in the
   gap before the next posture or, if there is none, just before the block that changes it.
   Frames where a moving track still has constraints (an overlapping block, a ``transpath``
   path point, a permanent hand shape) are solved as IK problems with the blend as a soft
   target (rule 3: transpaths once both postures exist). Trills are added last, and frames
   whose blend would pass through the body are pushed out by the collision rows.

Each step is a module: :mod:`azee_mj.schedule` (step 1), :mod:`azee_mj.keyposes` (step 2),
:mod:`azee_mj.motion` (step 3), :mod:`azee_mj.rollout` (the result), all solving through
one :class:`~azee_mj.ikadapter.IKAdapter`.

``Mode.FLATTENED`` is the 2018 method for comparison: one whole-body key posture at every
block boundary and a whole-body blend between consecutive keys.

Units: seconds, metres, radians.
"""

from __future__ import annotations

import time as _time
from collections.abc import Callable, Mapping

import numpy as np

from azee_mj import ik, mirror
from azee_mj import score as sc
from azee_mj.anatomy import ACROSS
from azee_mj.ikadapter import IKAdapter
from azee_mj.keyposes import LEAN_STEPS, RELAXING, KeyPoser
from azee_mj.motion import Motion
from azee_mj.preferences import (
    ELBOW_LOW,
    FACING_TOL,
    FACING_TOL_BODY,
    FACING_TOL_ROUNDED,
    FACING_WIDEN,
    MEET_TOL,
    UPRIGHT_TOL_DEG,
)
from azee_mj.rollout import (
    ConstraintTrace,
    Rollout,
    SolveStats,
    constraint_traces,
    site_positions,
    solve_stats,
)
from azee_mj.schedule import Mode, Schedule, make_solver
from azee_mj.sites import DEFAULT_MAP, SignerMap
from azee_mj.timing import check_fps

__all__ = [
    "ACROSS",
    "ELBOW_LOW",
    "FACING_TOL",
    "FACING_TOL_BODY",
    "FACING_TOL_ROUNDED",
    "FACING_WIDEN",
    "LEAN_STEPS",
    "MEET_TOL",
    "RELAXING",
    "UPRIGHT_TOL_DEG",
    "ConstraintTrace",
    "Mode",
    "Rollout",
    "SolveStats",
    "realize",
    "residual_summary",
    "score_traces",
]


def realize(
    score: sc.Score | str | Mapping,
    *,
    fps: float = 50.0,
    mode: Mode | str = Mode.MULTITRACK,
    solver: ik.Solver | None = None,
    signer_map: SignerMap | None = None,
    progress: Callable[[float], None] | None = None,
) -> Rollout:
    """Realize a score: the motion of the signer, frame ``k`` at ``k / fps`` [s].

    Args:
      score: a loaded :class:`~azee_mj.score.Score`, a path or a parsed JSON object.
      fps: frames per second.
      mode: ``multitrack`` (default) or ``flattened`` (the 2018 method, for comparison).
      solver: an :class:`~azee_mj.ik.Solver` to reuse (compiling one takes ~0.1 s; default
        :func:`~azee_mj.schedule.make_solver` for ``signer_map``).
      signer_map: the AZee names of the solver's signer (default: the bundled signer's).
      progress: called with the fraction done (0..1).

    Returns:
      A :class:`Rollout`: ``qpos`` (T, nq), ``site_pos`` (T, S, 3), residual traces, stats.
    """
    t_start = _time.perf_counter()
    if not isinstance(score, sc.Score):
        score = sc.load_score(score)
    mode = Mode(mode) if isinstance(mode, str) else mode
    fps = check_fps(fps, "fps")
    smap = signer_map or DEFAULT_MAP
    solver = solver or make_solver(signer_map=smap)
    tick = progress or (lambda f: None)
    # A left-handed score is realized as the mirror image of its right-handed mirror, so
    # left- and right-handed signing are mirror images by construction.
    flip = mirror.JointMirror.of(solver.model) if score.strong_side == "L" else None
    sched = Schedule(mirror.mirror_score(score) if flip else score, solver, smap)
    adapter = IKAdapter(sched)
    poser = KeyPoser(adapter, mode)
    keys = poser.key_postures()
    n_key = len(adapter.results)
    tick(0.4)
    motion = Motion(adapter, mode, fps)
    q = motion.frames(keys)
    del keys  # their constraints are not needed past the frames
    tick(0.8)
    times = motion.times()
    own, reasons = sched, poser.reasons
    if flip:
        own = Schedule(score, solver, smap)
        reasons = {k: mirror.mirror_words(v) for k, v in reasons.items()}
    # Residuals are those of the postures the blocks ask for: a trill is added on top.
    traces = constraint_traces(own, flip(q) if flip else q, times, fps, reasons)
    q = motion.trills(q, times)
    if flip:
        q = flip(q)
    site_pos = site_positions(solver, smap, q)
    tick(1.0)
    stats = solve_stats(adapter.results, n_key, _time.perf_counter() - t_start)
    return Rollout(fps, mode, times, q, tuple(smap.sites), site_pos, own.intervals(), traces, stats)


def score_traces(
    score: sc.Score | str, qpos: np.ndarray, fps: float, solver: ik.Solver | None = None
) -> tuple[ConstraintTrace, ...]:
    """Residual traces of ``score``'s constraints on given frames ``qpos`` (T, nq)."""
    if not isinstance(score, sc.Score):
        score = sc.load_score(score)
    sched = Schedule(score, solver or make_solver())
    return constraint_traces(sched, np.asarray(qpos, float), np.arange(len(qpos)) / fps, fps)


def residual_summary(
    score: sc.Score | str, rollout: Rollout, solver: ik.Solver | None = None
) -> tuple[str, bool]:
    """A readable residual summary of a rollout's postures against ``score``, and whether
    every constraint is within its tolerance."""
    if not isinstance(score, sc.Score):
        score = sc.load_score(score)
    # A trill moves its block's posture on purpose: its block's residuals are not checked.
    trilled = {
        b.path for b in score.blocks() if any(isinstance(c, sc.Trill) for c in b.constraints)
    }
    traces = [
        t for t in score_traces(score, rollout.qpos, rollout.fps, solver) if t.block not in trilled
    ]
    bad = [t for t in traces if not t.ok]
    lines = [
        f"{len(traces) - len(bad)}/{len(traces)} constraints within tolerance"
        + (f" ({len(trilled)} block(s) with a trill not checked)" if trilled else "")
    ]
    lines += [f"  {t.describe()}" for t in bad[:8]]
    return "\n".join(lines), not bad
