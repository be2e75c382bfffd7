"""Motion between the key postures: blends, transpath paths and trills.

Each track holds its key posture while driven and moves between postures with a
minimum-jerk blend; frames where a blending track still has constraints (an overlapping
block, a transpath path point, a permanent hand shape) are solved for the joints those
constraints need, nearest the blend (:class:`CurvePreference`), the other joints on the
blend; trills are added last. :class:`Motion` does this on a
:class:`~azee_mj.schedule.Schedule`.

Units: seconds, metres, radians.
"""

from __future__ import annotations

import dataclasses
import enum
import itertools

import mujoco
import numpy as np

from azee_mj import constraints as cn
from azee_mj import ik
from azee_mj import score as sc
from azee_mj.kinematics import Const, compile_point, compile_vector
from azee_mj.schedule import Schedule

#: Longest blend between two postures of a track when the gap allows more [s].
MAX_BLEND = 0.6
#: Shortest blend when a posture must change with no gap [s].
MIN_BLEND = 0.08
#: Postures closer than this per joint [rad] are the same (the solver's accuracy).
SAME_POSTURE = 2e-3
#: Peak joint speed a blend is sized for [rad/s] (the limit is 25 rad/s).
BLEND_SPEED = 12.0
#: Fastest a joint may turn between two frames solved one by one [rad/s]: a per-frame
#: solve stays on the branch of the frame before.
MAX_JOINT_SPEED = 20.0
#: Restarts of a per-frame solve (inside its step box) when its start does not converge.
FRAME_RESTARTS = 1
#: How far from its blend curve a joint a constrained blend solves may go [rad] before the
#: pull back counts as much as a constraint at its tolerance (a preference row of 1).
CURVE_TOL = 0.05


class Mode(enum.Enum):
    """How the score is laid out in time."""

    MULTITRACK = "multitrack"
    FLATTENED = "flattened"


@dataclasses.dataclass
class Key:
    """One track's posture over a segment, and the constraints that hold it there."""

    start: float
    end: float
    q: np.ndarray  # (nq,) the component's solved posture (only this track's joints count)
    cons: tuple  # ik constraints of the component (hard), for frames inside this key
    free: tuple[str, ...]  # joints of the component
    relax: bool = False  # a return to neutral: it blends from its start, not before it


def minjerk(u: np.ndarray | float):
    """The minimum-jerk profile 10u^3 - 15u^4 + 6u^5 on [0, 1] (clipped outside)."""
    u = np.clip(u, 0.0, 1.0)
    return u**3 * (10.0 - 15.0 * u + 6.0 * u**2)


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
        """Rows and their Jacobian (n, nv) on the posture of kinematics ``k``."""
        n = len(self.dofadr)
        J = np.zeros((n, k.m.nv))
        J[np.arange(n), self.dofadr] = 1.0 / self.tol
        return (k.d.qpos[self.qposadr] - self.values) / self.tol, J


class Motion:
    """Frames from key postures on ``schedule`` (``mode`` flattened or multitrack); every IK
    result solved for them is kept in ``results``."""

    def __init__(self, schedule: Schedule, mode: Mode, fps: float = 50.0):
        self.s, self.mode = schedule, mode
        self.solver, self.m, self.smap = schedule.solver, schedule.m, schedule.smap
        self.comp, self.blocks = schedule.comp, schedule.blocks
        self.track_joints, self.track_dofs = schedule.track_joints, schedule.track_dofs
        self.home = schedule.home
        self.results: list[ik.IKResult] = []
        self.fps = fps
        #: Largest joint change between two frames solved one by one [rad].
        self.frame_step = MAX_JOINT_SPEED / fps

    def solve(
        self,
        cons,
        free,
        q0,
        t: float,
        seeds=(),
        max_change=None,
        natural: bool = True,
        preferences=(),
        restarts=None,
        prefer=None,
        bounds=None,
    ) -> ik.IKResult:
        """Solve ``cons`` moving joints ``free`` from ``q0`` (and ``seeds``, other starts),
        allowing the contacts of time ``t`` [s], each joint within ``max_change`` of ``q0``
        and inside ``bounds`` ((lower, upper), each (nq,)) if given; every result is kept
        in ``results``."""
        problem = self.problem(cons, free, q0, t, seeds, max_change, natural, preferences)
        if bounds is not None:
            problem = dataclasses.replace(problem, bounds=bounds)
        if restarts is not None:
            problem = dataclasses.replace(problem, restarts=restarts)
        if prefer is not None:
            problem = dataclasses.replace(problem, prefer=prefer)
        res = self.solver.solve(problem, q0)
        self.results.append(res)
        return res

    def problem(
        self,
        cons,
        free,
        q0,
        t: float,
        seeds=(),
        max_change=None,
        natural: bool = True,
        preferences=(),
    ) -> ik.IKProblem:
        """The IK problem :meth:`solve` solves."""
        names = self.s.body_names
        touching = tuple((names[a], names[b]) for a, b in self.s.allowed_at(t) if a < b)
        return ik.IKProblem(
            tuple(cons),
            tuple(free),
            touching,
            q0,
            tuple(seeds),
            max_change,
            natural,
            preferences=tuple(preferences),
        )

    def curve_preference(self, qf: np.ndarray, joints) -> CurvePreference:
        """A preference for ``joints`` at their values in posture ``qf`` (a blend's frame)."""
        adr = self.m.jnt_qposadr[[self.solver.joint_id(j) for j in joints]]
        return CurvePreference(adr, self._dofs(joints), qf[adr].copy(), CURVE_TOL)

    def soft_targets(self, qf: np.ndarray, joints) -> list[cn.JointTarget]:
        """Soft targets keeping ``joints`` near posture ``qf`` (a blend to follow)."""
        adr = self.m.jnt_qposadr
        return [
            cn.JointTarget(j, float(qf[adr[self.solver.joint_id(j)]]), 0.3, "blend", soft=True)
            for j in sorted(joints)
        ]

    def penetrates(self, qf: np.ndarray, t: float) -> bool:
        """Whether posture ``qf`` penetrates beyond the limit outside time ``t``'s contacts."""
        d = self.solver.data
        d.qpos[:] = qf
        return cn.penetration_depth(self.m, d, self.s.allowed_at(t)) > cn.PENETRATION_LIMIT

    def track_curve(
        self, tkeys: list[Key], times: np.ndarray, dofs: np.ndarray, carried: list[float] = ()
    ):
        """Joint values (T, len(dofs)) of one track and a (T,) flag where it blends. A blend
        starts no earlier than the end of a key of another track that this track carries
        (``carried``, end times), so that it does not move a target while it is held."""
        out = np.tile(self.home[dofs], (len(times), 1))
        blend = np.zeros(len(times), bool)
        if not tkeys:
            return out, blend
        # Merge consecutive keys with the same posture into holds. A return to neutral
        # ends by the time its relax keys do (``due``): a key merged after it needs the
        # posture from its start.
        holds: list[list] = []
        for k in tkeys:
            qk = k.q[dofs]
            if (
                holds
                and abs(holds[-1][1] - k.start) < 1e-9
                and np.allclose(holds[-1][2], qk, atol=SAME_POSTURE)
            ):
                if holds[-1][1] == holds[-1][5] and k.relax:
                    holds[-1][5] = k.end
                holds[-1][1] = k.end
            else:
                holds.append(
                    [
                        k.start,
                        k.end,
                        qk,
                        k.relax,
                        all(isinstance(c, cn.JointTarget) for c in k.cons),
                        k.end,
                    ]
                )
        prev_q, prev_start, prev_end = self.home[dofs], 0.0, 0.0
        first = True
        for a, b, qk, relax, shape_only, due in holds:
            if relax:
                need = max(MIN_BLEND, 1.875 * float(np.max(np.abs(qk - prev_q))) / BLEND_SPEED)
                w0, w1 = a, min(b, a + max(need, min(MAX_BLEND, due - a)))
            elif self.mode is Mode.FLATTENED:
                w0, w1 = (a, a) if first else (prev_end, a)
            else:
                gap = a - prev_end
                need = max(MIN_BLEND, 1.875 * float(np.max(np.abs(qk - prev_q))) / BLEND_SPEED)
                # the shortest blend that keeps every joint under MAX_JOINT_SPEED
                fastest = 1.875 * float(np.max(np.abs(qk - prev_q))) / MAX_JOINT_SPEED
                if first and a <= 1e-9:
                    w0 = w1 = a
                elif gap >= 1e-9:
                    w0, w1 = max(prev_end, a - max(min(gap, MAX_BLEND), min(need, gap))), a
                    if first:
                        w0 = max(0.0, a - max(min(a, MAX_BLEND), need))
                    # a gap too short for the change: start inside the previous hold
                    if w1 - w0 < fastest and not first:
                        w0 = max(prev_start, w1 - fastest)
                else:  # no gap: blend at the end of the previous hold
                    w0, w1 = max(prev_start, a - need), a
                pins = [e for e in carried if e < w1 + 1e-9]
                if pins:  # never shorter than MIN_BLEND: a carried hold may end as this starts
                    w0 = max(w0, min(max(pins), w1 - MIN_BLEND))
                if w1 - w0 < fastest and not (first and a <= 1e-9) and shape_only:
                    w1 = min(b, w0 + fastest)  # still too fast: finish a shape change late
            sel = (times >= w0) & (times < w1)
            if w1 > w0:
                u = minjerk((times[sel] - w0) / (w1 - w0))[:, None]
                out[sel] = prev_q + u * (qk - prev_q)
                blend[sel] = True
            out[(times >= w1)] = qk
            prev_q, prev_end, prev_start, first = qk, b, a, False
        return out, blend

    def constrained_blends(self, q, times, moving, names, keys):
        """Frames where a blending track still has constraints become IK problems."""
        tp = [b for b in self.blocks if b.kind is sc.BlockKind.TRANSPATH]
        paths = {b.path: self.transpath_points(b, q, times) for b in tp}
        sites = {b.path: self.comp.site(b.transpath_site) for b in tp}
        limbs = {b.path: self.comp.site_tracks(sites[b.path]) for b in tp}
        curve = q.copy()
        still = _next_still(moving)
        needs: dict[tuple, set[int]] = {}  # constraints -> the dofs they move
        for f, t in enumerate(times):
            tracks = {names[i] for i in np.flatnonzero(moving[f])}
            cons, free = [], set()
            for tr in sorted(tracks):  # sorted: the same rows in any process
                # While blending, a key's constraints hold to its end, but for the joint
                # targets (hand shapes) the posture the blend heads for does not keep:
                # those joints are the blend's to move.
                i = next((i for i, k in enumerate(keys[tr]) if k.start <= t < k.end), None)
                if i is not None:
                    key, goal = keys[tr][i], self._goal(keys[tr], i, self.track_dofs[tr])
                    keep = [
                        c
                        for c in key.cons
                        if goal is None or c in goal.cons or not isinstance(c, cn.JointTarget)
                    ]
                    cons += [c for c in keep if c not in cons]
                    free |= set(key.free)
            for b in tp:
                if b.start <= t < b.end and limbs[b.path] & tracks:
                    cons.append(
                        cn.Place(
                            sites[b.path], Const(tuple(paths[b.path][f])), 1e-3, f"{b.path}@path"
                        )
                    )
                    free |= {j for tr in limbs[b.path] for j in self.track_joints[tr]}
            if not cons:
                free = {j for tr in sorted(tracks) for j in self.track_joints[tr]}
                soft = self.soft_targets(q[f], free)
                if f > 0 and free:
                    # after frames pushed out, back to the curve at most a step a frame
                    d, before = self._dofs(free), q[f - 1]
                    q[f][d] = np.clip(
                        q[f][d], before[d] - self.frame_step, before[d] + self.frame_step
                    )
                if tracks and self.penetrates(q[f], t):
                    # A blend that would pass through the body: push it out, staying close.
                    q0 = q[f].copy()
                    if f > 0:
                        # from half a step toward the curve from the frame before, moving at
                        # most half a step more: consecutive pushed frames cannot zig-zag
                        d, before = self._dofs(free), q[f - 1]
                        near = np.clip(
                            q[f][d], before[d] - self.frame_step, before[d] + self.frame_step
                        )
                        q0[d] = before[d] + 0.5 * (near - before[d])
                    q[f] = self.solve(
                        soft, sorted(free), q0, t, max_change=0.5 * self.frame_step, restarts=0
                    ).qpos
                    if f > 0 and self.penetrates(q[f], t):
                        # still through (it started deep in): from the frame before, clear
                        q[f] = self.solve(
                            soft,
                            sorted(free),
                            q[f - 1],
                            t,
                            max_change=0.5 * self.frame_step,
                            restarts=0,
                        ).qpos
                continue
            free |= {j for tr in tracks for j in self.track_joints[tr]}
            # The joints the constraints move start from the frame before (final by now),
            # advanced by the blend's step (the same branch), and among the postures that
            # meet the constraints take the one nearest the blend: a solve that starts where
            # its constraints are met stops at once, and would leave them still until the
            # next key. The others follow the blend, at most a step a frame from the frame
            # before.
            key = tuple(cons)
            if key not in needs:
                needs[key] = set(self.solver.free_dofs(ik.IKProblem(key)).tolist())
            needed = needs[key]
            moved = sorted(j for j in free if self._dofs([j])[0] in needed) or sorted(free)
            rest = sorted(set(free) - set(moved))
            step, q0 = self.frame_step, q[f].copy()
            bounds = self._reach(q, curve, still[f], f, names, tracks)
            if f > 0:
                before = q[f - 1]
                d = self._dofs(moved)
                q0[d] = before[d] + np.clip(curve[f][d] - curve[f - 1][d], -step, step)
                if rest:
                    d = self._dofs(rest)
                    q0[d] = np.clip(q0[d], before[d] - step, before[d] + step)
            if bounds is not None:
                q0 = np.clip(q0, *bounds)
            res = self.solve(
                cons,
                moved,
                q0,
                t,
                max_change=step,
                restarts=FRAME_RESTARTS,
                preferences=(self.curve_preference(q[f], moved),),
                prefer=q[f],
                bounds=bounds,
            )
            if rest and not res.converged and res.penetration > cn.PENETRATION_LIMIT:
                # the blend goes through the body: every joint may push it out
                res = self.solve(
                    cons + self.soft_targets(q[f], free),
                    sorted(free),
                    q0,
                    t,
                    max_change=step,
                    restarts=FRAME_RESTARTS,
                    bounds=bounds,
                )
            d = self._dofs(sorted(free))
            if f > 0 and np.abs(res.qpos[d] - q[f - 1][d]).max() > step + 1e-9:
                # a constraint far from the frame before (a key's hand shape that the blend
                # reaches late): from the frame before, at most a step
                q0[d] = q[f - 1][d]
                if bounds is not None:
                    q0 = np.clip(q0, *bounds)
                res = self.solve(
                    cons + self.soft_targets(q[f], free),
                    sorted(free),
                    q0,
                    t,
                    max_change=step,
                    restarts=FRAME_RESTARTS,
                    bounds=bounds,
                )
            q[f] = res.qpos
        return q

    def _reach(self, q, curve, goal, f: int, names, tracks):
        """Bounds (lower, upper) (nq,) keeping each blending track of frame ``f`` within
        reach of the posture its blend arrives at (``goal``: per track, the first frame it
        no longer blends, -1 if none): ``n`` frames before it, within ``n`` steps of it and
        still within a step of the frame before. A per-frame solve that follows a path onto
        another branch (the far side of the other arm) then returns to the key's in time,
        at most a step a frame, rather than snap at the key. None if no track has a goal."""
        step = self.frame_step
        lo, hi = self.solver.lower.copy(), self.solver.upper.copy()
        bounded = False
        for i, tr in enumerate(names):
            if tr not in tracks or goal[i] < 0:
                continue
            d, n = self.track_dofs[tr], goal[i] - f
            lo[d] = np.maximum(lo[d], curve[goal[i]][d] - n * step)
            hi[d] = np.minimum(hi[d], curve[goal[i]][d] + n * step)
            if f > 0:  # and a step at most from the frame before
                lo[d] = np.clip(lo[d], q[f - 1][d] - step, q[f - 1][d] + step)
                hi[d] = np.clip(hi[d], q[f - 1][d] - step, q[f - 1][d] + step)
            bounded = True
        return (lo, hi) if bounded else None

    def _goal(self, tkeys: list[Key], i: int, dofs: np.ndarray) -> Key | None:
        """The key a track's blend from key ``i`` heads for: the first after the keys that
        hold key ``i``'s posture on without a gap (None: the last posture)."""
        for a, b in zip(tkeys[i:], tkeys[i + 1 :]):
            if abs(a.end - b.start) > 1e-9 or not np.allclose(
                a.q[dofs], b.q[dofs], atol=SAME_POSTURE
            ):
                return b
        return None

    def _dofs(self, joints) -> np.ndarray:
        """Dof indices of joint names."""
        return np.array([self.m.jnt_dofadr[self.solver.joint_id(j)] for j in joints], int)

    def transpath_points(self, b: sc.Block, q: np.ndarray, times: np.ndarray) -> np.ndarray:
        """(T, 3) path points of a transpath for every frame (valid inside its interval)."""
        site = self.comp.site(b.transpath_site)
        sid = self.solver.site_id(site)
        d = self.solver.data
        fs = min(int(np.searchsorted(times, b.start - 1e-9)), len(times) - 1)
        fe = min(int(np.searchsorted(times, b.end - 1e-9)), len(times) - 1)
        ends = []
        for f in (fs, fe):
            d.qpos[:] = q[f]
            mujoco.mj_kinematics(self.m, d)
            ends.append(d.site_xpos[sid].copy())
        x0, x1 = ends
        u = minjerk((times - b.start) / b.duration)
        return path_points(b.route, x0, x1, u, self.s, q[fs])

    def flat_transpaths(self, q, times):
        """Flattened mode: a transpath adds keyframes along its path (the 2018 method)."""
        for b in (b for b in self.blocks if b.kind is sc.BlockKind.TRANSPATH):
            pts = self.transpath_points(b, q, times)
            sel = np.flatnonzero((times >= b.start) & (times < b.end))
            if not sel.size:
                continue
            site = self.comp.site(b.transpath_site)
            kf = sel[np.linspace(0, sel.size - 1, min(6, sel.size)).round().astype(int)]
            free = tuple(
                j
                for t in self.track_joints
                for j in self.track_joints[t]
                if t not in ("face", "eyes")
            )
            kq = {}
            for f in kf:
                soft = self.soft_targets(q[f], free)
                cons = [cn.Place(site, Const(tuple(pts[f])), 1e-3, f"{b.path}@path")]
                kq[f] = self.solve(cons + soft, free, q[f], times[f]).qpos
            # Whole-body blend between consecutive transpath keyframes.
            fr = sorted(kq)
            for f0, f1 in itertools.pairwise(fr):
                for f in range(f0, f1):
                    u = minjerk((f - f0) / (f1 - f0))
                    q[f] = kq[f0] + u * (kq[f1] - kq[f0])
            q[fr[-1]] = kq[fr[-1]]
        return q

    def trills(self, q: np.ndarray, times: np.ndarray) -> np.ndarray:
        """Pass 3: every trill added on top of the frames ``q`` (T, nq), in place."""
        d = self.solver.data
        m = self.m
        jac = np.empty((3, m.nv))
        for b in self.blocks:
            if b.kind is not sc.BlockKind.CSTR:
                continue
            for c in b.constraints:
                if not isinstance(c, sc.Trill):
                    continue
                dofs = np.concatenate([self.track_dofs[t] for t in sorted(self.comp.tracks_of(c))])
                sel = np.flatnonzero((times >= b.start) & (times < b.end))
                ramp = np.minimum(1.0, np.minimum(times[sel] - b.start, b.end - times[sel]) / 0.05)
                for f, env in zip(sel, ramp):
                    d.qpos[:] = q[f]
                    mujoco.mj_kinematics(m, d)
                    mujoco.mj_comPos(m, d)
                    v = self.solver.kinematics().value(compile_vector(c.vector, self.smap))
                    v = v / np.linalg.norm(v)
                    a = c.amplitude * env * np.sin(2 * np.pi * c.frequency * (times[f] - b.start))
                    if c.site is not None:
                        mujoco.mj_jacSite(
                            m, d, jac, None, self.solver.site_id(self.comp.site(c.site))
                        )
                    else:
                        mujoco.mj_jacBody(
                            m, d, None, jac, self.solver.body_id(c.bone.model_body(self.smap))
                        )
                    J = jac[:, dofs]
                    dq = J.T @ np.linalg.solve(J @ J.T + 1e-6 * np.eye(3), a * v)
                    q[f, dofs] = np.clip(
                        q[f, dofs] + dq, self.solver.lower[dofs], self.solver.upper[dofs]
                    )
                    if self.penetrates(q[f], times[f]):  # the shake must not go through
                        joints = {j for t in self.comp.tracks_of(c) for j in self.track_joints[t]}
                        q[f] = self.solve(
                            self.soft_targets(q[f], joints), sorted(joints), q[f], times[f]
                        ).qpos
        return q


def _next_still(moving: np.ndarray) -> np.ndarray:
    """(T, tracks) the first frame at or after each frame where each track does not blend
    (-1: it blends to the end)."""
    out = np.full(moving.shape, -1, int)
    nxt = np.full(moving.shape[1], -1, int)
    for f in range(len(moving) - 1, -1, -1):
        nxt = np.where(moving[f], nxt, f)
        out[f] = nxt
    return out


def path_points(route, x0, x1, u, sched: Schedule, q_start) -> np.ndarray:
    """Points (len(u), 3) of a transpath route from ``x0`` to ``x1`` at parameters ``u``."""
    u = np.asarray(u)[:, None]
    if isinstance(route, sc.Straight):
        return x0 + u * (x1 - x0)
    d = sched.solver.data
    d.qpos[:] = q_start
    mujoco.mj_kinematics(sched.m, d)
    kin, smap = sched.solver.kinematics(), sched.smap
    if isinstance(route, sc.Arc):
        bulge = kin.value(compile_vector(route.bulge, smap))
        mid = 0.5 * (x0 + x1) + bulge
        return arc_through(x0, mid, x1, u[:, 0])
    if isinstance(route, sc.Circle):
        c = kin.value(compile_point(route.center, smap))
        r0, r1 = x0 - c, x1 - c
        if route.normal is not None:
            n = kin.value(compile_vector(route.normal, smap))
        else:
            n = np.cross(r0, r1)
        n = n / max(np.linalg.norm(n), 1e-12)
        e1 = r0 - n * (r0 @ n)
        e2 = np.cross(n, e1)
        rad0 = np.linalg.norm(e1)
        e1, e2 = e1 / rad0, e2 / np.linalg.norm(e2)
        p1 = r1 - n * (r1 @ n)
        end_angle = np.arctan2(p1 @ e2, p1 @ e1) % (2 * np.pi)
        total = 2 * np.pi * route.turns + (end_angle if np.linalg.norm(p1) > 1e-9 else 0.0)
        if end_angle < 1e-6:
            total = 2 * np.pi * route.turns
        ang = u[:, 0] * total
        rad = rad0 + u[:, 0] * (np.linalg.norm(p1) - rad0)
        h = (r0 @ n) + u[:, 0] * ((r1 @ n) - (r0 @ n))
        return (
            c
            + rad[:, None] * (np.cos(ang)[:, None] * e1 + np.sin(ang)[:, None] * e2)
            + h[:, None] * n
        )
    raise TypeError(route)


def arc_through(a, b, c, u) -> np.ndarray:
    """Points of the circular arc from ``a`` through ``b`` to ``c`` at fractions ``u``."""
    ab, ac = b - a, c - a
    n = np.cross(ab, ac)
    if np.linalg.norm(n) < 1e-12:
        return a + u[:, None] * (c - a)
    # Circumcentre of the triangle.
    cc = a + (np.cross(n, ab) * (ac @ ac) + np.cross(ac, n) * (ab @ ab)) / (2 * (n @ n))
    n = n / np.linalg.norm(n)
    e1 = (a - cc) / np.linalg.norm(a - cc)
    e2 = np.cross(n, e1)
    r = np.linalg.norm(a - cc)

    def ang(p):
        v = p - cc
        return np.arctan2(v @ e2, v @ e1) % (2 * np.pi)

    total = ang(c)  # a is at angle 0; going through b in the +n sense reaches c at ang(c)
    return cc + r * (np.cos(u * total)[:, None] * e1 + np.sin(u * total)[:, None] * e2)
