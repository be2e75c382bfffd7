"""Constrained blend frames: a frame where a blending track still has constraints (an
overlapping block, a transpath's path point, a permanent hand shape) is solved as an IK
problem for the joints those constraints need, nearest the blend
(:class:`CurvePreference`), the other joints on the blend, each joint at most a step a
frame from the frame before (a box that keeps a per-frame solve on the branch of the frame
before; never smaller than the blend's own step, so it never slows a movement the score's
timing needs); a blend that would pass through the body is pushed out.

Units: seconds, metres, radians.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from azee_mj import constraints as cn
from azee_mj import ik
from azee_mj import score as sc
from azee_mj.blend import BRANCH_SPEED, Key, goal_key, minjerk, next_still
from azee_mj.ikadapter import IKAdapter
from azee_mj.intervals import IntervalIndex
from azee_mj.kinematics import Const, SitePos
from azee_mj.pathkeys import NEAR_ENDS, HandOrientation, body_rotation, hand_turn
from azee_mj.routes import path_points

#: Restarts of a per-frame solve (inside its step box) when its start does not converge.
FRAME_RESTARTS = 1
#: How far from its blend curve a joint a constrained blend solves may go [rad] before the
#: pull back counts as much as a constraint at its tolerance (a preference row of 1).
CURVE_TOL = 0.05
#: Tolerance of a transpath's path point [m].
PATH_TOL = 1e-3
#: How far [rad] the hand tracing a transpath may turn from its turn between the path's
#: ends before the pull back counts as much as a constraint at its tolerance.
TURN_TOL = 0.005
#: A frame's step box over the largest joint change of the blend into it: the box never
#: holds a joint slower than its blend moves.
STEP_MARGIN = 1.5
#: Constraint sets whose moved dofs are kept at most (a cache: it would grow with the score).
NEEDS_CACHE = 256


@dataclasses.dataclass(frozen=True, eq=False)
class CurvePreference:
    """Joints near their values on a blend curve, as a preference of an IK problem (rows
    ``(q - values) / tol`` that join the naturalness objective): among the postures that
    meet the constraints, the solver takes the one nearest the blend."""

    qposadr: np.ndarray  # (n,) the joints' qpos addresses
    dofadr: np.ndarray  # (n,) their dof addresses
    values: np.ndarray  # (n,) the curve's values [rad or m]
    tol: float  # [rad or m]: a row is 1 this far from the curve

    def rows(self, k) -> tuple[np.ndarray, np.ndarray]:
        """Rows and their Jacobian (n, nv) on the posture of kinematics ``k`` (the Jacobian
        is constant: made once, read-only)."""
        J = self.__dict__.get("_J")
        if J is None or J.shape[1] != k.m.nv:
            n = len(self.dofadr)
            J = np.zeros((n, k.m.nv))
            J[np.arange(n), self.dofadr] = 1.0 / self.tol
            J.flags.writeable = False
            self.__dict__["_J"] = J  # a cache, not a field (the record stays frozen)
        return (k.d.qpos[self.qposadr] - self.values) / self.tol, J


def transpath_points(
    adapter: IKAdapter,
    b: sc.Block,
    q: np.ndarray,
    times: np.ndarray,
    frames: slice = slice(None),
) -> np.ndarray:
    """(F, 3) path points [m] of transpath block ``b`` at the frames ``frames`` (default
    every frame) of ``q`` (T, nq) (valid inside its interval): from the site where the
    frames put it at the block's start to where they put it at its end, along its route,
    in minimum-jerk time."""
    sched = adapter.schedule
    site = SitePos(sched.comp.site(b.transpath_site))
    fs = min(int(np.searchsorted(times, b.start - 1e-9)), len(times) - 1)
    fe = min(int(np.searchsorted(times, b.end - 1e-9)), len(times) - 1)
    x0, x1 = (adapter.at(q[f]).value(site) for f in (fs, fe))
    u = minjerk((times[frames] - b.start) / b.duration)
    return path_points(b.route, x0, x1, u, adapter.at(q[fs]), sched.smap)


@dataclasses.dataclass(frozen=True, eq=False)
class Path:
    """A transpath during pass 2: its block, the model site it moves, the tracks of that
    site's limb and its points (F, 3) [m] at the frames from ``first`` on that its
    interval holds (only those: a long score has many transpaths and many frames)."""

    block: sc.Block
    site: str
    limbs: frozenset[str]
    points: np.ndarray
    first: int = 0
    hand: str | None = None  # the body of the hand carrying the site, if one does
    turn: np.ndarray | None = None  # (F, 2, 3) its axes at the same frames (hand_turn)

    def place(self, f: int) -> cn.Place:
        """The placement of the site on its path point at frame ``f`` (inside the block)."""
        at = Const(tuple(self.points[f - self.first]))
        return cn.Place(self.site, at, PATH_TOL, f"{self.block.path}@path")

    def turned(self, f: int) -> tuple[HandOrientation, ...]:
        """The orientation of the hand carrying the site at frame ``f`` (inside the block)
        as a preference (none if no hand carries it)."""
        if self.hand is None:
            return ()
        return (HandOrientation(self.hand, self.turn[f - self.first], TURN_TOL),)


def transpath(adapter: IKAdapter, b: sc.Block, q: np.ndarray, times: np.ndarray) -> Path:
    """Transpath block ``b`` on the frames ``q`` (T, nq) at ``times`` [s]: its path points,
    and, along a circle or between ends within ``NEAR_ENDS`` of each other, the hand
    carrying its site turning from its orientation at the block's start to that at its end
    in the same minimum-jerk time, about one axis (a fingertip tracing a circle or a small
    path carries its hand along rather than turn it about the tip; across a sweep the
    forearm turns, and the hand with it, as the blend has it)."""
    sched = adapter.schedule
    site = sched.comp.site(b.transpath_site)
    inside = slice(*np.searchsorted(times, [b.start, b.end]).tolist())  # start <= t < end
    points = transpath_points(adapter, b, q, times, inside)
    path = Path(b, site, frozenset(sched.comp.site_tracks(site)), points, inside.start)
    arm = sched.anatomy.hand_of(site)
    if arm is None:
        return path
    fs, fe = (min(int(np.searchsorted(times, x - 1e-9)), len(times) - 1) for x in (b.start, b.end))
    ends = [adapter.at(q[f]).value(SitePos(site)) for f in (fs, fe)]
    if not isinstance(b.route, sc.Circle) and np.linalg.norm(ends[1] - ends[0]) > NEAR_ENDS:
        return path
    R0, R1 = (body_rotation(adapter.at(q[f]), arm.hand) for f in (fs, fe))
    turn = hand_turn(R0, R1, minjerk((times[inside] - b.start) / b.duration))
    return dataclasses.replace(path, hand=arm.hand, turn=turn)


class BlendCurve:
    """The blend's frames ``q`` (T, nq) as they were before the per-frame solves changed
    them, without a copy of them all (a copy grows with the score): frames are solved in
    order, so the frames after the current one are still the blend's in ``q``, and the
    current and previous ones are kept as :meth:`advance` reaches them."""

    def __init__(self, q: np.ndarray):
        self.q, self.f = q, -1
        self.current: np.ndarray | None = None
        self.previous: np.ndarray | None = None

    def advance(self, f: int) -> None:
        """Frame ``f`` is next to be solved (call before changing ``q[f]``)."""
        self.previous, self.current, self.f = self.current, self.q[f].copy(), f

    def __getitem__(self, x: int) -> np.ndarray:
        if x > self.f:
            return self.q[x]
        if x == self.f:
            return self.current
        if x == self.f - 1 and self.previous is not None:
            return self.previous
        raise IndexError(f"frame {x} of the blend is no longer kept (now at frame {self.f})")


class KeyIndex:
    """Per track, which of its ``keys`` holds a time (an interval index of their spans),
    and what a key holds while its track blends (:meth:`FrameSolver.held`), worked out
    once per key rather than at every frame."""

    def __init__(self, keys: dict[str, list[Key]]):
        self.keys = keys
        self.spans = {tr: IntervalIndex((k.start, k.end) for k in ks) for tr, ks in keys.items()}
        self.kept: dict[tuple[str, int], list] = {}


class FrameSolver:
    """Solves the constrained frames of blends at ``fps`` frames per second through
    ``adapter``."""

    def __init__(self, adapter: IKAdapter, fps: float):
        self.adapter, self.schedule = adapter, adapter.schedule
        #: Largest joint change between two frames solved one by one [rad], at the frame
        #: being solved (:meth:`steps`).
        self.step = BRANCH_SPEED / fps
        self.base = self.step
        self._reach = np.zeros(1)  # cumulative steps, for reach()
        self._needs: dict[tuple, set[int]] = {}  # constraints -> the dofs they move
        #: (T,) the frames :meth:`solve` solved under constraints (the others follow their
        #: blends, or are pushed out of the body).
        self.held_frames = np.zeros(0, bool)

    def steps(self, curve: np.ndarray) -> np.ndarray:
        """(T,) each frame's step box [rad]: ``BRANCH_SPEED / fps``, or ``STEP_MARGIN``
        times the blend's largest joint change into the frame when that is more (a
        transition the score times faster than the box moves at the speed it needs)."""
        change = np.zeros(len(curve))
        for a in range(1, len(curve), 1024):  # a block at a time: no copy of every frame
            b = min(a + 1024, len(curve))
            change[a:b] = np.abs(curve[a:b] - curve[a - 1 : b - 1]).max(axis=1)
        return np.maximum(self.base, STEP_MARGIN * change)

    def paths(self, q: np.ndarray, times: np.ndarray) -> list[Path]:
        """The score's transpaths on the blended frames ``q``."""
        blocks = self.schedule.blocks
        return [
            transpath(self.adapter, b, q, times) for b in blocks if b.kind is sc.BlockKind.TRANSPATH
        ]

    def solve(self, q, times, moving, names, keys: dict[str, list[Key]]) -> np.ndarray:
        """Frames ``q`` (T, nq) (the blends, solved in place) where the tracks ``names``
        blend (``moving``, (T, tracks)) under the constraints of their ``keys``."""
        paths = self.paths(q, times)
        curve = BlendCurve(q)
        still = next_still(moving)
        joints = self.schedule.track_joints
        steps = self.steps(q)
        self._reach = np.cumsum(steps)
        # what holds a frame, in logarithmic time: not by asking every path and key
        paths_at = IntervalIndex((p.block.start, p.block.end) for p in paths)
        keys_at = KeyIndex(keys)
        self.held_frames = np.zeros(len(times), bool)
        for f, t in enumerate(times):
            self.step = float(steps[f])
            curve.advance(f)
            tracks = {names[i] for i in np.flatnonzero(moving[f])}
            cons, free = self.held(tracks, t, keys_at)
            turned = []
            for p in (paths[j] for j in paths_at.at(t)):
                if p.limbs & tracks:
                    cons.append(p.place(f))
                    turned += p.turned(f)
                    free |= {j for tr in p.limbs for j in joints[tr]}
            if not cons:
                self.follow(q, f, t, tracks)
                continue
            self.held_frames[f] = True
            free |= {j for tr in tracks for j in joints[tr]}
            bounds = self.reach(q, curve, still[f], f, names, tracks)
            q[f] = self.constrained(q, curve, f, t, cons, free, bounds, tuple(turned))
        return q

    def held(self, tracks, t: float, keys_at: KeyIndex) -> tuple[list, set[str]]:
        """The constraints the keys (``keys_at``) of blending ``tracks`` hold at time ``t``
        [s], and the joints they free. While blending, a key's constraints hold to its
        end, but for the joint targets (hand shapes) the posture the blend heads for does
        not keep: those joints are the blend's to move."""
        cons, free = [], set()
        for tr in sorted(tracks):  # sorted: the same rows in any process
            i = keys_at.spans[tr].first_at(t)
            if i is None:
                continue
            key = keys_at.keys[tr][i]
            keep = keys_at.kept.get((tr, i))
            if keep is None:
                goal = goal_key(keys_at.keys[tr], i, self.schedule.track_dofs[tr])
                keep = keys_at.kept[tr, i] = [
                    c
                    for c in key.cons
                    if goal is None or c in goal.cons or not isinstance(c, cn.JointTarget)
                ]
            cons += [c for c in keep if c not in cons]
            free |= set(key.free)
        return cons, free

    def follow(self, q: np.ndarray, f: int, t: float, tracks) -> None:
        """A frame of blending ``tracks`` without constraints: on the curve, back toward it
        at most a step a frame after frames pushed out, and pushed out of the body if the
        blend passes through it (staying close: consecutive pushed frames cannot zig-zag)."""
        ad, step = self.adapter, self.step
        free = {j for tr in sorted(tracks) for j in self.schedule.track_joints[tr]}
        if f > 0 and free:
            d, before = ad.dofs(free), q[f - 1]
            q[f][d] = np.clip(q[f][d], before[d] - step, before[d] + step)
        if not tracks or not ad.penetrates(q[f], t):
            return
        soft = ad.soft_targets(q[f], free)
        q0 = q[f].copy()
        if f > 0:
            # from half a step toward the curve from the frame before, moving at most
            # half a step more
            d, before = ad.dofs(free), q[f - 1]
            near = np.clip(q[f][d], before[d] - step, before[d] + step)
            q0[d] = before[d] + 0.5 * (near - before[d])
        q[f] = ad.solve(soft, sorted(free), q0, t, max_change=0.5 * step, restarts=0).qpos
        if f > 0 and ad.penetrates(q[f], t):
            # still through (it started deep in): from the frame before, clear
            q[f] = ad.solve(soft, sorted(free), q[f - 1], t, max_change=0.5 * step, restarts=0).qpos

    def constrained(self, q, curve, f: int, t: float, cons, free, bounds, turned=()):
        """The posture of frame ``f`` meeting ``cons``. The joints the constraints move
        start from the frame before (final by now), advanced by the blend's step (the same
        branch), and among the postures that meet the constraints take the one nearest the
        blend: a solve that starts where its constraints are met stops at once, and would
        leave them still until the next key. The others follow the blend, at most a step a
        frame from the frame before. ``turned``: the orientations of the hands tracing
        paths (:meth:`Path.turned`), preferred as the blend is."""
        ad, step = self.adapter, self.step
        key = tuple(cons)
        if key not in self._needs:
            if len(self._needs) >= NEEDS_CACHE:  # (a path point is new at every frame)
                self._needs.clear()
            self._needs[key] = set(ad.solver.free_dofs(ik.IKProblem(key)).tolist())
        needed = self._needs[key]
        moved = sorted(j for j in free if ad.dofs([j])[0] in needed) or sorted(free)
        rest = sorted(set(free) - set(moved))
        q0 = q[f].copy()
        if f > 0:
            before = q[f - 1]
            d = ad.dofs(moved)
            q0[d] = before[d] + np.clip(curve[f][d] - curve[f - 1][d], -step, step)
            if rest:
                d = ad.dofs(rest)
                q0[d] = np.clip(q0[d], before[d] - step, before[d] + step)
        if bounds is not None:
            q0 = np.clip(q0, *bounds)
        near = (self.curve_preference(q[f], moved), *turned)
        res = ad.solve(
            cons,
            moved,
            q0,
            t,
            max_change=step,
            restarts=FRAME_RESTARTS,
            preferences=near,
            prefer=q[f],
            bounds=bounds,
        )
        if rest and not res.converged and res.penetration > cn.PENETRATION_LIMIT:
            # the blend goes through the body: every joint may push it out
            res = self.on_blend(cons, q[f], free, q0, t, bounds)
        d = ad.dofs(sorted(free))
        if f > 0 and np.abs(res.qpos[d] - q[f - 1][d]).max() > step + 1e-9:
            # a constraint far from the frame before (a key's hand shape that the blend
            # reaches late): from the frame before, at most a step
            q0[d] = q[f - 1][d]
            if bounds is not None:
                q0 = np.clip(q0, *bounds)
            res = self.on_blend(cons, q[f], free, q0, t, bounds)
        return res.qpos

    def on_blend(self, cons, qf, free, q0, t: float, bounds) -> ik.IKResult:
        """``cons`` solved moving every joint of ``free`` from ``q0``, each kept near its
        blend value in ``qf`` (soft targets), at most a step from ``q0``."""
        ad = self.adapter
        soft = ad.soft_targets(qf, free)
        return ad.solve(
            cons + soft,
            sorted(free),
            q0,
            t,
            max_change=self.step,
            restarts=FRAME_RESTARTS,
            bounds=bounds,
        )

    def reach(self, q, curve, goal, f: int, names, tracks):
        """Bounds (lower, upper) (nq,) keeping each blending track of frame ``f`` within
        reach of the posture its blend arrives at (``goal``: per track, the first frame it
        no longer blends, -1 if none): ``n`` frames before it, within ``n`` steps of it and
        still within a step of the frame before. A per-frame solve that follows a path onto
        another branch (the far side of the other arm) then returns to the key's in time,
        at most a step a frame, rather than snap at the key. None if no track has a goal."""
        step, solver = self.step, self.adapter.solver
        lo, hi = solver.lower.copy(), solver.upper.copy()
        bounded = False
        for i, tr in enumerate(names):
            if tr not in tracks or goal[i] < 0:
                continue
            d = self.schedule.track_dofs[tr]
            n = goal[i] - f
            room = self._reach[goal[i]] - self._reach[f] if len(self._reach) > goal[i] else n * step
            lo[d] = np.maximum(lo[d], curve[goal[i]][d] - room)
            hi[d] = np.minimum(hi[d], curve[goal[i]][d] + room)
            if f > 0:  # and a step at most from the frame before
                lo[d] = np.clip(lo[d], q[f - 1][d] - step, q[f - 1][d] + step)
                hi[d] = np.clip(hi[d], q[f - 1][d] - step, q[f - 1][d] + step)
            bounded = True
        return (lo, hi) if bounded else None

    def curve_preference(self, qf: np.ndarray, joints) -> CurvePreference:
        """A preference for ``joints`` at their values in posture ``qf`` (a blend's frame)."""
        solver = self.adapter.solver
        adr = solver.model.jnt_qposadr[[solver.joint_id(j) for j in joints]]
        return CurvePreference(adr, self.adapter.dofs(joints), qf[adr].copy(), CURVE_TOL)

    def hold_frames(self, q, times, keys, misses: dict[int, list]) -> int:
        """Frames that leave a constraint of their block (``misses``: frame -> the
        (constraint, tracks it drives) out of tolerance there) solved again: those
        constraints with every constraint the keys of their tracks hold then, from the
        frame itself and nearest it (in place). Returns how many frames were solved."""
        joints, ad = self.schedule.track_joints, self.adapter
        keys_at = KeyIndex(keys)
        for f, missed in sorted(misses.items()):
            tracks = set().union(*(tr for _, tr in missed))
            cons, free = self.held(tracks, times[f], keys_at)
            cons += [c for c, _ in missed if c not in cons]
            free = sorted(free | {j for tr in tracks for j in joints[tr]})
            near = (self.curve_preference(q[f], free),)
            res = ad.solve(cons, free, q[f], times[f], preferences=near, restarts=FRAME_RESTARTS)
            if res.converged:
                q[f] = res.qpos
        return len(misses)
