"""Blocks scheduled per articulator track, postures solved per segment, frames rolled out.

The realizer (:func:`realize`) works in three steps.

1. **Schedule.** Every constraint drives some tracks of the signer (``spine``, ``head``,
   ``eyes``, ``face``, ``arm_X``, ``hand_X``; see :func:`constraint_tracks`). The block
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

``Mode.FLATTENED`` is the 2018 method for comparison: one whole-body key posture at every
block boundary and a whole-body blend between consecutive keys.

Units: seconds, metres, radians.
"""

from __future__ import annotations

import dataclasses
import enum
import time as _time
from collections.abc import Callable, Mapping

import mujoco
import numpy as np

from azee_mj import constraints as cn
from azee_mj import ik
from azee_mj import score as sc
from azee_mj.kinematics import Const, compile_point, compile_vector
from azee_mj.schedule import Compiler, make_solver
from azee_mj.sites import DEFAULT_MAP, SignerMap

#: Longest blend between two postures of a track when the gap allows more [s].
MAX_BLEND = 0.6
#: Shortest blend when a posture must change with no gap [s].
MIN_BLEND = 0.08
#: Postures closer than this per joint [rad] are the same (the solver's accuracy).
SAME_POSTURE = 2e-3
#: Peak joint speed a blend is sized for [rad/s] (the limit is 25 rad/s).
BLEND_SPEED = 12.0


class Mode(enum.Enum):
    """How the score is laid out in time."""

    MULTITRACK = "multitrack"
    FLATTENED = "flattened"


# ---------------------------------------------------------------------------------------
# Records
# ---------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class TrackInterval:
    """Track ``track`` driven by block ``block`` over ``[start, end)`` [s]."""

    track: str
    block: str
    start: float
    end: float


@dataclasses.dataclass(frozen=True)
class ConstraintTrace:
    """The residual of one constraint over the frames of its block's interval.

    ``values`` (T,) is NaN outside ``[start, end)``; unit is ``m`` or ``rad``.
    """

    block: str
    index: int
    kind: str
    tol: float
    unit: str
    start: float
    end: float
    values: np.ndarray

    @property
    def worst(self) -> float:
        v = self.values[~np.isnan(self.values)]
        return float(v.max()) if v.size else 0.0

    @property
    def ok(self) -> bool:
        return self.worst <= self.tol

    def describe(self) -> str:
        """``BLOCK constraint i (kind): worst X mm (tol Y mm)``, in mm or degrees."""
        k, u = (1000.0, "mm") if self.unit == "m" else (float(np.degrees(1.0)), "deg")
        return (f"{self.block} constraint {self.index} ({self.kind}): worst {self.worst * k:.2f}"
                f" {u} (tol {self.tol * k:.2f} {u})")


@dataclasses.dataclass(frozen=True)
class ContactWindow:
    """A contact constraint's interval ``[start, end)`` [s] and the two model bodies it
    brings together (allowed to touch then)."""

    start: float
    end: float
    body: int
    other: int


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
      time: (T,) frame times [s], ``k / fps``.
      qpos: (T, nq) postures in ``signer.xml`` joint order.
      site_names: (S,) AZee site names; ``site_pos`` (T, S, 3) their positions [m].
      schedule: per track, the intervals blocks drive it.
      traces: residual of every place / orient / look constraint over its interval.
    """

    fps: float
    mode: Mode
    time: np.ndarray
    qpos: np.ndarray
    site_names: tuple[str, ...]
    site_pos: np.ndarray
    schedule: Mapping[str, tuple[TrackInterval, ...]]
    traces: tuple[ConstraintTrace, ...]
    stats: SolveStats

    def report(self) -> dict:
        """The JSON report: residuals per constraint and block, and timings."""
        s = self.stats
        return {
            "fps": self.fps,
            "mode": self.mode.value,
            "frames": len(self.time),
            "duration_s": float(self.time[-1]) if len(self.time) else 0.0,
            "constraints": [
                {"block": t.block, "index": t.index, "kind": t.kind, "unit": t.unit,
                 "tol": float(t.tol), "worst": t.worst, "ok": bool(t.ok)}
                for t in self.traces
            ],  # fmt: skip
            "all_within_tolerance": bool(all(t.ok for t in self.traces)),
            "schedule": {
                k: [{"block": i.block, "start": i.start, "end": i.end} for i in v]
                for k, v in self.schedule.items()
            },
            "stats": {
                "ik_problems": s.problems, "key_problems": s.key_problems,
                "iterations": s.iterations, "not_converged": s.not_converged,
                "solve_time_s": s.solve_time, "total_time_s": s.total_time,
            },  # fmt: skip
        }


# ---------------------------------------------------------------------------------------
# Pass 1: segments and key postures
# ---------------------------------------------------------------------------------------


@dataclasses.dataclass
class _Key:
    """One track's posture over a segment, and the constraints that hold it there."""

    start: float
    end: float
    q: np.ndarray  # (nq,) the component's solved posture (only this track's joints count)
    cons: tuple  # ik constraints of the component (hard), for frames inside this key
    free: tuple[str, ...]  # joints of the component


def _minjerk(u: np.ndarray | float):
    u = np.clip(u, 0.0, 1.0)
    return u**3 * (10.0 - 15.0 * u + 6.0 * u**2)


class Realizer:
    def __init__(self, score: sc.Score, solver: ik.Solver, fps: float, mode: Mode,
                 signer_map: SignerMap = DEFAULT_MAP):  # fmt: skip
        self.score, self.solver, self.fps, self.mode = score, solver, fps, mode
        self.m = solver.model
        self.smap = signer_map
        self.comp = Compiler(self.m, self.smap)
        self.track_joints = {t: tuple(js) for t, js in self.smap.tracks.items()}
        self.track_dofs = {
            t: np.array([self.m.jnt_dofadr[solver.joint_id(j)] for j in js], int)
            for t, js in self.track_joints.items()
        }
        self.home = solver.natural.copy()
        self.blocks = [b for b in score.blocks()]
        self.by_path = {b.path: b for b in self.blocks}
        self.results: list[ik.IKResult] = []
        self.n_key = 0
        self.contacts = self._contact_windows()
        self._moved_cache: dict = {}
        self.body_names = [mujoco.mj_id2name(self.m, mujoco.mjtObj.mjOBJ_BODY, b)
                           for b in range(self.m.nbody)]  # fmt: skip

    def _contact_windows(self) -> list[ContactWindow]:
        """The window of every contact constraint of the score."""
        out = []
        for b in self.blocks:
            for c in b.constraints if b.kind is sc.BlockKind.CSTR else ():
                partners = self.comp.partner_sites(c)
                if partners:
                    body = int(self.m.site_bodyid[self.solver.site_id(self.comp.site(c.site))])
                for s in partners:
                    other = int(self.m.site_bodyid[self.solver.site_id(s)])
                    out.append(ContactWindow(b.start, b.end, body, other))
        return out

    def _allowed_at(self, t: float) -> frozenset[tuple[int, int]]:
        """Body pairs a contact active at time ``t`` [s] brings together (both orders)."""
        pairs = set()
        for w in self.contacts:
            if w.start - 1e-9 <= t < w.end:
                pairs |= {(w.body, w.other), (w.other, w.body)}
        return frozenset(pairs)

    # -- helpers ---------------------------------------------------------------------------
    def _solve(self, cons, free, q0, t: float) -> ik.IKResult:
        names = self.body_names
        touching = tuple((names[a], names[b]) for a, b in self._allowed_at(t) if a < b)
        res = self.solver.solve(ik.IKProblem(tuple(cons), tuple(free), touching, q0), q0)
        self.results.append(res)
        return res

    def _block_cons(self, b: sc.Block):
        """(ik constraints, morph joint changes, tracks) per constraint of a cstr block."""
        out = []
        for c in b.constraints:
            label = f"{b.path}#{c.index}"
            tracks = self.comp.tracks_of(c)
            if isinstance(c, sc.MorphC):
                out.append((None, self.comp.morph_changes(c), tracks, c))
            elif isinstance(c, sc.Trill):
                out.append((None, {}, tracks, c))
            else:
                out.append((self.comp.constraint(c, label), {}, tracks, c))
        return out

    def schedule(self) -> dict[str, tuple[TrackInterval, ...]]:
        sched: dict[str, list[TrackInterval]] = {t: [] for t in self.track_joints}
        for b in self.blocks:
            if b.kind is sc.BlockKind.CSTR:
                tracks = set().union(*(self.comp.tracks_of(c) for c in b.constraints))
            elif b.kind is sc.BlockKind.HOLD:
                tracks = self._held_tracks(b)
            elif b.kind is sc.BlockKind.TRANSPATH:
                tracks = self.comp.site_tracks(self.comp.site(b.transpath_site))
            else:
                continue
            for t in tracks:
                sched[t].append(TrackInterval(t, b.path, b.start, b.end))
        return {t: tuple(sorted(v, key=lambda i: (i.start, i.end))) for t, v in sched.items()}

    def _held_tracks(self, hold: sc.Block) -> set[str]:
        held = self.by_path[hold.hold_of]
        out: set[str] = set()
        for b in held.blocks():
            if b.kind is sc.BlockKind.CSTR:
                for c in b.constraints:
                    if not isinstance(c, sc.Trill):
                        out |= self.comp.tracks_of(c)
            elif b.kind is sc.BlockKind.HOLD:
                out |= self._held_tracks(b)
        return out

    def events(self) -> list[float]:
        ts = {0.0, self.score.duration}
        for b in self.blocks:
            if b.kind in (sc.BlockKind.CSTR, sc.BlockKind.HOLD):
                ts.update((b.start, b.end))
        return sorted(t for t in ts if 0.0 <= t <= self.score.duration)

    def key_postures(self) -> dict[str, list[_Key]]:
        """Pass 1: solve each segment's components in time order."""
        keys: dict[str, list[_Key]] = {t: [] for t in self.track_joints}
        state = self.home.copy()  # the posture each track holds now
        ev = self.events()
        cstr = [(b, self._block_cons(b)) for b in self.blocks if b.kind is sc.BlockKind.CSTR]
        holds = [b for b in self.blocks if b.kind is sc.BlockKind.HOLD]
        for t0, t1 in zip(ev[:-1], ev[1:]):
            items = []  # (ik constraint | None, morph changes, tracks, starts_now)
            for b, cons in cstr:
                if b.start <= t0 < b.end:
                    items += [(c, mch, tr, b.start == t0) for c, mch, tr, src in cons
                              if not isinstance(src, sc.Trill)]  # fmt: skip
            held: set[str] = set()
            for h in holds:
                if h.start <= t0 < h.end:
                    # Rule 4: the held block is realized (it ended before); keep its posture.
                    at = self.by_path[h.hold_of].end
                    for t in self._held_tracks(h) - held:
                        q = self._track_posture_at(keys[t], at).copy()
                        state[self.track_dofs[t]] = q[self.track_dofs[t]]
                        keys[t].append(_Key(t0, t1, q, (), self.track_joints[t]))
                        held.add(t)
            items = [it for it in items if not it[2] <= held]
            if not items:
                continue
            if self.mode is Mode.FLATTENED:
                # One whole-body problem: every track but the face and eyes is free.
                driven = set().union(*(tr for _, _, tr, _ in items))
                groups = [driven | (set(self.track_joints) - {"face", "eyes"})]
            else:
                groups = _components([tr for _, _, tr, _ in items])
            # Hand shapes and face first: a placed fingertip depends on its hand's shape.
            groups.sort(key=lambda g: any(it[0] is not None for it in items if it[2] & g))
            before = state.copy()
            solved = []
            for g in groups:
                solved.append(self._solve_group(g, items, state, keys, t0))
                for t in g:
                    state[self.track_dofs[t]] = solved[-1][0].qpos[self.track_dofs[t]]
            if self.mode is Mode.MULTITRACK and any(not r.converged for r, _, _ in solved):
                # Out of the limbs' reach alone: let the trunk help, and since moving it
                # moves everything above it, solve every active track together.
                group = set().union(*groups) | {"spine"}
                retry = self._solve_group(group, items, before, keys, t0)
                if retry[0].converged or _violation(retry[0]) < sum(_violation(r) for r, _, _ in solved):
                    groups, solved = [group], [retry]
            for group, (res, cons, free) in zip(groups, solved):
                for t in group:
                    d = self.track_dofs[t]
                    state[d] = res.qpos[d]
                    keys[t].append(_Key(t0, t1, res.qpos.copy(), tuple(cons), free))
        return keys

    def _solve_group(self, group: set[str], items, state: np.ndarray, keys, t0: float):
        """Solve the constraints of ``items`` that drive tracks of ``group`` (rule 2:
        placements first when a block starts with both). When the constraints are some of
        those that held the group until now (blocks only ended), nothing needs to move and
        the posture is kept. Returns (result, cons, free)."""
        mine = [it for it in items if it[2] & group]
        cons, targets = [], {}
        for c, mch, _, _ in mine:
            if c is not None:
                cons.append(c)
            for j, v in mch.items():
                targets[j] = targets.get(j, 0.0) + v
        cons += self._joint_targets(targets)
        free = tuple(j for t in sorted(group) for j in self.track_joints[t])
        prev = [keys[t][-1] for t in group if keys[t] and abs(keys[t][-1].end - t0) < 1e-9]
        if len(prev) == len(group) and set(cons) <= set().union(*(k.cons for k in prev)):
            kept = ik.IKResult(state.copy(), True, (), 0.0, 0, 0, 0.0, np.zeros(0))
            return kept, cons, free
        q0 = state.copy()
        places = [c for c in cons if not isinstance(c, (ik.Orient, ik.Look))]
        if len(places) < len(cons) and any(it[3] for it in mine) and places:
            q0 = self._solve(places, free, q0, t0).qpos
            self.n_key += 1
        res = self._solve(cons, free, q0, t0)
        self.n_key += 1
        return res, cons, free

    def _joint_targets(self, changes: dict[str, float], tol: float = 0.02):
        out = []
        for j, v in changes.items():
            jid = self.solver.joint_id(j)
            lo, hi = self.m.jnt_range[jid]
            val = float(np.clip(self.m.qpos0[self.m.jnt_qposadr[jid]] + v, lo, hi))
            out.append(cn.JointTarget(j, val, tol, f"morph:{j}"))
        return out

    def _track_posture_at(self, tkeys: list[_Key], t: float) -> np.ndarray:
        before = [k for k in tkeys if k.start < t - 1e-9]
        return (before[-1].q if before else self.home)

    # -- pass 2: frames ------------------------------------------------------------------
    def frames(self, keys: dict[str, list[_Key]]) -> np.ndarray:
        T = int(np.floor(self.score.duration * self.fps + 1e-9)) + 1
        times = np.arange(T) / self.fps
        q = np.tile(self.home, (T, 1))
        moving = np.zeros((T, len(self.track_joints)), bool)
        names = list(self.track_joints)
        for ti, t in enumerate(names):
            d = self.track_dofs[t]
            q[:, d], moving[:, ti] = self._track_curve(keys[t], times, d, self._carried(t, keys))
        if self.mode is Mode.FLATTENED:
            return self._flat_transpaths(q, times)
        return self._constrained_blends(q, times, moving, names, keys)

    def _carried(self, track: str, keys: dict[str, list[_Key]]) -> list[float]:
        """End times [s] of other tracks' keys with a constraint that names a body this
        track moves (a hand held in front of the chin is carried by the head track)."""
        return sorted(k.end for t, tk in keys.items() if t != track for k in tk
                      if any(track in self._moved_by(c) for c in k.cons))  # fmt: skip

    def _track_curve(self, tkeys: list[_Key], times: np.ndarray, dofs: np.ndarray,
                     carried: list[float] = ()):  # fmt: skip
        """Joint values (T, len(dofs)) of one track and a (T,) flag where it blends. A blend
        starts no earlier than the end of a key of another track that this track carries
        (``carried``, end times), so that it does not move a target while it is held."""
        out = np.tile(self.home[dofs], (len(times), 1))
        blend = np.zeros(len(times), bool)
        if not tkeys:
            return out, blend
        # Merge consecutive keys with the same posture into holds.
        holds: list[list] = []
        for k in tkeys:
            qk = k.q[dofs]
            if holds and abs(holds[-1][1] - k.start) < 1e-9 and np.allclose(holds[-1][2], qk, atol=SAME_POSTURE):
                holds[-1][1] = k.end
            else:
                holds.append([k.start, k.end, qk])
        prev_q, prev_start, prev_end = self.home[dofs], 0.0, 0.0
        first = True
        for a, b, qk in holds:
            if self.mode is Mode.FLATTENED:
                w0, w1 = (a, a) if first else (prev_end, a)
            else:
                gap = a - prev_end
                need = max(MIN_BLEND, 1.875 * float(np.max(np.abs(qk - prev_q))) / BLEND_SPEED)
                if first and a <= 1e-9:
                    w0 = w1 = a
                elif gap >= 1e-9:
                    w0, w1 = max(prev_end, a - max(min(gap, MAX_BLEND), min(need, gap))), a
                    if first:
                        w0 = max(0.0, a - max(min(a, MAX_BLEND), need))
                else:  # no gap: blend at the end of the previous hold
                    w0, w1 = max(prev_start, a - need), a
                pins = [e for e in carried if e < w1 + 1e-9]
                if pins:  # never shorter than MIN_BLEND: a carried hold may end as this starts
                    w0 = max(w0, min(max(pins), w1 - MIN_BLEND))
            sel = (times >= w0) & (times < w1)
            if w1 > w0:
                u = _minjerk((times[sel] - w0) / (w1 - w0))[:, None]
                out[sel] = prev_q + u * (qk - prev_q)
                blend[sel] = True
            out[(times >= w1)] = qk
            prev_q, prev_end, prev_start, first = qk, b, a, False
        return out, blend

    def _constrained_blends(self, q, times, moving, names, keys):
        """Frames where a blending track still has constraints become IK problems."""
        tp = [b for b in self.blocks if b.kind is sc.BlockKind.TRANSPATH]
        paths = {b.path: self._transpath_points(b, q, times) for b in tp}
        sites = {b.path: self.comp.site(b.transpath_site) for b in tp}
        limbs = {b.path: self.comp.site_tracks(sites[b.path]) for b in tp}
        prev = None
        for f, t in enumerate(times):
            tracks = {names[i] for i in np.flatnonzero(moving[f])}
            cons, free = [], set()
            for tr in tracks:
                # While blending toward the next posture, keep what both postures keep.
                key = next((k for k in keys[tr] if k.start <= t < k.end), None)
                nxt = next((k for k in keys[tr] if k.start > t), None)
                if key is not None:
                    keep = [c for c in key.cons if nxt is None or c in nxt.cons]
                    cons += [c for c in keep if c not in cons]
                    free |= set(key.free)
            for b in tp:
                if b.start <= t < b.end and limbs[b.path] & tracks:
                    cons.append(cn.Place(sites[b.path], Const(tuple(paths[b.path][f])), 1e-3,
                                         f"{b.path}@path"))  # fmt: skip
                    free |= {j for tr in limbs[b.path] for j in self.track_joints[tr]}
            if not cons:
                if tracks and self._penetrates(q[f], t):
                    # A blend that would pass through the body: push it out, staying close.
                    free = {j for tr in tracks for j in self.track_joints[tr]}
                    soft = self._soft_targets(q[f], free)
                    q[f] = prev = self._solve(soft, sorted(free), q[f], t).qpos
                continue
            free |= {j for tr in tracks for j in self.track_joints[tr]}
            soft = self._soft_targets(q[f], free)
            q0 = q[f].copy()
            if prev is not None:
                dofs = [self.m.jnt_dofadr[self.solver.joint_id(j)] for j in free]
                q0[dofs] = prev[dofs]
            res = self._solve(cons + soft, sorted(free), q0, t)
            q[f] = res.qpos
            prev = res.qpos
        return q

    def _moved_by(self, c) -> set[str]:
        """Tracks whose joints move a body that IK constraint ``c`` names."""
        if c not in self._moved_cache:
            bodies = self.solver.bodies_of(c)
            self._moved_cache[c] = set().union(
                *(self.comp.body_tracks(b, own_only=False) for b in bodies))
        return self._moved_cache[c]

    def _soft_targets(self, qf: np.ndarray, joints) -> list[cn.JointTarget]:
        adr = self.m.jnt_qposadr
        return [cn.JointTarget(j, float(qf[adr[self.solver.joint_id(j)]]), 0.3, "blend", soft=True)
                for j in sorted(joints)]  # fmt: skip

    def _penetrates(self, qf: np.ndarray, t: float) -> bool:
        d = self.solver.data
        d.qpos[:] = qf
        return cn.penetration_depth(self.m, d, self._allowed_at(t)) > cn.PENETRATION_LIMIT

    def _transpath_points(self, b: sc.Block, q: np.ndarray, times: np.ndarray) -> np.ndarray:
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
        u = _minjerk((times - b.start) / b.duration)
        return _path_points(b.route, x0, x1, u, self, q[fs])

    def _flat_transpaths(self, q, times):
        """Flattened mode: a transpath adds keyframes along its path (the 2018 method)."""
        for b in (b for b in self.blocks if b.kind is sc.BlockKind.TRANSPATH):
            pts = self._transpath_points(b, q, times)
            sel = np.flatnonzero((times >= b.start) & (times < b.end))
            if not sel.size:
                continue
            site = self.comp.site(b.transpath_site)
            kf = sel[np.linspace(0, sel.size - 1, min(6, sel.size)).round().astype(int)]
            free = tuple(j for t in self.track_joints for j in self.track_joints[t]
                         if t not in ("face", "eyes"))  # fmt: skip
            kq = {}
            for f in kf:
                soft = self._soft_targets(q[f], free)
                cons = [cn.Place(site, Const(tuple(pts[f])), 1e-3, f"{b.path}@path")]
                kq[f] = self._solve(cons + soft, free, q[f], times[f]).qpos
            # Whole-body blend between consecutive transpath keyframes.
            fr = sorted(kq)
            for f0, f1 in zip(fr[:-1], fr[1:]):
                for f in range(f0, f1):
                    u = _minjerk((f - f0) / (f1 - f0))
                    q[f] = kq[f0] + u * (kq[f1] - kq[f0])
            q[fr[-1]] = kq[fr[-1]]
        return q

    # -- pass 3: trills ----------------------------------------------------------------
    def trills(self, q: np.ndarray, times: np.ndarray) -> np.ndarray:
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
                        mujoco.mj_jacSite(m, d, jac, None, self.solver.site_id(self.comp.site(c.site)))
                    else:
                        mujoco.mj_jacBody(m, d, None, jac, self.solver.body_id(c.bone.model_body(self.smap)))
                    J = jac[:, dofs]
                    dq = J.T @ np.linalg.solve(J @ J.T + 1e-6 * np.eye(3), a * v)
                    q[f, dofs] = np.clip(q[f, dofs] + dq, self.solver.lower[dofs],
                                         self.solver.upper[dofs])  # fmt: skip
                    if self._penetrates(q[f], times[f]):  # the shake must not go through
                        joints = {j for t in self.comp.tracks_of(c) for j in self.track_joints[t]}
                        q[f] = self._solve(self._soft_targets(q[f], joints), sorted(joints), q[f],
                                           times[f]).qpos  # fmt: skip
        return q

    # -- residuals ---------------------------------------------------------------------
    def traces(self, q: np.ndarray, times: np.ndarray) -> tuple[ConstraintTrace, ...]:
        out = []
        d = self.solver.data
        for b in self.blocks:
            if b.kind is not sc.BlockKind.CSTR:
                continue
            for c in b.constraints:
                ic = self.comp.constraint(c, f"{b.path}#{c.index}")
                if ic is None:
                    continue
                vals = np.full(len(times), np.nan)
                for f in np.flatnonzero((times >= b.start - 1e-9) & (times < b.end - 1e-9)):
                    d.qpos[:] = q[f]
                    mujoco.mj_kinematics(self.m, d)
                    vals[f] = ic.residual(self.solver.kinematics())
                unit = "m" if isinstance(ic, cn.Place) else "rad"
                out.append(ConstraintTrace(b.path, c.index, type(c).__name__.lower(), ic.tol,
                                           unit, b.start, b.end, vals))  # fmt: skip
        return tuple(out)


def _violation(res: ik.IKResult) -> float:
    """How far a result is from its tolerances (sum of value / tol over the violated)."""
    return sum(r.value / r.tol for r in res.residuals if not r.ok) + res.penetration / 1e-3


def _components(track_sets: list[set[str]]) -> list[set[str]]:
    """Connected components of tracks coupled by the given sets."""
    groups: list[set[str]] = []
    for s in track_sets:
        s = set(s)
        merged = [g for g in groups if g & s]
        for g in merged:
            s |= g
            groups.remove(g)
        groups.append(s)
    return groups


def _path_points(route, x0, x1, u, realizer: Realizer, q_start) -> np.ndarray:
    """Points (len(u), 3) of a transpath route from ``x0`` to ``x1`` at parameters ``u``."""
    u = np.asarray(u)[:, None]
    if isinstance(route, sc.Straight):
        return x0 + u * (x1 - x0)
    d = realizer.solver.data
    d.qpos[:] = q_start
    mujoco.mj_kinematics(realizer.m, d)
    kin, smap = realizer.solver.kinematics(), realizer.smap
    if isinstance(route, sc.Arc):
        bulge = kin.value(compile_vector(route.bulge, smap))
        mid = 0.5 * (x0 + x1) + bulge
        return _arc_through(x0, mid, x1, u[:, 0])
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
        return c + rad[:, None] * (np.cos(ang)[:, None] * e1 + np.sin(ang)[:, None] * e2) + h[:, None] * n
    raise TypeError(route)


def _arc_through(a, b, c, u) -> np.ndarray:
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


# ---------------------------------------------------------------------------------------
# Public API
# ---------------------------------------------------------------------------------------


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
    if fps <= 0:
        raise ValueError(f"fps must be positive, got {fps}")
    smap = signer_map or DEFAULT_MAP
    solver = solver or make_solver(signer_map=smap)
    r = Realizer(score, solver, fps, mode, smap)
    tick = progress or (lambda f: None)
    keys = r.key_postures()
    tick(0.4)
    q = r.frames(keys)
    tick(0.8)
    times = np.arange(q.shape[0]) / fps
    # Residuals are those of the postures the blocks ask for: a trill is added on top.
    traces = r.traces(q, times)
    q = r.trills(q, times)
    site_names = tuple(smap.sites)
    sids = np.array([solver.site_id(s) for s in smap.sites.values()])
    d = solver.data
    site_pos = np.empty((len(times), len(sids), 3))
    for f in range(len(times)):
        d.qpos[:] = q[f]
        mujoco.mj_kinematics(solver.model, d)
        site_pos[f] = d.site_xpos[sids]
    tick(1.0)
    res = r.results
    stats = SolveStats(
        problems=len(res), key_problems=r.n_key, iterations=sum(x.iterations for x in res),
        not_converged=sum(not x.converged for x in res),
        solve_time=sum(x.time for x in res), total_time=_time.perf_counter() - t_start,
        per_problem_iterations=np.array([x.iterations for x in res]),
    )  # fmt: skip
    return Rollout(fps, mode, times, q, site_names, site_pos, r.schedule(), traces, stats)


def schedule(score: sc.Score | str, solver: ik.Solver | None = None
             ) -> dict[str, tuple[TrackInterval, ...]]:
    """Per track, the intervals blocks drive it, without solving anything."""
    if not isinstance(score, sc.Score):
        score = sc.load_score(score)
    return Realizer(score, solver or make_solver(), 1.0, Mode.MULTITRACK).schedule()


def contact_pairs(score: sc.Score | str | Mapping, times: np.ndarray,
                  solver: ik.Solver | None = None) -> dict[int, frozenset[tuple[str, str]]]:
    """Frame -> body-name pairs that a contact constraint active then brings together."""
    if not isinstance(score, sc.Score):
        score = sc.load_score(score)
    r = Realizer(score, solver or make_solver(), 1.0, Mode.MULTITRACK)
    out: dict[int, set[tuple[str, str]]] = {}
    for w in r.contacts:
        for f in np.flatnonzero((times >= w.start - 1e-9) & (times < w.end)):
            out.setdefault(int(f), set()).add((r.body_names[w.body], r.body_names[w.other]))
    return {f: frozenset(v) for f, v in out.items()}


def score_traces(score: sc.Score | str, qpos: np.ndarray, fps: float,
                 solver: ik.Solver | None = None) -> tuple[ConstraintTrace, ...]:
    """Residual traces of ``score``'s constraints on given frames ``qpos`` (T, nq)."""
    if not isinstance(score, sc.Score):
        score = sc.load_score(score)
    r = Realizer(score, solver or make_solver(), fps, Mode.MULTITRACK)
    return r.traces(np.asarray(qpos, float), np.arange(len(qpos)) / fps)


def residual_summary(score: sc.Score | str, rollout: Rollout,
                     solver: ik.Solver | None = None) -> tuple[str, bool]:
    """A readable residual summary of a rollout's postures against ``score``, and whether
    every constraint is within its tolerance."""
    if not isinstance(score, sc.Score):
        score = sc.load_score(score)
    # A trill moves its block's posture on purpose: its block's residuals are not checked.
    trilled = {b.path for b in score.blocks() if any(isinstance(c, sc.Trill) for c in b.constraints)}
    traces = [t for t in score_traces(score, rollout.qpos, rollout.fps, solver)
              if t.block not in trilled]  # fmt: skip
    bad = [t for t in traces if not t.ok]
    lines = [f"{len(traces) - len(bad)}/{len(traces)} constraints within tolerance"
             + (f" ({len(trilled)} block(s) with a trill not checked)" if trilled else "")]
    lines += [f"  {t.describe()}" for t in bad[:8]]
    return "\n".join(lines), not bad
