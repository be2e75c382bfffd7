"""Blends that go around the body: a straight joint-space blend between two postures of an
arm that passes through the body (the other forearm, the trunk) is bent, before any frame
is solved, through a via posture out of the body, in one movement.

Solving such a blend frame by frame pushes each frame out of the body in turn: the hand
stops at the obstacle, frames repeat, then jump. A signer moves the hand around it in one
smooth movement. So for each blend of an arm whose frames go into the body, the posture at
its deepest frame is pushed out by the solver (nearest it, the arm's joints only): the
via. The blend becomes ``qa + s (qb - qa) + bump(s) (via - blend(s_via))``, with ``s`` the
blend's own minimum-jerk progress and ``bump`` a smooth bell, 0 with zero slope at both
ends and 1 at ``s_via``: key, via and key in one movement, at rest at both ends. The via
is pushed further (:data:`REACH`) until no frame of the bent blend goes in; a blend that
cannot be bent out of the body is left straight (the frame solver pushes it out). A bend
whose vias zig-zag (several speed peaks) may give way to a *grown* one: a single bell
whose offset grows until the blend clears the body (:meth:`Detour.bent_run`).

Units: radians, seconds.
"""

from __future__ import annotations

import numpy as np

from azee_mj import constraints as cn
from azee_mj import ik
from azee_mj import movement as mv
from azee_mj.blend import minjerk
from azee_mj.ikadapter import IKAdapter, Solved
from azee_mj.posture.collision import pair_coordinates, still_pairs

#: How far a bend goes, over the via's offset from the blend: the via itself only just
#: clears the body, the frames around it may not.
REACH = 1.25
#: Fastest a bend may move a wrist [m/s] (the human range the report holds rollouts to)
#: where the straight blend did not.
FASTEST = 3.0
#: Most bends a blend takes (each at its deepest frame still in the body).
BENDS = 12
#: How deep [m] a bent blend may still go into the body: the frame solver pushes such
#: frames out by a few millimetres, with no jump.
SHALLOW = 5e-3
#: A via's progress along the blend is kept this far from its ends (a bend at an end
#: would be a jerk).
EDGE = 0.05
#: Bends tried when the first leaves the wrist with more than one speed peak, as
#: ``(reach, timed, grown)``: their bells over the blend's time rather than its progress
#: (a via near an end is then reached over all the frames before it, not in the last few
#: of them), reaching less or further than the first; ``grown``: one bell only, its via's
#: offset grown until every frame is out of the body (:meth:`Detour.bent_run`).
ALTERNATIVES = ((1.0, True, True), (1.0, True, False))
#: How much shorter an alternative bend's wrist path must be to replace the first when it
#: leaves as many speed peaks: a clearly shorter way around, not noise.
SHORTER = 0.95
#: A grown bend's bell is at least this high where it pushes a frame out: a frame near an
#: end, where the bell is low, would otherwise ask for a far via.
GROWN_FLOOR = 0.5
#: A grown bend's bell tops this far (a fraction of the blend's time or progress) from
#: its ends, at least: a bell that tops near an end rises (or falls) in a few frames, a
#: speed peak of its own; this one rises as the blend speeds up (a hand leaving a contact
#: it would graze goes around in the same bell).
GROWN_EDGE = 0.3


def bump(s: np.ndarray, at: float) -> np.ndarray:
    """(n,) a smooth bell over blend progress ``s`` (n,) in [0, 1]: 0 with zero slope at
    0 and 1, 1 with zero slope at ``at`` (in (0, 1)), a minimum-jerk rise and fall."""
    s = np.clip(s, 0.0, 1.0)
    up = minjerk(np.clip(s / at, 0.0, 1.0))
    down = minjerk(np.clip((1.0 - s) / (1.0 - at), 0.0, 1.0))
    return np.where(s <= at, up, down)


def progress(q: np.ndarray) -> np.ndarray:
    """(n,) how far along each row of ``q`` (n, d) is on the straight line from its first
    row to its last, 0 to 1."""
    span = q[-1] - q[0]
    den = float(span @ span)
    if den <= 0.0:
        return np.linspace(0.0, 1.0, len(q))
    return np.clip((q - q[0]) @ span / den, 0.0, 1.0)


def better(candidate: tuple[int, float], kept: tuple[int, float]) -> bool:
    """Whether a bend whose wrist moves with ``candidate`` ``(speed peaks, path length)``
    replaces one with ``kept``: a :data:`SHORTER` path, or fewer peaks over a path at most
    as much longer as :data:`SHORTER` asks shorter (of two bends about as long, the one
    bell; a clearly shorter way, which pacing may still make one bell, before a longer
    one)."""
    (peaks, length), (kept_peaks, kept_length) = candidate, kept
    if length < SHORTER * kept_length:
        return True
    return peaks < kept_peaks and SHORTER * length <= kept_length


def runs(flags: np.ndarray) -> list[tuple[int, int]]:
    """``(a, b)`` of each run of True in ``flags`` (T,): from the frame before it to the
    frame after it, within the frames."""
    n = len(flags)
    return [(max(a - 1, 0), min(b + 1, n - 1)) for a, b in mv.runs(flags)]


class Detour:
    """Bends the blends of the arm tracks through ``adapter`` around the body."""

    def __init__(self, adapter: IKAdapter):
        self.adapter, self.schedule = adapter, adapter.schedule
        #: Blends bent, as ``(track, first frame, last frame)``.
        self.bent: list[tuple[str, int, int]] = []
        self._speeds: dict[tuple, np.ndarray] = {}  # see wrist_path_speed
        self._vias: dict[tuple, ik.IKResult] = {}  # see via
        solver = adapter.solver
        self._pairs = solver.all_pairs  # with the coordinates moving each, see depths
        self._pair_q = pair_coordinates(solver.model, self._pairs)
        self._lower, self._upper = solver.lower, solver.upper  # per dof: a hinge's, its qpos's

    def apply(self, q: np.ndarray, times: np.ndarray, moving: np.ndarray, names) -> np.ndarray:
        """Every arm's blend (its runs of ``moving`` (T, tracks) of tracks ``names``) in
        ``q`` (T, nq) at ``times`` [s] that goes into the body, bent out of it (in place).
        The blends that move their joints furthest go first: of two arms whose blends meet,
        the one that travels goes around the other, which may then stay straight. A bent
        blend keeps within the joint ranges."""
        blends = []
        for ti, t in enumerate(names):
            if t.startswith("arm_"):
                d = self.schedule.track_dofs[t]
                for a, b in runs(moving[:, ti]):
                    if b - a >= 4:
                        blends.append((-float(np.abs(q[b, d] - q[a, d]).sum()), t, a, b))
        for _, t, a, b in sorted(blends):
            self._speeds, self._vias = {}, {}  # a blend's, asked again by its bends' tests
            d = self.schedule.track_dofs[t]
            joints = sorted(self.schedule.track_joints[t])
            depth = self.depths(q[a : b + 1], times[a : b + 1])
            if not (depth[1:-1] > cn.COLLISION_TOL).any():
                continue  # it stays out of the body
            new = self.bent_run(q[a : b + 1], times[a : b + 1], d, joints, depth=depth)
            if new is None or np.array_equal(new, q[a : b + 1, d]):
                # not bent: its deepest frames next to an end, where its progress is slow
                new = self.bent_run(q[a : b + 1], times[a : b + 1], d, joints, timed=True)
            if new is None:
                continue
            bent = self.shortest(q[a : b + 1], times[a : b + 1], t, new)
            if bent is not None:
                # a bend's curve through its vias may overshoot a joint its keys hold at a
                # bound (apart-cross's clavicle, 2.6 mrad past it): it keeps to the ranges
                q[a : b + 1, d] = np.clip(bent, self._lower[d], self._upper[d])
                self.bent.append((t, a, b))
        return q

    def shortest(self, run: np.ndarray, times: np.ndarray, track: str, first: np.ndarray):
        """The bend of arm ``track``'s blend ``run`` (n, nq) at ``times`` to keep: ``first``
        (its dofs' values), or, when that leaves the wrist with more than one speed peak or
        moves it too fast (:meth:`rushed`), the :data:`ALTERNATIVES` bend that is not
        rushed and travels least, or about as little with fewer speed peaks
        (:func:`better`); a grown bend only if it is one speed bell (pacing may not make
        one of a grown bend's two). None: every bend is rushed (the blend stays straight).
        Vias on different sides of an obstacle add up to a zig-zag: a longer way around,
        with a speed peak per leg, that pacing cannot make one bell without speeding it
        up. The shorter way, or one bell grown around the obstacle, paced, is one slower
        bell."""
        d = self.schedule.track_dofs[track]
        joints = sorted(self.schedule.track_joints[track])
        if self.rushed(run, first, d, track, times):
            best, kept = None, (np.inf, np.inf)
        else:
            speed = self.wrist_speed(run, first, d, track, times)
            if speed is None or mv.speed_peaks(speed) <= 1:
                return first
            best, kept = first, (mv.speed_peaks(speed), float(speed.sum()))
        for reach, timed, grown in ALTERNATIVES:
            new = self.bent_run(run, times, d, joints, reach, timed, grown=grown)
            if new is None or self.rushed(run, new, d, track, times):
                continue
            speed = self.wrist_speed(run, new, d, track, times)
            if speed is None:
                continue
            now = (mv.speed_peaks(speed), float(speed.sum()))
            if grown and now[0] > 1:
                continue  # a grown bend is tried for one bell
            if better(now, kept):
                best, kept = new, now
        return best

    def wrist_path_speed(self, frames, track: str, times) -> np.ndarray | None:
        """(n,) the speed [m/s] of arm ``track``'s wrist over postures ``frames`` (n, nq) at
        ``times``; None if the signer has no such wrist or there is a single frame. Kept
        for the blend being bent (read-only): its tests ask the same paths again."""
        site = self.schedule.smap.sites.get(f"WR_{track.removeprefix('arm_')}")
        if site is None or len(times) < 2:
            return None
        key = (site, frames.tobytes(), times.tobytes())
        speed = self._speeds.get(key)
        if speed is None:
            sid, fps = self.adapter.solver.site_id(site), 1.0 / float(times[1] - times[0])
            pos = np.array([self.adapter.at(x).d.site_xpos[sid].copy() for x in frames])
            speed = self._speeds[key] = mv.speed(pos, fps)
            speed.flags.writeable = False
        return speed

    def wrist_speed(self, run, new, d, track: str, times) -> np.ndarray | None:
        """(n,) the speed [m/s] of arm ``track``'s wrist over ``run`` (n, nq) with its dofs
        ``d`` at ``new``; None if the signer has no such wrist or it stands still."""
        bent = run.copy()
        bent[:, d] = new
        speed = self.wrist_path_speed(bent, track, times)
        return speed if speed is not None and speed.max() > 0.0 else None

    def rushed(self, run: np.ndarray, new: np.ndarray, d, track: str, times) -> bool:
        """Whether the bent blend (``new``, the dofs ``d`` of arm ``track`` over the blend
        ``run`` (n, nq)) moves its wrist faster than :data:`FASTEST` where the straight
        one did not: a longer path in the same time."""
        bent = run.copy()
        bent[:, d] = new
        fast = self.wrist_path_speed(bent, track, times)
        if fast is None:
            return False
        return float(fast.max()) > max(
            float(self.wrist_path_speed(run, track, times).max()), FASTEST
        )

    def bent_run(
        self,
        run,
        times,
        d,
        joints,
        reach: float = REACH,
        timed: bool = False,
        depth=None,
        grown: bool = False,
    ) -> np.ndarray | None:
        """The dofs ``d`` of the arm (``joints``) over the blend ``run`` (n, nq) at
        ``times`` bent around the body, or None: the blend stays out of it, or no bend
        found within :data:`BENDS` keeps every frame out. ``reach``: the bend over the
        via's offset; ``timed``: the bells over the frames' time, not the blend's
        progress; ``depth``: :meth:`depths` of ``run`` when known. Each bend adds a bell
        at the deepest frame still in the body; ``grown``: one bell only, topping at the
        first deepest frame (:data:`GROWN_EDGE` from the ends at least), its offset grown
        by the via of each frame then deepest (over the bell's height there, at least
        :data:`GROWN_FLOOR`): the wrist goes around an obstacle that spans much of the
        blend (the other arm, moving too) in one curve rather than a zig-zag of bells."""
        allowed = [self.schedule.allowed_at(t) for t in times]  # the same at every bend
        depth = self.depths(run, times, allowed) if depth is None else depth
        if not (depth[1:-1] > cn.COLLISION_TOL).any():
            return None
        s = np.linspace(0.0, 1.0, len(run)) if timed else progress(run[:, d])
        path, best, least = run.copy(), None, np.inf
        bell, offset = None, np.zeros(len(d))
        for k in range(BENDS):
            if k:
                depth = self.depths(path, times, allowed)
            if depth.max() < least:
                best, least = path[:, d].copy(), depth.max()
            if least <= cn.COLLISION_TOL:
                break
            m = int(np.argmax(depth[1:-1])) + 1 if grown else self.via_frame(depth, s)
            via = self.via(path[m], joints, times[m])
            if via.penetration > cn.PENETRATION_LIMIT:
                break
            push = reach * (via.qpos[d] - path[m, d])
            if grown:
                if bell is None:
                    bell = bump(s, float(np.clip(s[m], GROWN_EDGE, 1.0 - GROWN_EDGE)))
                offset = offset + push / max(float(bell[m]), GROWN_FLOOR)
                bent = run[:, d] + bell[:, None] * offset
            else:
                bent = path[:, d] + bump(s, s[m])[:, None] * push
            if np.array_equal(bent, path[:, d]):
                break  # the via is the frame itself: every further bend would be this one
            path[:, d] = bent
        else:
            depth = self.depths(path, times, allowed)
            if depth.max() < least:
                best, least = path[:, d].copy(), depth.max()
        return best if least <= SHALLOW else None

    def via(self, q: np.ndarray, joints, t: float) -> ik.IKResult:
        """The arm (``joints``) solved out of the body from frame ``q`` at time ``t`` [s],
        kept for the blend being bent: a retry (bells over time, another reach) often bends
        first at the same frame. A kept solve is logged again in the adapter's results, as
        taking no time."""
        ad = self.adapter
        key = (q.tobytes(), tuple(joints), t)
        via = self._vias.get(key)
        if via is None:
            via = self._vias[key] = ad.solve(ad.soft_targets(q, joints), joints, q, t)
        else:
            ad.results.append(Solved(via.iterations, via.converged, 0.0))
        return via

    def via_frame(self, depth: np.ndarray, s: np.ndarray) -> int:
        """The frame to bend at: the deepest inner one, its progress ``s`` kept
        :data:`EDGE` from the ends."""
        m = int(np.argmax(depth[1:-1])) + 1
        at = float(np.clip(s[m], EDGE, 1.0 - EDGE))
        return int(np.argmin(np.abs(s - at)))

    def depths(self, run: np.ndarray, times: np.ndarray, allowed_at=None) -> np.ndarray:
        """(n,) how deep [m] each frame of ``run`` (n, nq) goes into the body (beyond what
        the contacts of its time allow) further than its keys (the first and last frames,
        weighed by how far it is from each): a hand leaving a contact (or reaching one)
        may touch as its key does. ``allowed_at``: the body pairs the contacts allow at
        each of ``times`` when known (:meth:`~azee_mj.schedule.Schedule.allowed_at`)."""
        if allowed_at is None:
            allowed_at = [self.schedule.allowed_at(t) for t in times]
        s = np.linspace(0.0, 1.0, len(run))
        # The pairs the run moves are measured at every frame, the others once.
        still = still_pairs(self._pair_q, run)
        moved = np.ascontiguousarray(self._pairs[~still])
        kept = np.ascontiguousarray(self._pairs[still])
        frames: dict[frozenset, list[int]] = {}  # the frames of each allowed set
        for i, allowed in enumerate(allowed_at):
            frames.setdefault(allowed, []).append(i)
        depth, first, last = np.empty(len(run)), np.empty(len(run)), np.empty(len(run))
        for allowed, idx in frames.items():
            first[idx], last[idx] = self.depth(run[0], allowed), self.depth(run[-1], allowed)
        k = self.adapter.at(run[0])  # the still pairs' place over the whole run
        rest = {allowed: cn.pairs_depth(k.m, k.d, kept, allowed) for allowed in frames}
        for allowed, idx in frames.items():
            depth[idx] = self.adapter.depths(run[idx], allowed, (moved, rest[allowed]))
        return np.maximum(depth - ((1.0 - s) * first + s * last), 0.0)

    def depth(self, q: np.ndarray, allowed) -> float:
        """How deep [m] posture ``q`` goes into the body, but for the body pairs ``allowed``
        (worked out once per posture by the adapter: a blend's keys are its end frames, and a
        bend leaves the frames near its ends as they were)."""
        return self.adapter.depth(q, allowed, posed=False)
