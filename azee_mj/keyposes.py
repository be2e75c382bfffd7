"""Pass 1: the key postures of every segment, in time order.

The block boundaries cut the score into segments; in each, the active constraints are
grouped into components of the tracks they couple (a contact couples both arms), and each
group is solved warm-started from the postures the tracks hold (rule 1); a group where a
block starts with placements and orientations solves the placements first (rule 2); a
``hold`` keeps the posture its block reached, as joint targets on the tracks that block
drove (rule 4). Tracks no block drives are not touched; the trunk and the head return to
neutral when nothing needs them.

The group policy, in named steps: :meth:`GroupPoser.solve` (placements first, natural
preferences, facing widened when the hands would join behind the back, dropped when it
cannot be met); :meth:`KeyPoser.recruit_trunk` when the limbs alone cannot meet a group;
:meth:`KeyPoser.lean_less` brings a recruited trunk back toward upright; :meth:`KeyPoser.relax`.

Units: seconds, metres, radians.
"""

from __future__ import annotations

import bisect
import dataclasses
import functools
import itertools

import numpy as np

from azee_mj import constraints as cn
from azee_mj import ik, reach
from azee_mj import score as sc
from azee_mj.blend import EPS, SAME_POSTURE, Key
from azee_mj.diagnose import diagnose
from azee_mj.ikadapter import IKAdapter
from azee_mj.intervals import IntervalIndex
from azee_mj.pathkeys import lead_into_paths
from azee_mj.preferences import UNDER_TOL_DEG, Preferences, widened
from azee_mj.schedule import FLAT_FIXED, DrivenConstraint, Mode

#: Bisection steps bringing a recruited trunk back toward neutral (1/32 of its lean).
LEAN_STEPS = 5
#: Largest lean [rad] of any spine joint kept for a group the trunk helps but that still
#: misses (two spine joints: the chest at most about 10 degrees from upright).
MISS_LEAN = np.deg2rad(5.0)
#: Tracks that return to neutral when no block needs them.
RELAXING = ("spine", "head")


@dataclasses.dataclass(frozen=True)
class Active:
    """A constraint active in a segment, and whether its block starts with the segment."""

    driven: DrivenConstraint
    starts_now: bool


@dataclasses.dataclass(frozen=True, eq=False)
class GroupSolve:
    """One group's solve: the result, the constraints it was solved with (the score's and
    the preferences made hard, e.g. face to face) and the joints it moved."""

    result: ik.IKResult
    cons: tuple
    free: tuple[str, ...]

    @property
    def converged(self) -> bool:
        return self.result.converged

    @property
    def qpos(self) -> np.ndarray:
        return self.result.qpos


@dataclasses.dataclass(frozen=True, eq=False)
class Unfaced:
    """A face-to-face solve that failed and was dropped for the placement alone, kept to
    say why: the solve, its start posture and time [s]."""

    solve: GroupSolve
    start: np.ndarray
    t0: float


def violation(res: ik.IKResult) -> float:
    """How far a result is from its tolerances (sum of value / tol over the violated)."""
    return (
        sum(r.value / r.tol for r in res.residuals if not r.ok)
        + res.penetration / cn.PENETRATION_LIMIT
    )


def needs_trunk(group: set[str]) -> bool:
    """Whether the trunk (or another arm branch) can help ``group`` meet its constraints:
    not a hand's fingers missing one another."""
    return not all(t.startswith("hand") for t in group)


def components(track_sets: list[set[str]]) -> list[set[str]]:
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


class GroupPoser:
    """Solves one group of coupled tracks in a segment through ``adapter``, with the
    signer's natural preferences; remembers the face-to-face solves it dropped."""

    def __init__(self, adapter: IKAdapter):
        self.adapter, self.schedule = adapter, adapter.schedule
        self.prefs = Preferences(adapter.solver, self.schedule.anatomy, self.schedule.smap)
        #: facing label -> the face-to-face solve dropped for the placement alone
        self.unfaced: dict[str, Unfaced] = {}
        self._free: dict[tuple[str, ...], tuple[str, ...]] = {}  # one tuple per set of joints

    def constraints(self, mine: list[Active]) -> list:
        """The solver constraints of active constraints ``mine``: theirs, then the joint
        targets of their morphs (summed per joint)."""
        cons, targets = [], {}
        for it in mine:
            if it.driven.con is not None:
                cons.append(it.driven.con)
            for j, v in it.driven.morph.items():
                targets[j] = targets.get(j, 0.0) + v
        return cons + self.schedule.comp.morph_targets(targets)

    def unchanged(self, group, cons, state: np.ndarray, keys, t0: float) -> bool:
        """Whether ``cons`` are some of those that held ``group`` until ``t0`` (blocks
        only ended) and no track outside the group moved what they name (the head under a
        hand; of the face, only the joints that move it count: its jaw moves the chin, its
        brows and lids do not): nothing needs to move."""
        prev = [keys[t][-1] for t in group if keys[t] and abs(keys[t][-1].end - t0) < EPS]
        if len(prev) != len(group) or not set(cons) <= set().union(*(k.cons for k in prev)):
            return False  # (before the carriers: most segments change their constraints)
        carriers = set().union(*(self.schedule.moved_by(c) for c in cons)) - group
        moving = set().union(*(self.schedule.moving_dofs(c) for c in cons))
        dofs = [
            [d for d in self.schedule.track_dofs[t] if t != "face" or d in moving]
            for t in sorted(carriers)
        ]
        return all(np.allclose(state[d], prev[0].q[d], atol=SAME_POSTURE) for d in dofs)

    def solve(
        self,
        group: set[str],
        items: list[Active],
        state: np.ndarray,
        keys,
        t0: float,
        upright: bool = False,
        reuse: bool = True,
        held: tuple[str, ...] = (),
        restarts: int | None = None,
        branches: bool = False,
    ) -> GroupSolve:
        """Solve the constraints of ``items`` that drive tracks of ``group`` from posture
        ``state`` at segment start ``t0`` [s] (rule 2: placements first when a block starts
        with both). A posture still held is kept (:meth:`unchanged`; unless not ``reuse``:
        the trunk under it moved). The ``held`` tracks of the group keep their posture in
        ``state``, and the solve continues from ``state`` (no placements-first start).
        ``upright``: the trunk was recruited; among the postures that meet the
        constraints, the one with the chest nearest upright is preferred. ``restarts``:
        the solver's, if None. ``branches``: no two-bone arm starts, so that the solver's
        restarts try each arm on its other elbow-swivel branches (its seeder)."""
        ad, prefs, anatomy = self.adapter, self.prefs, self.schedule.anatomy
        mine = [it for it in items if it.driven.tracks & group]
        cons = self.constraints(mine)
        joints = self.schedule.track_joints
        free = tuple(j for t in sorted(group) if t not in held for j in joints[t])
        free = self._free.setdefault(free, free)  # every key keeps it
        if reuse and self.unchanged(group, cons, state, keys, t0):
            kept = ik.IKResult(state.copy(), True, (), 0.0, 0, 0, 0.0, np.zeros(0))
            return GroupSolve(kept, tuple(cons), free)
        q0 = state.copy()
        places = [c for c in cons if not isinstance(c, (cn.Orient, cn.Look))]
        # Also start each arm in its natural two-bone posture for its hand's target.
        facing = prefs.facing(cons)
        seeds = (
            ()
            if branches
            else reach.arm_seeds(
                ad.solver,
                anatomy.arms,
                cons + facing,
                free,
                q0,
                anatomy.hand_of,
                prefs.meet,
                anatomy.carried_by,
            )
        )
        if not held and len(places) < len(cons) and any(it.starts_now for it in mine) and places:
            q0 = ad.solve(places, free, q0, t0, seeds, natural=False, restarts=1).qpos
        where = (
            prefs.meeting_place(cons)
            + prefs.elbows_low(cons, free, q0)
            + (prefs.upright if upright else ())
        )

        def attempt(with_facing, wide=False) -> GroupSolve:
            both = tuple(cons) + tuple(with_facing)
            res = ad.solve(
                both, free, q0, t0, seeds, preferences=where, restarts=restarts, wide=wide
            )
            return GroupSolve(res, both, free)

        out = attempt(facing)
        if facing and out.converged and prefs.joined_behind(cons, out.qpos):
            out = self.join_in_front(out, attempt(widened(facing)), cons)
        if facing and not out.converged:
            out = self.drop_facing(out, attempt(()), facing, q0, t0)
        if not out.converged:
            # Missed with and without facing: the limbs started anywhere (a last resort).
            wide = attempt(facing, wide=True)
            out = wide if wide.converged else out
        return self.from_below(out, q0, t0, where, seeds) if out.converged else out

    def from_below(self, out: GroupSolve, q0, t0: float, where, seeds) -> GroupSolve:
        """A hand placed on the face with its elbow raised to the shoulder (or above it),
        brought up from below instead: the solve ``out`` (met) again, first with each such
        forearm within each of ``UNDER_TOL_DEG`` of vertical, the tightest first
        (:meth:`~azee_mj.preferences.Preferences.forearms_under`), from ``q0`` and
        ``seeds``, the score's orientations asked as the ranges their tolerances are
        (``IKProblem.ranges``: turned to the middle, a palm asked within 30 degrees took
        the arm with it), then from :func:`~azee_mj.reach.rising_seed` (each such arm's wrist
        under its target, the elbow hanging; one attempt). The first that meets
        everything and is more natural than ``out`` by the solver's own measure
        (:func:`~azee_mj.ik.natural_cost`, without the forearm rows; from the forearm
        solves, only with the elbow low) is kept. The usual starts come at a temple head-on
        from the side and fold the arm up there, the upper arm horizontal; the natural
        posture lies in another basin, one that no single start or tolerance reaches for
        every contact."""
        prefs, ad = self.prefs, self.adapter
        raised = prefs.raised_on_face(out.cons, out.free, out.qpos)
        if not raised:
            return out
        problem = ad.problem(out.cons, out.free, q0, t0, preferences=where)
        cost = functools.partial(ik.natural_cost, ad.solver, problem)
        first = cost(out.qpos)
        for tol in np.radians(UNDER_TOL_DEG):
            under = prefs.forearms_under(raised, tol)
            res = ad.solve(
                out.cons + under, out.free, q0, t0, (q0, *seeds), preferences=where, ranges=True
            )
            if not res.converged or prefs.raised_on_face(out.cons, out.free, res.qpos):
                continue  # a miss, or the elbow still raised
            if cost(res.qpos) < first:
                kept = tuple(r for r in res.residuals if r.label != under[0].label)
                return GroupSolve(dataclasses.replace(res, residuals=kept), out.cons, out.free)
        hand_of = self.schedule.anatomy.hand_of
        start = reach.rising_seed(ad.solver, raised, out.cons, q0, hand_of)
        res = ad.solve(out.cons, out.free, start, t0, restarts=0, preferences=where, prefer=q0)
        if res.converged and cost(res.qpos) < first:
            return GroupSolve(res, out.cons, out.free)
        return out

    def join_in_front(self, faced: GroupSolve, wide: GroupSolve, cons) -> GroupSolve:
        """Hands join in the signing space before they meet head-on: face to face with a
        wider tolerance (``wide``: a fingertip on the back of the other hand, leaning)
        when that meets them in front, else the head-on ``faced``."""
        if wide.converged and not self.prefs.joined_behind(cons, wide.qpos):
            return wide
        return faced

    def drop_facing(self, faced: GroupSolve, plain: GroupSolve, facing, q0, t0: float):
        """Face to face is a preference below the score's constraints: the solve without
        it (``plain``) when that meets them or misses by less than ``faced``; the dropped
        solve is kept to say why face to face failed."""
        if plain.converged or violation(plain.result) < violation(faced.result):
            if not plain.converged:
                self.unfaced.update({f.label: Unfaced(faced, q0, t0) for f in facing})
            return plain
        return faced

    def why_not_facing(self, label: str) -> str:
        """Why placement ``label`` could not be met face to face, when it was solved
        without its facing after that failed (``"; face to face, ..."``), else ``""``."""
        kept = self.unfaced.get(f"{label}:facing")
        if kept is None:
            return ""
        s = kept.solve
        problem = self.adapter.problem(s.cons, s.free, kept.start, kept.t0, natural=False)
        why = diagnose(
            self.adapter.solver,
            problem,
            s.result,
            kept.start,
            self.schedule.anatomy.limb_root,
            only=f"{label}:facing",
        )
        return f"; face to face, {why[0].detail}" if why else ""


def solve_order(groups: list[set[str]], items: list[Active], moved_by) -> list[set[str]]:
    """The order to solve a segment's groups in: a group whose tracks move a body that
    another group's constraints name first (the trunk before the head it carries, the
    head before a hand that touches it: solved the other way round, the later group
    moves the earlier one off its target). Otherwise (and in a cycle) hands and the
    face first (a placed fingertip depends on its hand's shape), then groups driven
    by morphs only, then by name (deterministic). ``moved_by(constraint)``: the tracks
    whose joints move a body the constraint names."""

    def key(g):
        return (
            not all(t.startswith(("hand", "face", "eyes")) for t in g),
            any(it.driven.con is not None for it in items if it.driven.tracks & g),
            sorted(g),
        )

    needs = [
        set().union(
            *(
                moved_by(it.driven.con)
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


class KeyPoser:
    """Pass 1: the key postures of the adapter's schedule laid out by ``mode``; ``reasons``
    says why a key posture misses a constraint (constraint label -> the diagnosis, see
    :mod:`azee_mj.diagnose`)."""

    def __init__(self, adapter: IKAdapter, mode: Mode):
        self.adapter, self.schedule, self.mode = adapter, adapter.schedule, mode
        self.groups = GroupPoser(adapter)
        # the holds, and which hold a time (made on first use)
        self._holds: tuple[list[sc.Block], IntervalIndex] | None = None
        self.reasons: dict[str, str] = {}
        #: id of a missing solve kept upright -> the joints to say why it missed with (the
        #: trunk's too: it was tried, so what conflicts is told as it is with the trunk)
        self.diagnose_free: dict[int, tuple[str, ...]] = {}
        m, sched = adapter.solver.model, self.schedule
        spine = [adapter.solver.joint_id(j) for j in sched.track_joints.get("spine", ())]
        #: the spine's dofs that tilt it (axis not the vertical in the body's frame)
        self.tilt = np.array([m.jnt_dofadr[j] for j in spine if abs(m.jnt_axis[j][2]) < 0.9], int)

    def take(self, state: np.ndarray, tracks, q: np.ndarray) -> None:
        """Copy the joints of ``tracks`` from posture ``q`` into ``state`` (in place)."""
        for t in tracks:
            d = self.schedule.track_dofs[t]
            state[d] = q[d]

    def key_postures(self) -> dict[str, list[Key]]:
        """Each segment's groups solved in time order: per track, its keys."""
        sched = self.schedule
        keys: dict[str, list[Key]] = {t: [] for t in sched.track_joints}
        state = sched.home.copy()  # the posture each track holds now
        cstr = [
            (b, sched.block_constraints(b)) for b in sched.blocks if b.kind is sc.BlockKind.CSTR
        ]
        trills = [
            (b, dc.tracks) for b, cons in cstr for dc in cons if isinstance(dc.source, sc.Trill)
        ]
        # what holds an event's time, in logarithmic time (not by asking every block)
        cstr_at = IntervalIndex((b.start, b.end) for b, _ in cstr)
        trills_at = IntervalIndex((b.start, b.end) for b, _ in trills)
        for t0, t1 in itertools.pairwise(sched.events()):
            items = [
                Active(dc, b.start == t0)
                for b, cons in (cstr[i] for i in cstr_at.at(t0))
                for dc in cons
                if not isinstance(dc.source, sc.Trill)
            ]
            held = self.hold(keys, state, t0, t1)
            items = [it for it in items if not it.driven.tracks <= held]
            if self.mode is Mode.MULTITRACK:
                trilled = [trills[i][1] for i in trills_at.at(t0)]
                busy = held.union(*(it.driven.tracks for it in items), *trilled)
                self.relax(keys, state, busy, {it.driven.con for it in items}, t0, t1)
            if items:
                self.pose_segment(items, keys, state, t0, t1)
        return lead_into_paths(self.adapter, keys) if self.mode is Mode.MULTITRACK else keys

    def hold(self, keys, state: np.ndarray, t0: float, t1: float) -> set[str]:
        """Rule 4: over a segment ``[t0, t1)`` inside a hold, the tracks of the held block
        (realized: it ended before) keep the posture it reached. Returns those tracks."""
        sched, held = self.schedule, set()
        if self._holds is None:
            holds = [b for b in sched.blocks if b.kind is sc.BlockKind.HOLD]
            self._holds = holds, IntervalIndex((h.start, h.end) for h in holds)
        holds, holds_at = self._holds
        for h in (holds[i] for i in holds_at.at(t0)):
            block = sched.by_path[h.hold_of]
            at = block.end
            for t in (sched.held_tracks(h) | self.recruited(keys, block)) - held:
                q = self.posture_at(keys[t], at)  # keys' postures are never changed
                self.take(state, (t,), q)
                keys[t].append(Key(t0, t1, q, (), sched.track_joints[t]))
                held.add(t)
        return held

    def recruited(self, keys, block: sc.Block) -> set[str]:
        """The trunk and head tracks (:data:`RELAXING`) whose last key before ``block``
        ends was solved inside it, for its constraints: recruited to reach them, they are
        part of the posture a hold of ``block`` keeps (relaxing them during the hold would
        move the held hands; they relax with the next movement instead)."""
        out = set()
        for t in RELAXING:
            i = bisect.bisect_left(keys.get(t, ()), block.end - EPS, key=lambda k: k.start)
            k = keys[t][i - 1] if i else None
            if k is not None and k.cons and not k.relax and k.start >= block.start - EPS:
                out.add(t)
        return out

    def posture_at(self, keys: list[Key], t: float) -> np.ndarray:
        """The posture of the last of a track's ``keys`` starting before time ``t`` [s]
        (neutral if none; the keys are in time order: found by bisection)."""
        i = bisect.bisect_left(keys, t - EPS, key=lambda k: k.start)
        return keys[i - 1].q if i else self.schedule.home

    def pose_segment(self, items: list[Active], keys, state: np.ndarray, t0, t1) -> None:
        """Solve the groups of the segment ``[t0, t1)`` (the trunk recruited where the
        limbs alone fall short), diagnose what they miss, and append their keys."""
        sched = self.schedule
        if self.mode is Mode.FLATTENED:
            # One whole-body problem: every track but the face and eyes is free.
            driven = set().union(*(it.driven.tracks for it in items))
            groups = [driven | (set(sched.track_joints) - set(FLAT_FIXED))]
        else:
            groups = components([it.driven.tracks for it in items])
        groups = solve_order(groups, items, self.schedule.moved_by)
        before = state.copy()
        solved = []
        for g in groups:
            solved.append(self.groups.solve(g, items, state, keys, t0))
            self.take(state, g, solved[-1].qpos)
        if self.mode is Mode.MULTITRACK and any(
            not s.converged and needs_trunk(g) for g, s in zip(groups, solved)
        ):
            alone = groups, solved
            groups, solved = self.recruit_trunk(groups, solved, items, before, keys, t0)
            groups, solved = self.other_branches(alone, (groups, solved), items, before, keys, t0)
        for group, s in zip(groups, solved):
            if not s.converged:
                free = self.diagnose_free.pop(id(s), s.free)
                self.diagnose(dataclasses.replace(s, free=free), before, t0)
            q = s.qpos.copy()  # one posture for the keys of all the group's tracks
            for t in group:
                self.take(state, (t,), s.qpos)
                if keys[t] and keys[t][-1].start == t0:
                    keys[t].pop()  # recruited after all: no return to neutral here
                keys[t].append(Key(t0, t1, q, s.cons, s.free))

    def other_branches(self, alone, kept, items, before: np.ndarray, keys, t0: float):
        """A signer moves the arm another way before bending the trunk: when the solve
        ``kept`` (groups, solves) leans or misses, the groups the limbs missed ``alone``
        are solved again upright from their arms' other elbow-swivel branches (the groups
        after them anew); that is kept if it meets everything and raises no elbow above
        its shoulder that ``kept`` holds below it (the palm on the back of the head: the
        elbow raised beside the head instead of a 20-degree bow; two palms on the cheeks
        keep their elbows low, trunk upright)."""
        final = before.copy()
        for g, s in zip(*kept):
            self.take(final, g, s.qpos)
        if "spine" not in self.schedule.track_dofs or (
            all(s.converged for s in kept[1]) and not self.leans(final)
        ):
            return kept
        unfaced = dict(self.groups.unfaced)  # the kept solve's, to say why it missed
        state, out, redo = before.copy(), [], False
        for g, s in zip(*alone):
            if not s.converged or redo:
                s = self.groups.solve(g, items, state, keys, t0, reuse=False, branches=True)
                redo = True
            out.append(s)
            if not s.converged:
                break
            self.take(state, g, s.qpos)
        up = self.groups.prefs.elbows_up
        if not all(s.converged for s in out) or any(
            up(s.cons, s.free, state) - up(s.cons, s.free, final) for s in out
        ):
            self.groups.unfaced = unfaced
            return kept
        return alone[0], out

    def diagnose(self, s: GroupSolve, start: np.ndarray, t0: float) -> None:
        """Why solve ``s`` (from ``start`` at ``t0`` [s]) misses its constraints, into
        ``reasons`` (the first reason found for each constraint is kept)."""
        ad = self.adapter
        problem = ad.problem(s.cons, s.free, start, t0, natural=False)
        limb_root = self.schedule.anatomy.limb_root
        for dg in diagnose(ad.solver, problem, s.result, start, limb_root):
            if dg.label not in self.reasons:
                self.reasons[dg.label] = dg.detail + self.groups.why_not_facing(dg.label)

    def recruit_trunk(self, groups, solved, items, before: np.ndarray, keys, t0: float):
        """The limbs alone cannot meet some groups' constraints: the trunk helps them, as
        little as it can (the chest nearest upright among the postures that meet them).
        The groups met without it are then solved again on the moved trunk (it carries
        them) rather than riding along: a look turns the head only as far as it needs. If
        that fails, every active track is solved together with the trunk. Returns the
        (groups, solved) kept (:meth:`keep_upright_on_miss`)."""
        solve = self.groups.solve
        # a group the score drives the trunk with joins the groups it helps
        failed = [g for g, s in zip(groups, solved) if not s.converged or "spine" in g]
        met = [g for g in groups if g not in failed]
        helped = set().union(*failed) | {"spine"}
        state = before.copy()
        first_failed = next(i for i, g in enumerate(groups) if g in failed)
        for g, s in zip(groups[:first_failed], solved):
            self.take(state, g, s.qpos)  # solved before it: what the helped group builds on
        first = solve(helped, items, state, keys, t0, upright=True)
        out = [self.lean_less(first, helped, items, keys, t0)]
        self.take(state, helped, out[0].qpos)
        for g in met:
            out.append(solve(g, items, state, keys, t0, reuse=False))
            self.take(state, g, out[-1].qpos)
        tries = [([helped, *met], out)]
        if met and all(s.converged for s in out) and self.leans(state):
            tries.insert(0, self.lean_together(tries[0], state, items, keys, t0))
        if met and not all(s.converged for s in out):
            group = set().union(*groups) | {"spine"}
            tries.append(([group], [solve(group, items, before, keys, t0, upright=True)]))

        return self.keep_upright_on_miss((groups, solved), tries)

    def keep_upright_on_miss(self, upright, tries):
        """The first of the trunk-recruited ``tries`` that meets everything; else a miss
        costs no naturalness: the least violating of the solve the limbs made alone
        (``upright``) and the tries whose trunk leans at most ``MISS_LEAN`` at every
        spine joint (the trunk does not bow toward a constraint it cannot meet)."""
        met = next((c for c in tries if all(s.converged for s in c[1])), None)
        if met is not None:
            return met
        d, home = self.schedule.track_dofs.get("spine"), self.schedule.home

        def upright_enough(cand) -> bool:
            return all(np.abs(s.qpos[d] - home[d]).max() <= MISS_LEAN for s in cand[1])

        def total(cand) -> float:
            return sum(violation(s.result) for s in cand[1])

        near = [c for c in tries if d is not None and upright_enough(c)]
        kept = min([upright, *near], key=total)
        spine = self.schedule.track_joints.get("spine", ())
        for s in kept[1]:
            if not s.converged:
                self.diagnose_free[id(s)] = s.free + tuple(j for j in spine if j not in s.free)
        return kept

    def leans(self, q: np.ndarray) -> bool:
        """Whether posture ``q``'s trunk bends from upright (forward, back or sideways; a
        turn about the vertical is not a lean): only then are the arms solved again
        another way to bring it back (:meth:`lean_together`, :meth:`other_branches`),
        each retry costing the arms' solves again."""
        tilt = self.tilt
        return bool(tilt.size and np.abs(q[tilt] - self.schedule.home[tilt]).max() >= SAME_POSTURE)

    def lean_together(self, recruited, state: np.ndarray, items, keys, t0: float):
        """The met ``recruited`` (groups, solves; posture ``state``) with the trunk brought
        back toward upright, every arm it carries solved anew at each step: the other arm
        may move aside (two palms on the belly). ``recruited`` if it leans no less."""
        groups, solved = recruited
        arms = [i for i, g in enumerate(groups) if needs_trunk(g)]
        union = set().union(*(groups[i] for i in arms))
        cons = tuple(c for i in arms for c in solved[i].cons)
        free = tuple(j for i in arms for j in solved[i].free)
        whole = GroupSolve(dataclasses.replace(solved[0].result, qpos=state.copy()), cons, free)
        best = self.lean_less(whole, union, items, keys, t0)
        if best is whole:
            return recruited  # no less lean found
        rest = [i for i in range(len(groups)) if i not in arms]
        return [union, *(groups[i] for i in rest)], [best, *(solved[i] for i in rest)]

    def lean_less(self, solved: GroupSolve, group: set[str], items, keys, t0: float):
        """Bring the trunk of a converged ``solved`` back toward neutral as far as the rest
        of ``group`` can still meet the constraints without it: a bisection on the
        fraction of the trunk's motion kept, the limbs solved again at each step from the
        last posture that met them. A solve lands where its start leads; this finds the
        least lean along the way it found. Returns the best solve."""
        d = self.schedule.track_dofs.get("spine")
        asked = any("spine" in it.driven.tracks for it in items if it.driven.tracks & group)
        if not solved.converged or d is None or asked:  # the score places the trunk itself
            return solved
        home = self.schedule.home
        lean = solved.qpos[d] - home[d]
        if np.abs(lean).max() < SAME_POSTURE:
            return solved
        lo, hi, best = 0.0, 1.0, solved
        for _ in range(LEAN_STEPS):
            f = 0.5 * (lo + hi)
            q = best.qpos.copy()
            q[d] = home[d] + f * lean
            s = self.groups.solve(
                group, items, q, keys, t0, reuse=False, held=("spine",), restarts=0
            )
            if s.converged:
                hi, best = f, GroupSolve(s.result, s.cons, solved.free)
            else:
                lo = f
        return best

    def relax(self, keys, state: np.ndarray, busy: set[str], active: set, t0, t1) -> None:
        """The trunk and the head return to neutral over ``[t0, t1)`` when no block needs
        them: none drives them, and none that they were recruited for (their last key's
        constraints) is still ``active``."""
        sched = self.schedule
        for t in RELAXING:
            d = sched.track_dofs.get(t)
            if d is None or t in busy or not keys[t] or set(keys[t][-1].cons) & active:
                continue
            if np.allclose(keys[t][-1].q[d], sched.home[d], atol=SAME_POSTURE):
                continue
            state[d] = sched.home[d]
            keys[t].append(Key(t0, t1, sched.home, (), sched.track_joints[t], relax=True))
