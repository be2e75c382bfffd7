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

from azee_mj import heap, ik, mirror
from azee_mj import score as sc
from azee_mj.anatomy import ACROSS
from azee_mj.blend import REST_GAP, REST_HOLD
from azee_mj.errors import AzeeError
from azee_mj.findings import constraint_findings, speed_findings
from azee_mj.ikadapter import IKAdapter
from azee_mj.keyposes import LEAN_STEPS, RELAXING, KeyPoser
from azee_mj.motion import Motion, check_room
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
    Finding,
    ResidualTable,
    Rollout,
    SolveStats,
    constraint_traces,
    site_positions,
    solve_stats,
)
from azee_mj.schedule import Mode, Schedule, make_solver, shifted
from azee_mj.sites import DEFAULT_MAP, SignerMap
from azee_mj.timing import check_fps

#: Scores at least this long [s] give the heap back to the system after the key postures and
#: after the frames (:func:`~azee_mj.heap.release`). A shorter score frees a few MB at most,
#: while the collection, the trim and the page faults after it cost a short realization
#: about 5 % of its CPU time.
RELEASE_FROM = 60.0

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
    "RELEASE_FROM",
    "UPRIGHT_TOL_DEG",
    "ConstraintTrace",
    "Finding",
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
    rest: bool = True,
    hold: float = REST_HOLD,
    tempo: float = 1.0,
    rest_gap: float = REST_GAP,
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
      rest: come from rest before the first block (a lead-in timed from its distance, the
        rollout's clock starting ``score_start`` seconds before the score's) and return to
        rest ``hold`` [s] after each track's last block (multitrack). False: each track
        starts in its first posture and keeps its last.
      hold: how long a track holds its last posture before relaxing [s].
      tempo: play the score this many times as fast (block times divided by it).
      rest_gap: with ``rest``, a track whose next block starts at least this long [s]
        after its last one ends returns to rest in between and comes back (when the gap
        also fits ``hold``, both movements and a moment at rest); ``inf``: never.

    Returns:
      A :class:`Rollout`: ``qpos`` (T, nq), ``site_pos`` (T, S, 3), residual traces,
      findings, stats.
    """
    t_start = _time.perf_counter()
    score, mode, fps = checked(score, mode, fps, rest, hold, tempo, rest_gap)
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
    release = heap.release if score.duration >= RELEASE_FROM else lambda: False
    release()  # the solves' scratch, freed among the keys that live on
    n_key = len(adapter.results)
    tick(0.4)
    motion = Motion(adapter, mode, fps, rest, hold, rest_gap)
    q = motion.frames(keys)
    tick(0.8)
    times, lead = motion.times(), motion.lead_frames
    own, reasons = sched, poser.reasons
    if flip:
        own = Schedule(score, solver, smap)
        reasons = {k: mirror.mirror_words(v) for k, v in reasons.items()}
    trilled = trilled_blocks(score)
    # A trill moves its block's posture on purpose: its residuals are those before it.
    shaken = constraint_traces(own, flip(q) if flip else q, times, fps, reasons, lead, trilled)
    q = motion.trills(q, times)
    q, traces = held(motion, own, q, keys, flip, reasons, trilled)
    shift, results = motion.score_start, adapter.results
    del keys, poser, motion, adapter  # grown with the score, and not needed from here
    release()
    traces = tuple(sorted(shaken + traces, key=order_of(own)))
    site_pos = site_positions(solver, smap, q)
    tick(1.0)
    rt = np.arange(len(times)) / fps
    intervals = shifted(own.intervals(), shift)
    found = findings_of(solver, own, rt, q, site_pos, smap, intervals, shift, traces)
    stats = solve_stats(results, n_key, _time.perf_counter() - t_start)
    return Rollout(
        fps, mode, rt, q, tuple(smap.sites), site_pos, intervals, traces, stats, shift, found
    )


def held(motion: Motion, own: Schedule, q, keys, flip, reasons, trilled):
    """The frames ``q`` (T, nq) with every constraint held at every frame of its block
    (:meth:`~azee_mj.motion.Motion.hold_constraints`; not those of the ``trilled`` blocks),
    mirrored by ``flip`` for a left-handed score, and the residual traces of ``own`` (the
    score's schedule) on them. Right-handed, the frames are checked and traced by one
    measurement (:class:`~azee_mj.rollout.ResidualTable`), taken again only at the frames
    the check solves again; left-handed, the traces measure the mirrored frames."""
    times, fps, lead = motion.times(), motion.fps, motion.lead_frames
    rest_of = {b.path for b in own.blocks} - trilled
    if flip:
        q = flip(motion.hold_constraints(q, times, keys, trilled))
        return q, constraint_traces(own, q, times, fps, reasons, lead, rest_of)
    table = ResidualTable(own, q, fps, lead, rest_of)
    misses = table.misses()
    q = motion.hold_constraints(q, times, keys, trilled, misses)
    table.update(q, misses)
    return q, table.traces(reasons)


def at_tempo(score: sc.Score, tempo: float, hold: float) -> sc.Score:
    """``score`` played ``tempo`` times as fast, after checking ``tempo`` and the rest
    ``hold`` [s] (a clean :class:`AzeeError` naming a bad one)."""
    if not (np.isfinite(tempo) and 0.1 <= tempo <= 10.0):
        raise AzeeError(f"tempo must be a number from 0.1 to 10, got {tempo!r}")
    if not (np.isfinite(hold) and 0.0 <= hold <= 10.0):
        raise AzeeError(f"the rest hold must be from 0 to 10 s, got {hold!r}")
    return score.at_tempo(tempo) if tempo != 1.0 else score


def checked(score, mode, fps, rest, hold, tempo, rest_gap) -> tuple[sc.Score, Mode, float]:
    """The score (loaded, at its ``tempo``), the mode and the fps of :func:`realize`, after
    checking every option it takes (a clean :class:`AzeeError` naming a bad one)."""
    if not isinstance(score, sc.Score):
        score = sc.load_score(score)
    score = at_tempo(score, tempo, hold)
    check_gap(rest_gap)
    mode, fps = Mode(mode), check_fps(fps, "fps")
    if rest and mode is Mode.MULTITRACK:
        check_room(score.duration, fps, hold)
    return score, mode, fps


def check_gap(rest_gap: float) -> None:
    """Refuse a rest gap [s] that is not a number from 0 (``inf``: never pause)."""
    if not rest_gap >= 0.0:  # NaN too
        raise AzeeError(
            f"the rest gap must be a number of seconds from 0 (inf: never), got {rest_gap!r}"
        )


def trilled_blocks(score: sc.Score) -> set[str]:
    """Paths of the blocks with a trill (their posture is shaken on purpose)."""
    return {b.path for b in score.blocks() if any(isinstance(c, sc.Trill) for c in b.constraints)}


def order_of(schedule: Schedule):
    """Sort key of traces in the schedule's block order, then constraint index."""
    rank = {b.path: i for i, b in enumerate(schedule.blocks)}
    return lambda t: (rank.get(t.block, 0), t.index)


def findings_of(solver, sched, rt, q, site_pos, smap, intervals, shift, traces):
    """The rollout's findings: speeds over the human range and constraints left."""
    m = solver.model
    joints = {}
    for track, names in sched.track_joints.items():
        for j in names:
            joints[j] = (track, m.jnt_qposadr[solver.joint_id(j)])
    end = shift + sched.score.duration
    out = speed_findings(rt, q, site_pos, list(smap.sites), joints, intervals, shift, end)
    return tuple(out + constraint_findings(list(traces), rt))


def score_traces(
    score: sc.Score | str,
    qpos: np.ndarray,
    fps: float,
    solver: ik.Solver | None = None,
    score_start: float = 0.0,
) -> tuple[ConstraintTrace, ...]:
    """Residual traces of ``score``'s constraints on given frames ``qpos`` (T, nq), the
    score's time 0 at ``score_start`` [s] of their clock."""
    if not isinstance(score, sc.Score):
        score = sc.load_score(score)
    sched = Schedule(score, solver or make_solver())
    q = np.asarray(qpos, float)
    lead = round(score_start * fps)
    return constraint_traces(sched, q, np.arange(len(q)) / fps, fps, lead_frames=lead)


def rollout_speed_findings(
    score: sc.Score, rollout: Rollout, solver: ik.Solver | None = None
) -> tuple[Finding, ...]:
    """The speed findings of a rollout's motion against ``score`` (wrists and joints over
    the human range, each in its block of the rollout's schedule), as ``realize`` finds
    them: what ``check --score`` says too."""
    solver = solver or make_solver()
    sched = Schedule(score, solver)
    joints = {
        j: (track, solver.model.jnt_qposadr[solver.joint_id(j)])
        for track, names in sched.track_joints.items()
        for j in names
    }
    t0 = rollout.score_start
    return tuple(
        speed_findings(
            rollout.time,
            rollout.qpos,
            rollout.site_pos,
            list(rollout.site_names),
            joints,
            rollout.schedule,
            t0,
            t0 + score.duration,
        )
    )


def residual_summary(
    score: sc.Score | str, rollout: Rollout, solver: ik.Solver | None = None
) -> tuple[str, bool]:
    """A readable residual summary of a rollout's postures against ``score``, and whether
    every constraint is within its tolerance."""
    if not isinstance(score, sc.Score):
        score = sc.load_score(score)
    # A trill moves its block's posture on purpose: its block's residuals are not checked.
    trilled = trilled_blocks(score)
    every = score_traces(score, rollout.qpos, rollout.fps, solver, rollout.score_start)
    traces = [t for t in every if t.block not in trilled]
    bad = [t for t in traces if not t.ok]
    lines = [
        f"{len(traces) - len(bad)}/{len(traces)} constraints within tolerance"
        + (f" ({len(trilled)} block(s) with a trill not checked)" if trilled else "")
    ]
    lines += [f"  {t.describe()}" for t in bad[:8]]
    return "\n".join(lines), not bad
