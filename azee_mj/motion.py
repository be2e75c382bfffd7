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

import bisect
import dataclasses
import itertools
import math

import numpy as np

from azee_mj import constraints as cn
from azee_mj import movement as mv
from azee_mj import score as sc
from azee_mj.blend import (
    BLEND_SPEED,
    BRANCH_SPEED,
    EPS,
    MAX_BLEND,
    MAX_JOINT_SPEED,
    MAX_REST_MOVE,
    MIN_BLEND,
    MIN_LEAD,
    MIN_RELAX,
    MINJERK_PEAK,
    REST_GAP,
    REST_HOLD,
    REST_JOINT_SPEED,
    REST_SPEED,
    REST_STAY,
    SAME_POSTURE,
    Columns,
    Hold,
    Key,
    Pause,
    Rest,
    holds_of,
    minjerk,
    pause_between,
    rest_duration,
    track_curve,
)
from azee_mj.detour import Detour
from azee_mj.detour import runs as runs_of
from azee_mj.errors import AzeeError
from azee_mj.framesolver import (
    CURVE_TOL,
    FRAME_RESTARTS,
    CurvePreference,
    FrameSolver,
    transpath,
)
from azee_mj.ikadapter import IKAdapter
from azee_mj.intervals import IntervalIndex
from azee_mj.pacing import SMOOTHING, paced, resample, smoothed
from azee_mj.routes import arc_through, path_points
from azee_mj.schedule import FLAT_FIXED, Mode
from azee_mj.timing import MAX_FRAMES, frame_count, frame_range
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
    "MIN_LEAD",
    "MIN_RELAX",
    "REST_GAP",
    "REST_HOLD",
    "REST_JOINT_SPEED",
    "REST_SPEED",
    "REST_STAY",
    "SAME_POSTURE",
    "CurvePreference",
    "Hold",
    "Key",
    "Mode",
    "Motion",
    "Pause",
    "Rest",
    "arc_through",
    "minjerk",
    "path_points",
]

#: A movement this smooth (SPARC of its sites' summed speed; minimum jerk gives -1.40)
#: is one bell already: it is not paced again.
BELL_SPARC = -1.42
#: How far [m] a site of a paced frame may be from its path (the polyline of its frames)
#: where the joints between two frames were interpolated.
RESAMPLE_TOL = 2e-3
#: Most of a paced movement's frames that may be pushed out of the body one by one.
MAX_PUSHED = 0.5
#: How much faster than a minimum-jerk bell along its own path a site of a paced movement
#: may peak (where it peaks faster than the frames did): the joints' turns and the power
#: law share the bell with the sites.
BELL_MARGIN = 1.1
#: Keyframes the flattened mode puts along a transpath (the 2018 method).
FLAT_PATH_KEYS = 6


def coupled(runs: list[tuple]) -> list[list[tuple]]:
    """``runs`` ``(a, b, ...)`` grouped: those over the same frames (within one at either
    end) together, spanning the widest."""
    groups: list[list[tuple]] = []
    firsts: list[int] = []  # each group's first start, ascending (the runs are sorted)
    for r in sorted(runs, key=lambda r: r[:2]):
        # only groups starting at r[0] - 1 or later can take it (not a scan of them all)
        for g in groups[bisect.bisect_left(firsts, r[0] - 1) :]:
            if abs(g[0][0] - r[0]) <= 1 and abs(g[0][1] - r[1]) <= 1:
                g.append(r)
                break
        else:
            groups.append([r])
            firsts.append(r[0])
    out = []
    for g in groups:
        a, b = min(r[0] for r in g), max(r[1] for r in g)
        out.append([(a, b, *r[2:]) for r in g])
    return out


class Pacer:
    """Paces the movements of the arms in frames solved at ``fps`` frames per second
    through ``adapter`` (:func:`~azee_mj.pacing.paced`): each movement keeps its path,
    its start and its end, and the frames held under a constraint keep their postures."""

    def __init__(self, adapter: IKAdapter, fps: float):
        self.adapter, self.schedule, self.fps = adapter, adapter.schedule, fps

    def joints(self, tracks) -> list[str]:
        """The joints of ``tracks``, sorted."""
        return sorted(j for t in tracks for j in self.schedule.track_joints[t])

    def dofs(self, tracks) -> np.ndarray:
        """The dofs of the joints of ``tracks`` (in :meth:`joints` order)."""
        return self.adapter.dofs(self.joints(tracks))

    def pace(self, q: np.ndarray, times, moving: np.ndarray, names: list[str], held) -> np.ndarray:
        """Each arm's movements (its runs of blending frames, ``moving`` (T, tracks) of
        the tracks ``names``, at ``times`` [s]) paced along their own paths
        (:func:`~azee_mj.pacing.paced`): one speed bell between the same two frames at
        rest, slower in the curves of a movement that follows a curved transpath (the
        two-thirds power law). The arm's hand track goes with it; two arms moving over the
        same frames go together (a two-handed sign), by their summed path. Only the
        frames not ``held`` (T,) under a constraint are smoothed (in place)."""
        sched = self.schedule
        runs = []
        for ti, t in enumerate(names):
            side = t.removeprefix("arm_")
            site = sched.smap.sites.get(f"WR_{side}") if t.startswith("arm_") else None
            if site is not None:
                runs += [(a, b, t, side, site) for a, b in runs_of(moving[:, ti])]
        paths = self.curved_paths(), *self.path_ends(times)  # worked out once
        for group in coupled(runs):
            if not self.pace_group(q, times, group, held, paths) and len(group) > 1:
                for r in group:  # the arms on their own times (each keeps its path)
                    self.pace_group(q, times, [r], held, paths)
        return q

    def pace_group(self, q, times, group, held, paths) -> bool:
        """The movement of the arms of ``group`` (runs ``(a, b, arm track, side, wrist
        site)`` over the same frames of ``q`` at ``times``) paced by their summed path
        (in place, but the frames ``held`` under a constraint not smoothed); whether it
        was. ``paths``: :meth:`curved_paths` and :meth:`path_ends`' two lists."""
        sched, solver = self.schedule, self.adapter.solver
        curved, ends, limbs = paths
        a, b = group[0][0], group[0][1]
        tracks = [t for r in group for t in (r[2], f"hand_{r[3]}") if t in sched.track_dofs]
        span = times[a], times[b]
        along = [s for t0, t1, arm, s in curved if arm in tracks and t0 < span[1] and span[0] < t1]
        sids = [solver.site_id(r[4]) for r in group] + [solver.site_id(s) for s in along[:1]]
        within = range(bisect.bisect_right(ends, a), bisect.bisect_left(ends, b))
        pins = [ends[i] - a for i in within if limbs[i] & set(tracks)]
        keep = np.flatnonzero(held[a : b + 1]).tolist()
        new = self.paced_run(q[a : b + 1], times[a : b + 1], tracks, sids, bool(along), pins, keep)
        if new is not None:
            q[a : b + 1, self.dofs(tracks)] = new
        return new is not None

    def paced_run(self, run, times, tracks, sids, law: bool, pins=(), kept=()):
        """The joints of ``tracks`` in one movement's frames ``run`` (n, nq) at ``times``
        paced by the path of sites ``sids`` (``law``: the last traces a curved transpath;
        ``pins``: frames that keep their time, see :func:`~azee_mj.pacing.paced`; ``kept``:
        frames held under a constraint, not smoothed):
        its path smoothed, else as it is; a frame paced into the body (another limb moves
        on its own time, a smoothed corner) pushed out, nearest it. Of those that keep
        the body out of itself (within the solver's ``PENETRATION_LIMIT``), turn no joint
        faster than the frames or ``BRANCH_SPEED``, move no site faster than the frames'
        fastest and are smoother than the frames (SPARC of the sites' summed speed), the
        one with fewer speed peaks, the smoothed path on a tie: a smoothed corner pushed
        out of the body frame by frame can leave bumps the path as it is, paced, does
        not. None: the frames, or the sites hardly move."""
        ad = self.adapter
        joints = self.joints(tracks)
        d = ad.dofs(joints)
        at_run = np.array([ad.at(x).d.site_xpos[sids] for x in run])
        score = self.smoothness(at_run)
        if score >= BELL_SPARC and not law and self.peaks(at_run) <= 1:
            return None  # one bell already
        fastest = max(np.abs(np.diff(run[:, d], axis=0)).max(), BRANCH_SPEED / self.fps)
        kept, pins = sorted(set(pins) | set(kept)), sorted(set(pins))
        best, fewest = None, np.inf
        for passes in (SMOOTHING, 0):
            path = run.copy()
            path[:, d] = smoothed(run[:, d], passes)
            path[kept] = run[kept]  # held frames, where a transpath starts and ends
            if not self.retimed(path, d, sids, law, pins, None if passes else at_run):
                continue
            if np.abs(np.diff(path[:, d], axis=0)).max() > fastest + 1e-9:
                continue
            pts = np.array([ad.at(x).d.site_xpos[sids] for x in path])
            if self.smoothness(pts) <= score:
                continue  # pushing frames out would not make it smoother
            pts = self.pushed_out(path, times, joints, sids, run, kept)
            if pts is None or np.abs(np.diff(path[:, d], axis=0)).max() > fastest + 1e-9:
                continue
            if self.too_fast(pts, at_run):
                continue  # a push made a site faster than the frames or a bell
            if self.smoothness(pts) > score and self.peaks(pts) < fewest:
                best, fewest = path[:, d], self.peaks(pts)
                if fewest <= 1:
                    break
        return best

    def retimed(self, path, d, sids, law: bool, pins, pts=None) -> bool:
        """The dofs ``d`` of ``path`` (n, nq) paced along it (:func:`~azee_mj.pacing.paced`
        by the sites ``sids``; ``law``, ``pins``: see :meth:`paced_run`), in place; whether
        they were. False when no bell fits, or when a site of a paced frame leaves the
        polyline of the path's frames by more than :data:`RESAMPLE_TOL` (a joint swings
        between two frames), measured with every joint paced alike: a trunk that moves on
        its own time moves the sites too, but not off their path. ``pts``: the sites at
        ``path``'s frames when known."""
        ad = self.adapter
        if pts is None:
            pts = np.array([ad.at(x).d.site_xpos[sids] for x in path])
        frames = paced(pts, pts[:, -1] if law else None, path[:, d], pins)
        if frames is None:
            return False
        whole = resample(path, frames)
        path[:, d] = whole[:, d]
        along = resample(pts.reshape(len(pts), -1), frames).reshape(pts.shape)
        new = np.array([ad.at(x).d.site_xpos[sids] for x in whole])
        return bool(np.linalg.norm(new - along, axis=2).max() <= RESAMPLE_TOL)

    def path_ends(self, times) -> tuple[list[int], list[set[str]]]:
        """The frames at ``times`` where the score's transpaths start or end, ascending,
        and the tracks of the limb each moves (worked out once: asked for every movement,
        a scan of the blocks each time grew with the square of the score)."""
        comp, ends = self.schedule.comp, []
        for b in self.schedule.blocks:
            if b.kind is sc.BlockKind.TRANSPATH and b.transpath_site:
                limbs = comp.site_tracks(comp.site(b.transpath_site))
                f0, f1 = np.searchsorted(times, [b.start - 1e-9, b.end - 1e-9]).tolist()
                ends += [(f0, limbs), (f1, limbs)]
        ends.sort(key=lambda e: e[0])
        return [f for f, _ in ends], [limbs for _, limbs in ends]

    def too_fast(self, pts: np.ndarray, before: np.ndarray) -> bool:
        """Whether a site at ``pts`` (n, k, 3) moves faster than both the same site at
        ``before`` (the frames as solved) and :data:`BELL_MARGIN` times the peak of a
        minimum-jerk bell along its own path in the movement's time: a bell peaks higher
        than a flattened profile of two humps over the same path, a push that jumps
        higher still."""
        duration = (len(pts) - 1) / self.fps
        for j in range(pts.shape[1]):
            length = float(np.linalg.norm(np.diff(pts[:, j], axis=0), axis=1).sum())
            bell = BELL_MARGIN * MINJERK_PEAK * length / duration
            fastest = max(float(mv.speed(before[:, j], self.fps).max()), bell)
            if mv.speed(pts[:, j], self.fps).max() > fastest + 1e-9:
                return True
        return False

    def peaks(self, pts: np.ndarray) -> int:
        """The most speed peaks (:func:`~azee_mj.movement.speed_peaks`) of any site at
        ``pts`` (n, k, 3)."""
        return max(mv.speed_peaks(mv.speed(pts[:, j], self.fps)) for j in range(pts.shape[1]))

    def smoothness(self, pts: np.ndarray) -> float:
        """SPARC of the summed speed of sites at ``pts`` (n, k, 3), one a frame."""
        sp = sum(mv.speed(pts[:, j], self.fps) for j in range(pts.shape[1]))
        return mv.sparc(sp, self.fps) if sp.max() > 0.0 else -np.inf

    def pushed_out(self, path, times, joints, sids, run, kept=()) -> np.ndarray | None:
        """Frames of ``path`` (n, nq) at ``times`` that go into the body pushed out by
        their ``joints``, nearest them (in place); the sites ``sids`` at each frame
        (n, k, 3). None when a pushed frame stays deeper than the frame of ``run`` it
        replaces (or ``COLLISION_TOL``), when more than ``MAX_PUSHED`` of them go in, when one of
        the frames ``kept`` (held under a constraint, which a push would not keep) does, or
        when, where a contact lets two parts touch, they go deeper into each other than in
        ``run``."""
        ad, sched = self.adapter, self.schedule

        def depth(q, t, allowed=None, posed=True):
            return ad.depth(q, sched.allowed_at(t) if allowed is None else allowed, posed)

        pts = np.empty((len(path), len(sids), 3))
        bad, held = [], set(kept)
        for i, t in enumerate(times):
            if ad.penetrates(path[i], t):
                bad.append(i)
                if len(bad) > MAX_PUSHED * len(path) or i in held:
                    return None  # paced through the body, or where it must hold a constraint
            pts[i] = ad.solver.data.site_xpos[sids]
        # where a contact lets two parts touch, they go no deeper into each other than the
        # frame did
        none = frozenset()
        for i in (i for i, t in enumerate(times) if sched.allowed_at(t)):
            deepest = max(depth(run[i], times[i], none, posed=False), cn.COLLISION_TOL)
            if depth(path[i], times[i], none) > deepest:
                return None
        for i in bad:
            soft = ad.soft_targets(path[i], joints)
            limit = max(cn.COLLISION_TOL, depth(run[i], times[i], posed=False))
            path[i] = ad.solve(soft, joints, path[i], times[i], restarts=0).qpos
            if depth(path[i], times[i]) > limit:
                return None
            pts[i] = ad.solver.data.site_xpos[sids]
        return pts

    def curved_paths(self) -> list[tuple[float, float, str, str]]:
        """``(start, end, arm track, site)`` of the transpaths along an arc or a circle:
        their interval [s], the tracks of the limb and the model site that traces them."""
        comp, out = self.schedule.comp, []
        for b in self.schedule.blocks:
            if b.kind is sc.BlockKind.TRANSPATH and isinstance(b.route, sc.Arc | sc.Circle):
                site = comp.site(b.transpath_site)
                out += [(b.start, b.end, t, site) for t in comp.site_tracks(site)]
        return out


def check_room(duration: float, fps: float, hold: float) -> None:
    """Refuse, before any solve, a score of ``duration`` [s] whose rollout at ``fps`` could
    pass :data:`~azee_mj.timing.MAX_FRAMES` once its lead-in from rest and return to rest
    (each at most ``MAX_REST_MOVE``, the return after ``hold`` [s]) are added: they are
    planned only after the key postures, which take most of the time."""
    margin = 2 * MAX_REST_MOVE + hold
    n = math.floor((duration + margin) * fps) + 3  # + a frame each for rounding lead and end
    if n > MAX_FRAMES:
        raise AzeeError(
            f"{duration:g} s of score at {fps:g} fps, with up to {margin:g} s of lead-in "
            f"from rest and return to it, may need {n} frames; the limit is {MAX_FRAMES} "
            "frames (1 hour at 50 fps): lower --fps, realize with --no-rest or split the score"
        )


class Motion:
    """Frames (pass 2) and trills (pass 3) of the adapter's schedule laid out by ``mode``
    at ``fps`` frames per second.

    With ``rest`` (multitrack only), every track comes from rest (the neutral posture) into
    its first posture in a lead-in timed from its distance, and returns to rest ``hold``
    seconds after its last block; in a gap of ``gap`` seconds or more between two of its
    blocks it returns to rest and comes back (a pause, :func:`~azee_mj.blend.pause_between`).
    The rollout's time axis gains the lead-in before the score's time 0 (:attr:`lead_frames`)
    and the return after its end. Without ``rest`` each track starts in its first posture
    and keeps its last one (the score's time axis)."""

    def __init__(
        self,
        adapter: IKAdapter,
        mode: Mode,
        fps: float,
        rest: bool = True,
        hold: float = REST_HOLD,
        gap: float = REST_GAP,
    ):
        self.adapter, self.schedule = adapter, adapter.schedule
        self.mode, self.fps = mode, fps
        self.rest, self.hold, self.gap = rest and mode is Mode.MULTITRACK, hold, gap
        #: Per track, its lead-in and return to rest (empty: none planned yet, or flattened).
        self.rests: dict[str, Rest] = {}
        #: Frames of lead-in before the score's time 0; the rollout ends at ``end`` [s]
        #: (score time).
        self.lead_frames, self.end = 0, self.schedule.score.duration
        #: Frames :meth:`hold_constraints` solved again.
        self.resolved = 0

    @property
    def score_start(self) -> float:
        """Rollout time [s] of the score's time 0: frames before it are the lead-in."""
        return self.lead_frames / self.fps

    def times(self) -> np.ndarray:
        """(T,) frame times [s] on the score's clock, ``(k - lead_frames) / fps``: negative
        during the lead-in."""
        n = frame_count(self.end + self.score_start, self.fps)
        return (np.arange(n) - self.lead_frames) / self.fps

    def plan(self, keys: dict[str, list[Key]], carried: dict[str, list[tuple]]) -> None:
        """Each track's lead-in, pauses at rest and return to rest (:attr:`rests`), and the
        time axis they need (:attr:`lead_frames`, :attr:`end`); ``carried``:
        :meth:`carried_spans` of ``keys``."""
        sched = self.schedule
        self.rests, self.lead_frames, self.end = {}, 0, sched.score.duration
        if self.mode is not Mode.MULTITRACK:
            return
        lead, end = 0.0, sched.score.duration
        for t in sched.track_joints:
            holds = holds_of(keys[t], sched.track_dofs[t])
            if not holds:
                continue
            if not self.rest:
                self.rests[t] = Rest(None)
                continue
            first, last = holds[0], holds[-1]
            r = Rest(
                self.move_time(t, None, first.q, MIN_LEAD), pauses=self.pauses(t, holds, carried[t])
            )
            home = sched.home[sched.track_dofs[t]]
            if not np.allclose(last.q, home, atol=SAME_POSTURE):
                after = [e for _, e in carried[t] if e > last.end]
                at = max([last.end + self.hold, *after])
                r = dataclasses.replace(
                    r, relax_at=at, relax=self.move_time(t, last.q, None, MIN_RELAX)
                )
                end = max(end, at + r.relax)
            self.rests[t] = r
            lead = max(lead, r.lead - first.start)
        self.tie_carriers(keys)
        self.tie_hands(keys)
        self.lead_frames = int(np.ceil(lead * self.fps - 1e-6))
        self.end = end if end <= sched.score.duration else np.ceil(end * self.fps) / self.fps

    def pauses(self, track: str, holds: list[Hold], busy) -> tuple[Pause, ...]:
        """The pauses at rest of ``track`` between its ``holds`` (:func:`pause_between`,
        gaps of at least :attr:`gap`; ``busy``: its :meth:`carried_spans`): not from or
        into a posture at rest already, nor into a return to neutral."""
        home = self.schedule.home[self.schedule.track_dofs[track]]
        out = []
        for a, b in itertools.pairwise(holds):
            if b.start - a.end < self.gap or b.relax:
                continue
            if np.allclose(a.q, home, atol=SAME_POSTURE) or np.allclose(
                b.q, home, atol=SAME_POSTURE
            ):
                continue
            relax = self.move_time(track, a.q, None, MIN_RELAX)
            lead = self.move_time(track, None, b.q, MIN_LEAD)
            p = pause_between(a.end, b.start, self.hold, relax, lead, self.gap, busy)
            if p is not None:
                out.append(p)
        return tuple(out)

    def tie_carriers(self, keys) -> None:
        """Tracks that come from rest into first keys starting together and sharing a
        constraint (a trunk recruited to carry the arms to a far place, and those arms)
        take the longest of their lead-ins: the trunk leaning on its own, shorter time
        would add a speed peak of its own to the hands it carries."""
        first = {
            t: keys[t][0]
            for t, r in self.rests.items()
            if r.lead is not None and keys[t] and not t.startswith("hand")
        }
        groups: list[set[str]] = []
        for t, k in first.items():
            joined = [
                g
                for g in groups
                if any(
                    abs(first[u].start - k.start) < EPS and set(first[u].cons) & set(k.cons)
                    for u in g
                )
            ]
            groups = [g for g in groups if g not in joined] + [{t}.union(*joined)]
        for g in groups:
            lead = max(self.rests[u].lead for u in g)
            for u in g:
                self.rests[u] = dataclasses.replace(self.rests[u], lead=lead)

    def tie_hands(self, keys) -> None:
        """A hand shape forms while its arm travels: a hand track whose first posture starts
        with its arm's takes the arm's lead-in when that is longer, and so does a lead-in
        back from a pause when it still fits after the hand's return to rest."""
        for t, r in list(self.rests.items()):
            arm = self.rests.get(t.replace("hand", "arm"))
            if not t.startswith("hand") or arm is None or r.lead is None:
                continue
            if keys[t][0].start == keys[t.replace("hand", "arm")][0].start:
                r = dataclasses.replace(r, lead=max(r.lead, arm.lead))
            back = {p.until: p.lead for p in arm.pauses}
            pauses = tuple(
                dataclasses.replace(p, lead=back[p.until])
                if back.get(p.until, 0.0) > p.lead
                and p.until - back[p.until] >= p.at + p.relax + REST_STAY
                else p
                for p in r.pauses
            )
            self.rests[t] = dataclasses.replace(r, pauses=pauses)

    def move_time(self, track: str, qa, qb, shortest: float) -> float:
        """Duration [s] of a movement of ``track`` between its joint values ``qa`` and
        ``qb`` (None: rest) at a human speed: an arm by the path its wrist travels
        (:data:`REST_SPEED`), any other track by its largest joint change
        (:data:`REST_JOINT_SPEED`)."""
        sched = self.schedule
        d = sched.track_dofs[track]
        qa = sched.home[d] if qa is None else qa
        qb = sched.home[d] if qb is None else qb
        site = sched.smap.sites.get(f"WR_{track[-1]}") if track.startswith("arm_") else None
        if site is None:
            return rest_duration(float(np.abs(qb - qa).max()), REST_JOINT_SPEED, shortest)
        sid, q = self.adapter.solver.site_id(site), sched.home.copy()
        pts = []
        for u in np.linspace(0.0, 1.0, 9):
            q[d] = qa + u * (qb - qa)
            pts.append(self.adapter.at(q).d.site_xpos[sid].copy())
        length = float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())
        return rest_duration(length, REST_SPEED, shortest)

    def frames(self, keys: dict[str, list[Key]]) -> np.ndarray:
        """(T, nq) frames through the key postures ``keys`` (per track), on :meth:`times`."""
        sched = self.schedule
        spans = self.carried_spans(keys)
        carried = {t: sorted(e for _, e in v) for t, v in spans.items()}
        self.plan(keys, spans)
        times = self.times()
        q = np.tile(sched.home, (len(times), 1))
        names = list(sched.track_joints)
        moving = np.zeros((len(times), len(names)), bool)
        flattened = self.mode is Mode.FLATTENED
        for ti, t in enumerate(names):
            d = sched.track_dofs[t]
            _, moving[:, ti] = track_curve(
                keys[t],
                times,
                d,
                sched.home,
                flattened,
                carried[t],
                self.rests.get(t),
                Columns(q, d),
            )
        if flattened:
            return self.flat_transpaths(q, times)
        Detour(self.adapter).apply(q, times, moving, names)
        solver = FrameSolver(self.adapter, self.fps)
        q = solver.solve(q, times, moving, names, keys)
        return Pacer(self.adapter, self.fps).pace(q, times, moving, names, solver.held_frames)

    def carried_spans(self, keys: dict[str, list[Key]]) -> dict[str, list[tuple]]:
        """Per track, the ``(start, end)`` [s] of other tracks' keys with a constraint that
        names a body the track moves (a hand held in front of the chin is carried by the
        head track): each key's carriers found once for every track."""
        out: dict[str, list[tuple]] = {t: [] for t in keys}
        for t, tk in keys.items():
            for k in tk:
                moved = set().union(*(self.schedule.moved_by(c) for c in k.cons))
                for tr in moved - {t}:
                    if tr in out:
                        out[tr].append((k.start, k.end))
        return out

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

    def misses(self, q: np.ndarray, times: np.ndarray, skip=()) -> dict[int, list]:
        """Frame -> the (constraint, tracks it drives) of its blocks (but those in ``skip``,
        block paths) outside their tolerance at that frame of ``q`` (T, nq)."""
        sched, n = self.schedule, len(times)
        spans = []
        for b in sched.blocks:
            if b.kind is not sc.BlockKind.CSTR or b.path in skip:
                continue
            r = frame_range(b.start, b.end, self.fps, n - self.lead_frames)
            cons = [(dc.con, dc.tracks) for dc in sched.block_constraints(b) if dc.con is not None]
            if cons and len(r):
                spans.append((r.start + self.lead_frames, r.stop + self.lead_frames, cons))
        spans_at = IntervalIndex((f0, f1) for f0, f1, _ in spans)  # not every block per frame
        out: dict[int, list] = {}
        for f in range(n):
            now = [c for i in spans_at.at(f) for c in spans[i][2]]
            if not now:
                continue
            k = self.adapter.at(q[f])
            bad = [(c, tr) for c, tr in now if not c.residual(k) <= c.tol]
            if bad:
                out[f] = bad
        return out

    def hold_constraints(self, q, times, keys, skip=(), misses=None) -> np.ndarray:
        """Every constraint held at every frame of its block: the frames of ``q`` (T, nq)
        that leave one (a neighbouring trill, a per-frame solve's box) are solved again
        with it (in place; ``skip``: paths of blocks whose own frames are not held, their
        trill shakes them on purpose; ``misses``: :meth:`misses` of ``q`` and ``skip`` when
        measured already). :attr:`resolved` counts them."""
        misses = self.misses(q, times, skip) if misses is None else misses
        self.resolved = len(misses)
        if misses and self.mode is Mode.MULTITRACK:
            FrameSolver(self.adapter, self.fps).hold_frames(q, times, keys, misses)
        return q
