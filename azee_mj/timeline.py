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

``Mode.FLATTENED`` is the 2018 method for comparison: one whole-body key posture at every
block boundary and a whole-body blend between consecutive keys.

Units: seconds, metres, radians.
"""

from __future__ import annotations

import dataclasses
import itertools
import time as _time
from collections.abc import Callable, Mapping

import mujoco
import numpy as np

from azee_mj import constraints as cn
from azee_mj import ik, mirror, natural, reach
from azee_mj import score as sc
from azee_mj.diagnose import diagnose
from azee_mj.kinematics import BodyAxis, BodyOrigin, Const, Lin, SitePos
from azee_mj.motion import SAME_POSTURE, Key, Mode, Motion
from azee_mj.reach import Arm
from azee_mj.schedule import DrivenConstraint, Schedule, TrackInterval, descends, make_solver
from azee_mj.sites import DEFAULT_MAP, DIGITS, SignerMap
from azee_mj.timing import check_fps, frame_count, frame_range

__all__ = [
    "ConstraintTrace",
    "Mode",
    "Realizer",
    "Rollout",
    "SolveStats",
    "realize",
    "residual_summary",
    "score_traces",
]

# ---------------------------------------------------------------------------------------
# Records
# ---------------------------------------------------------------------------------------


#: How nearly two skin surfaces a placement joins face each other [rad], by the hand part
#: that touches: flat parts of the hand meet flat, a finger pad nearly so, a fingertip or a
#: knuckle touches at an angle (a finger does not point straight into the face).
FACING_TOL = {
    "PA": 5.0,
    "H_BACK": 5.0,
    "H_EDGE": 10.0,
    "viande": 20.0,
    "PAD": 30.0,
    "TIP": 20.0,
    "NA": 45.0,
    "KN": 45.0,
    "KNi": 45.0,
    "BACK": 45.0,
    "INT": 45.0,
}
#: How much wider the facing tolerance of two joined hands gets when head-on they would
#: meet only behind the back (the realizer then joins them in front, leaning).
FACING_WIDEN = 2.0
#: How far from the signing space two joined hands may drift at the cost of one unit of
#: naturalness [m].
MEET_TOL = 0.1
#: Where the palm of an arm that the other hand touches (its elbow, forearm, upper arm)
#: rests, from that arm's shoulder joint [m]: forward, toward the midline, up. Its forearm
#: comes up in front of the body with the elbow bent and low, where the other hand meets it.
ACROSS = (0.25, 0.0, 0.1)
#: Two parts neither of which is a hand part (an elbow on the chest).
FACING_TOL_BODY = 20.0


#: An elbow held below its shoulder, as a natural preference when the hand is placed
#: below the eyes: (how far below [m], the height above that costs one unit [m]).
ELBOW_LOW = (0.02, 0.05)
#: Rounded parts of the body [deg]: a fingertip meets them from a range of directions
#: around the site's normal (the shoulder's cap, the forehead's and the temple's curve),
#: as far as the fingertip's own roundness lets the site meet within its tolerance without
#: sinking in.
FACING_TOL_ROUNDED = {"SH": 45.0, "FH": 40.0, "TE": 40.0}


def _facing_tol(a: str, b: str) -> float:
    """The facing tolerance [rad] of AZee sites ``a`` and ``b`` brought together: the hand
    part's, widened for a rounded part of the body."""

    def hand(site: str) -> float:
        parts = site.split("_")
        if len(parts) > 1 and parts[0] in DIGITS and parts[1] in FACING_TOL:
            return FACING_TOL[parts[1]]  # a finger part: I_TIP_R, T_KN_R_1
        return next((t for stem, t in FACING_TOL.items() if site.startswith(stem + "_")), 0.0)

    def rounded(site: str) -> float:
        return next(
            (
                t
                for stem, t in FACING_TOL_ROUNDED.items()
                if site == stem or site.startswith(stem + "_")
            ),
            0.0,
        )

    tol = max(hand(a), hand(b)) or FACING_TOL_BODY
    return np.radians(max(tol, rounded(a), rounded(b)))


#: How far the chest may lean from upright for one unit of naturalness cost, once the trunk
#: is recruited [deg]: far dearer than any joint's comfort, so the trunk leans only as much
#: as the constraints need.
UPRIGHT_TOL_DEG = 3.0
#: Bisection steps bringing a recruited trunk back toward neutral (1/32 of its lean).
LEAN_STEPS = 5
#: Tracks that return to neutral when no block needs them.
RELAXING = ("spine", "head")


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


# ---------------------------------------------------------------------------------------
# Key postures and frames
# ---------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Active:
    """A constraint active in a segment, and whether its block starts with the segment."""

    driven: DrivenConstraint
    starts_now: bool


class Realizer:
    """Key postures (pass 1), frames (pass 2, with :class:`~azee_mj.motion.Motion`) and
    residual traces of ``score``; use :func:`realize`."""

    def __init__(
        self,
        score: sc.Score,
        solver: ik.Solver,
        fps: float,
        mode: Mode,
        signer_map: SignerMap = DEFAULT_MAP,
    ):
        self.score, self.solver, self.fps, self.mode = score, solver, fps, mode
        self.sched = Schedule(score, solver, signer_map)
        self.motion = Motion(self.sched, mode, fps)
        self.m, self.smap, self.comp = self.sched.m, self.sched.smap, self.sched.comp
        self.track_joints, self.track_dofs = self.sched.track_joints, self.sched.track_dofs
        self.home, self.blocks, self.by_path = (
            self.sched.home,
            self.sched.blocks,
            self.sched.by_path,
        )
        self.n_key = 0
        #: constraint label -> why its key posture misses it (see :mod:`azee_mj.diagnose`)
        self.reasons: dict[str, str] = {}
        #: facing label -> (result, cons, free, start, t0) of a face-to-face solve that
        #: failed and was dropped for the placement alone
        self._unfaced: dict[str, tuple] = {}
        self.arms = reach.arms_of(self.smap)
        #: arm -> the model site of its palm's centre (AZee ``PA``), or None
        self._palms = {a: self._palm_site(a) for a in self.arms}
        self._azee_site = {model: azee for azee, model in self.smap.sites.items()}
        ssp = self.smap.loci.get("ssp")
        self._meet = (
            ssp
            if ssp is not None and mujoco.mj_name2id(self.m, mujoco.mjtObj.mjOBJ_SITE, ssp) >= 0
            else None
        )
        self._chest = chest = self.smap.bones.get("back_2")
        #: The chest upright, a preference once the trunk is recruited (least recruitment).
        self._upright = (
            ()
            if chest is None
            else (
                cn.Orient(
                    chest.body,
                    chest.dir,
                    cn.Rel.ALONG,
                    Const((0.0, 0.0, 1.0)),
                    np.radians(UPRIGHT_TOL_DEG),
                    "upright",
                ),
            )
        )

    def _take(self, state: np.ndarray, tracks, q: np.ndarray) -> None:
        """Copy the joints of ``tracks`` from posture ``q`` into ``state`` (in place)."""
        for t in tracks:
            state[self.track_dofs[t]] = q[self.track_dofs[t]]

    def _arm_carrying(self, site: str, part: str = "hand") -> Arm | None:
        """The arm whose ``part`` (``hand`` or ``upper``) carries model ``site``, or None."""
        body = int(self.m.site_bodyid[self.solver.site_id(site)])
        return next(
            (a for a in self.arms if descends(self.m, body, self.solver.body_id(getattr(a, part)))),
            None,
        )

    def _hand_of(self, site: str) -> Arm | None:
        """The arm whose hand carries model ``site`` (for the analytic seeds), or None."""
        return self._arm_carrying(site)

    def _carried_by(self, site: str):
        """(the arm whose forearm or upper arm carries model ``site``, that arm's palm
        site, where that palm rests: ``ACROSS``) when the site is not on its hand, else
        None (for the analytic seeds and the natural preferences)."""
        arm = self._arm_carrying(site, "upper")
        if arm is None or self._hand_of(site) is arm:
            return None
        palm = self._palms[arm]
        return None if palm is None else (arm, palm, self._across_at(arm))

    def _limb_root(self, site: str) -> int | None:
        """The body a site's arm hangs from (its clavicle), for the reach diagnosis."""
        arm = self._arm_carrying(site, "upper")
        return None if arm is None else int(self.m.body_parentid[self.solver.body_id(arm.upper)])

    @property
    def results(self) -> list[ik.IKResult]:
        """Every IK result solved so far, in order."""
        return self.motion.results

    def schedule(self) -> dict[str, tuple[TrackInterval, ...]]:
        """Per track, the intervals blocks drive it."""
        return self.sched.intervals()

    def key_postures(self) -> dict[str, list[Key]]:
        """Pass 1: solve each segment's components in time order."""
        keys: dict[str, list[Key]] = {t: [] for t in self.track_joints}
        state = self.home.copy()  # the posture each track holds now
        ev = self.sched.events()
        cstr = [
            (b, self.sched.block_constraints(b)) for b in self.blocks if b.kind is sc.BlockKind.CSTR
        ]
        holds = [b for b in self.blocks if b.kind is sc.BlockKind.HOLD]
        trills = [
            (b, dc.tracks) for b, cons in cstr for dc in cons if isinstance(dc.source, sc.Trill)
        ]

        def trill_tracks(t: float) -> list[set[str]]:
            return [tr for b, tr in trills if b.start <= t < b.end]

        for t0, t1 in itertools.pairwise(ev):
            items: list[Active] = []
            for b, cons in cstr:
                if b.start <= t0 < b.end:
                    items += [
                        Active(dc, b.start == t0)
                        for dc in cons
                        if not isinstance(dc.source, sc.Trill)
                    ]
            held: set[str] = set()
            for h in holds:
                if h.start <= t0 < h.end:
                    # Rule 4: the held block is realized (it ended before); keep its posture.
                    at = self.by_path[h.hold_of].end
                    for t in self.sched.held_tracks(h) - held:
                        q = self._track_posture_at(keys[t], at).copy()
                        state[self.track_dofs[t]] = q[self.track_dofs[t]]
                        keys[t].append(Key(t0, t1, q, (), self.track_joints[t]))
                        held.add(t)
            items = [it for it in items if not it.driven.tracks <= held]
            if self.mode is Mode.MULTITRACK:
                busy = held.union(*(it.driven.tracks for it in items), *trill_tracks(t0))
                self._relax(keys, state, busy, {it.driven.con for it in items}, t0, t1)
            if not items:
                continue
            if self.mode is Mode.FLATTENED:
                # One whole-body problem: every track but the face and eyes is free.
                driven = set().union(*(it.driven.tracks for it in items))
                groups = [driven | (set(self.track_joints) - {"face", "eyes"})]
            else:
                groups = _components([it.driven.tracks for it in items])
            groups = self._order(groups, items)
            before = state.copy()
            solved = []
            for g in groups:
                solved.append(self._solve_group(g, items, state, keys, t0))
                self._take(state, g, solved[-1][0].qpos)
            if self.mode is Mode.MULTITRACK and any(not r.converged for r, _, _ in solved):
                groups, solved = self._recruit_trunk(groups, solved, items, before, keys, t0)
            for group, (res, cons, free) in zip(groups, solved):
                if not res.converged:
                    problem = self.motion.problem(cons, free, before, t0, natural=False)
                    for dg in diagnose(self.solver, problem, res, before, self._limb_root):
                        if dg.label not in self.reasons:
                            self.reasons[dg.label] = dg.detail + self._why_not_facing(dg.label)
                for t in group:
                    d = self.track_dofs[t]
                    state[d] = res.qpos[d]
                    if keys[t] and keys[t][-1].start == t0:
                        keys[t].pop()  # recruited after all: no return to neutral here
                    keys[t].append(Key(t0, t1, res.qpos.copy(), tuple(cons), free))
        return keys

    def _order(self, groups: list[set[str]], items: list[Active]) -> list[set[str]]:
        """The order to solve a segment's groups in: a group whose tracks move a body that
        another group's constraints name first (the trunk before the head it carries, the
        head before a hand that touches it: solved the other way round, the later group
        moves the earlier one off its target). Otherwise (and in a cycle) hands and the
        face first (a placed fingertip depends on its hand's shape), then groups driven
        by morphs only, then by name (deterministic)."""

        def key(g):
            return (
                not all(t.startswith(("hand", "face", "eyes")) for t in g),
                any(it.driven.con is not None for it in items if it.driven.tracks & g),
                sorted(g),
            )

        needs = [
            set().union(
                *(
                    self.sched.moved_by(it.driven.con)
                    for it in items
                    if it.driven.tracks & g and it.driven.con is not None
                )
            )
            - g
            for g in groups
        ]
        rest = sorted(range(len(groups)), key=lambda i: key(groups[i]))
        out = []
        while rest:
            i = next(
                (i for i in rest if not any(needs[i] & groups[j] for j in rest if j != i)), rest[0]
            )
            rest.remove(i)
            out.append(groups[i])
        return out

    def _recruit_trunk(self, groups, solved, items, before: np.ndarray, keys, t0: float):
        """The limbs alone cannot meet some groups' constraints: the trunk helps them, as
        little as it can (the chest nearest upright among the postures that meet them).
        The groups met without it are then solved again on the moved trunk (it carries
        them) rather than riding along: a look turns the head only as far as it needs. If
        that fails, every active track is solved together with the trunk. Returns the
        (groups, solved) kept: the first that meets everything, else the least violation."""
        # a group the score drives the trunk with joins the groups it helps
        failed = [g for g, (r, _, _) in zip(groups, solved) if not r.converged or "spine" in g]
        met = [g for g in groups if g not in failed]
        helped = set().union(*failed) | {"spine"}
        state = before.copy()
        first_failed = next(i for i, g in enumerate(groups) if g in failed)
        for g, (r, _, _) in zip(groups[:first_failed], solved):
            self._take(state, g, r.qpos)  # solved before it: what the helped group builds on
        first = self._lean_less(
            self._solve_group(helped, items, state, keys, t0, upright=True), helped, items, keys, t0
        )
        out = [first]
        self._take(state, helped, first[0].qpos)
        for g in met:
            out.append(self._solve_group(g, items, state, keys, t0, reuse=False))
            self._take(state, g, out[-1][0].qpos)
        tries = [([helped, *met], out)]
        if met and not all(r.converged for r, _, _ in out):
            group = set().union(*groups) | {"spine"}
            together = self._solve_group(group, items, before, keys, t0, upright=True)
            tries.append(([group], [together]))

        def violation(cand) -> float:
            return sum(_violation(r) for r, _, _ in cand[1])

        best = (groups, solved)
        for cand in tries:
            if all(r.converged for r, _, _ in cand[1]):
                return cand
            if violation(cand) < violation(best):
                best = cand
        return best

    def _lean_less(self, solved, group: set[str], items, keys, t0: float):
        """Bring the trunk of a converged ``solved`` (result, cons, free) back toward
        neutral as far as the rest of ``group`` can still meet the constraints without it:
        a bisection on the fraction of the trunk's motion kept, the limbs solved again at
        each step from the last posture that met them. A solve lands where its start
        leads; this finds the least lean along the way it found. Returns the best solve."""
        res = solved[0]
        d = self.track_dofs.get("spine")
        asked = any("spine" in it.driven.tracks for it in items if it.driven.tracks & group)
        if not res.converged or d is None or asked:  # the score places the trunk itself
            return solved
        lean = res.qpos[d] - self.home[d]
        if np.abs(lean).max() < SAME_POSTURE:
            return solved
        lo, hi, best = 0.0, 1.0, solved
        for _ in range(LEAN_STEPS):
            f = 0.5 * (lo + hi)
            q = best[0].qpos.copy()
            q[d] = self.home[d] + f * lean
            res, cons, _ = self._solve_group(
                group, items, q, keys, t0, reuse=False, held=("spine",), restarts=0
            )
            if res.converged:
                hi, best = f, (res, cons, solved[2])
            else:
                lo = f
        return best

    def _relax(
        self, keys, state: np.ndarray, busy: set[str], active: set, t0: float, t1: float
    ) -> None:
        """The trunk and the head return to neutral over ``[t0, t1)`` when no block needs
        them: none drives them, and none that they were recruited for (their last key's
        constraints) is still ``active``."""
        for t in RELAXING:
            d = self.track_dofs.get(t)
            if d is None or t in busy or not keys[t] or set(keys[t][-1].cons) & active:
                continue
            if np.allclose(keys[t][-1].q[d], self.home[d], atol=SAME_POSTURE):
                continue
            state[d] = self.home[d]
            keys[t].append(Key(t0, t1, self.home.copy(), (), self.track_joints[t], relax=True))

    def _solve_group(
        self,
        group: set[str],
        items,
        state: np.ndarray,
        keys,
        t0: float,
        upright: bool = False,
        reuse: bool = True,
        held: tuple[str, ...] = (),
        restarts: int | None = None,
    ):
        """Solve the constraints of ``items`` that drive tracks of ``group`` (rule 2:
        placements first when a block starts with both). When the constraints are some of
        those that held the group until now (blocks only ended), nothing needs to move and
        the posture is kept (unless not ``reuse``: the trunk under it moved). The ``held``
        tracks of the group keep their posture in ``state``, and the solve continues from
        ``state`` (no placements-first start). ``upright``: the trunk was
        recruited; among the postures that meet the constraints, the one with the chest
        nearest upright is preferred. ``restarts``: the solver's, if None. Returns (result,
        cons, free)."""
        mine = [it for it in items if it.driven.tracks & group]
        cons, targets = [], {}
        for it in mine:
            if it.driven.con is not None:
                cons.append(it.driven.con)
            for j, v in it.driven.morph.items():
                targets[j] = targets.get(j, 0.0) + v
        cons += self._joint_targets(targets)
        free = tuple(j for t in sorted(group) if t not in held for j in self.track_joints[t])
        prev = [keys[t][-1] for t in group if keys[t] and abs(keys[t][-1].end - t0) < 1e-9]
        # (unless a track outside the group moved what they name: the head under a hand)
        carriers = set().union(*(self.sched.moved_by(c) for c in cons)) - group
        if (
            reuse
            and len(prev) == len(group)
            and set(cons) <= set().union(*(k.cons for k in prev))
            and all(
                np.allclose(
                    state[self.track_dofs[t]], prev[0].q[self.track_dofs[t]], atol=SAME_POSTURE
                )
                for t in carriers
            )
        ):
            kept = ik.IKResult(state.copy(), True, (), 0.0, 0, 0, 0.0, np.zeros(0))
            return kept, cons, free
        q0 = state.copy()
        places = [c for c in cons if not isinstance(c, (cn.Orient, cn.Look))]
        # Also start each arm in its natural two-bone posture for its hand's target.
        facing = self._facing(cons)
        seeds = reach.arm_seeds(
            self.solver,
            self.arms,
            cons + facing,
            free,
            q0,
            self._hand_of,
            self._meet,
            self._carried_by,
        )
        if not held and len(places) < len(cons) and any(it.starts_now for it in mine) and places:
            q0 = self.motion.solve(places, free, q0, t0, seeds, natural=False).qpos
            self.n_key += 1
        where = (
            self._meeting_place(cons)
            + self._elbows_low(cons, free, q0)
            + (self._upright if upright else ())
        )
        res = self.motion.solve(
            cons + facing, free, q0, t0, seeds, preferences=where, restarts=restarts
        )
        self.n_key += 1
        if facing and res.converged and self._joined_behind(cons, res.qpos):
            # Hands join in the signing space before they meet head-on: face to face with
            # a wider tolerance there (a fingertip on the back of the other hand, leaning).
            wide = [dataclasses.replace(f, tol=FACING_WIDEN * f.tol) for f in facing]
            alt = self.motion.solve(
                cons + wide, free, q0, t0, seeds, preferences=where, restarts=restarts
            )
            self.n_key += 1
            if alt.converged and not self._joined_behind(cons, alt.qpos):
                return alt, cons + wide, free
        if facing and not res.converged:
            # Face to face is a preference below the score's constraints: without it?
            plain = self.motion.solve(
                cons, free, q0, t0, seeds, preferences=where, restarts=restarts
            )
            self.n_key += 1
            if plain.converged or _violation(plain) < _violation(res):
                if not plain.converged:  # kept to say why face to face failed, if asked
                    self._unfaced.update(
                        {f.label: (res, cons + facing, free, q0, t0) for f in facing}
                    )
                return plain, cons, free
        return res, cons + facing, free

    def _why_not_facing(self, label: str) -> str:
        """Why placement ``label`` could not be met face to face, when it was solved
        without its facing after that failed (``"; face to face, ..."``), else ``""``."""
        kept = self._unfaced.get(f"{label}:facing")
        if kept is None:
            return ""
        res, cons, free, q0, t0 = kept
        problem = self.motion.problem(cons, free, q0, t0, natural=False)
        why = diagnose(self.solver, problem, res, q0, self._limb_root, only=f"{label}:facing")
        return f"; face to face, {why[0].detail}" if why else ""

    def _joined_behind(self, cons, q: np.ndarray) -> bool:
        """Whether a placement of ``cons`` that joins the two hands meets, in posture
        ``q``, behind the chest's frontal plane (the hands behind the back)."""
        chest = self._chest
        joined = [c for c in cons if self._joins_hands(c)]
        if chest is None or not joined:
            return False
        d = self.solver.data
        d.qpos[:] = q
        mujoco.mj_kinematics(self.m, d)
        body = self.solver.body_id(chest.body)
        forward = d.xmat[body].reshape(3, 3) @ np.asarray(chest.nrm, float)
        return any(
            (d.site_xpos[self.solver.site_id(c.site)] - d.xpos[body]) @ forward < 0.0
            for c in joined
        )

    def _joins_hands(self, c) -> bool:
        """Whether constraint ``c`` places a site of one hand on a site of the other."""
        if not isinstance(c, cn.Place) or not isinstance(c.target, SitePos):
            return False
        arm, other = self._hand_of(c.site), self._hand_of(c.target.site)
        return arm is not None and other is not None and other is not arm

    def _meeting_place(self, cons) -> tuple[cn.Place, ...]:
        """Where two hands meet when nothing else places them: a preference (with the
        naturalness, below the constraints) for the contact in the neutral signing space,
        where signers join their hands, rather than low where holding them costs least.
        A hand that touches the other arm (its elbow, forearm or upper arm) meets it in
        front of the body too: that arm's palm prefers ``ACROSS``, its forearm raised in
        front with the elbow bent and low, instead of the arm held out to the side."""
        if self._meet is None:
            return ()
        placed = [c for c in cons if isinstance(c, cn.Place)]
        if len(placed) != 1 or not isinstance(placed[0].target, SitePos):
            return ()
        c = placed[0]
        arm = self._hand_of(c.site)
        if arm is None:
            return ()
        if self._joins_hands(c):
            return (cn.Place(c.site, SitePos(self._meet), MEET_TOL, "meet"),)
        held = self._carried_by(c.target.site)
        if held is not None and held[0] is not arm:
            return (cn.Place(held[1], held[2], MEET_TOL, "meet"),)
        return ()

    def _elbows_low(self, cons, free, q: np.ndarray) -> tuple[natural.Below, ...]:
        """A preference, with the naturalness, for each free arm whose hand is placed below
        the eyes: its elbow no higher than its shoulder (``ELBOW_LOW``). Comfort alone
        would sometimes fold a raised arm (the upper arm up, the forearm back) rather than
        bend the wrist; a signer keeps the elbow down unless the hand goes above the eyes."""
        eyes = [s for a, s in self.smap.sites.items() if a.startswith("EYE_")]
        if not eyes:
            return ()
        d = self.solver.data
        d.qpos[:] = q
        mujoco.mj_kinematics(self.m, d)
        k = self.solver.kinematics()
        eye_z = min(k.value(SitePos(s))[2] for s in eyes)
        out, done = [], set()
        free = set(free)
        for c in cons:
            if not isinstance(c, cn.Place) or (arm := self._hand_of(c.site)) is None:
                continue
            if arm in done or not {arm.flex, arm.abd, arm.rot, arm.elbow} <= free:
                continue
            done.add(arm)
            if k.value(c.target)[2] < eye_z:
                margin, tol = ELBOW_LOW
                out.append(natural.Below(arm.fore, arm.upper, margin, tol, "elbow low"))
        return tuple(out)

    def _palm_site(self, arm: Arm) -> str | None:
        """The model site of the palm's centre (AZee ``PA``) on ``arm``'s hand, or None."""
        hand = self.solver.body_id(arm.hand)
        return next(
            (
                s
                for a, s in self.smap.sites.items()
                if a.startswith("PA_") and int(self.m.site_bodyid[self.solver.site_id(s)]) == hand
            ),
            None,
        )

    def _across_at(self, arm: Arm):
        """Where the palm of ``arm`` rests when the other hand touches that arm: ``ACROSS``
        from its shoulder joint (forward, toward the midline, up)."""
        fwd, inward, up = ACROSS
        return Lin(((1.0, BodyOrigin(arm.upper)), (1.0, Const((fwd, arm.out * -inward, up)))))

    def _facing(self, cons) -> list[cn.Orient]:
        """For each placement of a skin site on another, the two surfaces face to face:
        outward normals opposed (within ``FACING_TOL`` of the hand part), unless the score orients one of
        the two bodies itself."""
        oriented = {c.body for c in cons if isinstance(c, cn.Orient)}
        out = []
        for c in cons:
            if not isinstance(c, cn.Place) or not isinstance(c.target, SitePos):
                continue
            a, b = self._azee_site.get(c.site), self._azee_site.get(c.target.site)
            if a not in self.smap.normals or b not in self.smap.normals:
                continue
            ba, bb = (
                self.m.body(int(self.m.site_bodyid[self.solver.site_id(s)])).name
                for s in (c.site, c.target.site)
            )
            if ba in oriented or bb in oriented:
                continue
            tol = _facing_tol(a, b)
            out.append(
                cn.Orient(
                    ba,
                    self.smap.normals[a],
                    cn.Rel.OPP,
                    BodyAxis(bb, self.smap.normals[b]),
                    tol,
                    f"{c.label}:facing",
                )
            )
        return out

    def _joint_targets(self, changes: dict[str, float], tol: float = 0.02):
        out = []
        for j, v in changes.items():
            jid = self.solver.joint_id(j)
            lo, hi = self.m.jnt_range[jid]
            val = float(np.clip(self.m.qpos0[self.m.jnt_qposadr[jid]] + v, lo, hi))
            out.append(cn.JointTarget(j, val, tol, f"morph:{j}"))
        return out

    def _track_posture_at(self, tkeys: list[Key], t: float) -> np.ndarray:
        before = [k for k in tkeys if k.start < t - 1e-9]
        return before[-1].q if before else self.home

    # -- pass 2: frames ---------------------------------------------------------------
    def frames(self, keys: dict[str, list[Key]]) -> np.ndarray:
        T = frame_count(self.score.duration, self.fps)
        times = np.arange(T) / self.fps
        q = np.tile(self.home, (T, 1))
        moving = np.zeros((T, len(self.track_joints)), bool)
        names = list(self.track_joints)
        for ti, t in enumerate(names):
            d = self.track_dofs[t]
            q[:, d], moving[:, ti] = self.motion.track_curve(
                keys[t], times, d, self._carried(t, keys)
            )
        if self.mode is Mode.FLATTENED:
            return self.motion.flat_transpaths(q, times)
        return self.motion.constrained_blends(q, times, moving, names, keys)

    def _carried(self, track: str, keys: dict[str, list[Key]]) -> list[float]:
        """End times [s] of other tracks' keys with a constraint that names a body this
        track moves (a hand held in front of the chin is carried by the head track)."""
        return sorted(
            k.end
            for t, tk in keys.items()
            if t != track
            for k in tk
            if any(track in self.sched.moved_by(c) for c in k.cons)
        )

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
                span = frame_range(b.start, b.end, self.fps, len(times))
                vals = np.empty(len(span))
                for k, f in enumerate(span):
                    d.qpos[:] = q[f]
                    mujoco.mj_kinematics(self.m, d)
                    vals[k] = ic.residual(self.solver.kinematics())
                unit = "m" if isinstance(ic, cn.Place) else "rad"
                out.append(
                    ConstraintTrace(
                        b.path,
                        c.index,
                        type(c).__name__.lower(),
                        ic.tol,
                        unit,
                        b.start,
                        b.end,
                        span.start,
                        vals,
                        len(times),
                        self.reasons.get(ic.label, ""),
                    )
                )
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
    fps = check_fps(fps, "fps")
    smap = signer_map or DEFAULT_MAP
    solver = solver or make_solver(signer_map=smap)
    # A left-handed score is realized as the mirror image of its right-handed mirror, so
    # left- and right-handed signing are mirror images by construction.
    flip = mirror.JointMirror.of(solver.model) if score.strong_side == "L" else None
    r = Realizer(mirror.mirror_score(score) if flip else score, solver, fps, mode, smap)
    tick = progress or (lambda f: None)
    keys = r.key_postures()
    tick(0.4)
    q = r.frames(keys)
    tick(0.8)
    times = np.arange(q.shape[0]) / fps
    own = Realizer(score, solver, fps, mode, smap) if flip else r
    if flip:
        own.reasons = {k: mirror.mirror_words(v) for k, v in r.reasons.items()}
    # Residuals are those of the postures the blocks ask for: a trill is added on top.
    traces = own.traces(flip(q) if flip else q, times)
    q = r.motion.trills(q, times)
    if flip:
        q = flip(q)
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
        problems=len(res),
        key_problems=r.n_key,
        iterations=sum(x.iterations for x in res),
        not_converged=sum(not x.converged for x in res),
        solve_time=sum(x.time for x in res),
        total_time=_time.perf_counter() - t_start,
        per_problem_iterations=np.array([x.iterations for x in res]),
    )
    return Rollout(fps, mode, times, q, site_names, site_pos, own.schedule(), traces, stats)


def score_traces(
    score: sc.Score | str, qpos: np.ndarray, fps: float, solver: ik.Solver | None = None
) -> tuple[ConstraintTrace, ...]:
    """Residual traces of ``score``'s constraints on given frames ``qpos`` (T, nq)."""
    if not isinstance(score, sc.Score):
        score = sc.load_score(score)
    r = Realizer(score, solver or make_solver(), fps, Mode.MULTITRACK)
    return r.traces(np.asarray(qpos, float), np.arange(len(qpos)) / fps)


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
