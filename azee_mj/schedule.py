"""A score laid on a signer, before any motion: which tracks (articulator groups: ``spine``,
``head``, ``eyes``, ``face``, ``arm_X``, ``hand_X``) each constraint drives, the intervals
blocks drive them, the segment boundaries and the contact windows. Also the solver for a
signer (:func:`make_solver`, with the AZee joint weights).

Units: seconds.
"""

from __future__ import annotations

import dataclasses
import enum
import os
from collections.abc import Mapping

import mujoco
import numpy as np

from azee_mj import constraints as cn
from azee_mj import contact, ik, natural, reach
from azee_mj import score as sc
from azee_mj.anatomy import SignerAnatomy, descends
from azee_mj.intervals import IntervalIndex
from azee_mj.kinematics import SitePos, compile_point, compile_vector
from azee_mj.model import MODEL_PATH
from azee_mj.sites import DEFAULT_MAP, SignerMap
from azee_mj.timing import frame_range

__all__ = [
    "FLAT_FIXED",
    "Compiler",
    "ContactWindow",
    "DrivenConstraint",
    "FramePairs",
    "Mode",
    "Schedule",
    "TrackInterval",
    "branch_seeder",
    "constraint_tracks",
    "contact_pairs",
    "descends",
    "joint_weights",
    "make_solver",
    "schedule",
]


class Mode(enum.Enum):
    """How the score is laid out in time: per track (``multitrack``), or one whole-body
    key posture at every block boundary (``flattened``, the 2018 method, for comparison)."""

    MULTITRACK = "multitrack"
    FLATTENED = "flattened"


#: Tracks the flattened mode never moves as part of the whole body.
FLAT_FIXED = ("face", "eyes")


#: How dear moving a track's joints is, relative to an arm joint (1): the trunk and neck are
#: dearer to move than the arms, and a clavicle joint costs CLAVICLE_WEIGHT.
TRACK_WEIGHTS = {"spine": 8.0, "head": 4.0}
CLAVICLE_WEIGHT = 3.0
#: Tolerance of a morph's joint targets [rad].
MORPH_TOL = 0.02


def joint_weights(signer_map: SignerMap) -> dict[str, float]:
    """Joint name -> weight for :class:`~azee_mj.ik.Solver` from the tracks of ``signer_map``."""
    return {
        j: TRACK_WEIGHTS.get(track, CLAVICLE_WEIGHT if "clav" in j else 1.0)
        for track, joints in signer_map.tracks.items()
        for j in joints
    }


def make_solver(
    model: str | os.PathLike | mujoco.MjSpec | None = None,
    signer_map: SignerMap | None = None,
    **options,
) -> ik.Solver:
    """An :class:`~azee_mj.ik.Solver` for a signer: ``model`` (default the bundled one) with
    the joint weights of ``signer_map`` (default :data:`~azee_mj.sites.DEFAULT_MAP`);
    ``options`` go to the solver (``seed``, ``max_iter``, ``on_solve``, ...)."""
    smap = signer_map or DEFAULT_MAP
    solver = ik.Solver(
        MODEL_PATH if model is None else model, joint_weights=joint_weights(smap), **options
    )
    solver.set_naturalness(natural.from_signer_map(solver.model, smap, solver.natural))
    if "seeder" not in options:
        solver.seeder = branch_seeder(solver, smap)
    return solver


def branch_seeder(solver: ik.Solver, smap: SignerMap):
    """The solver's ``seeder`` for a signer: when a solve fails from its warm start, the
    placed hands turned and each arm on other elbow-swivel branches
    (:func:`azee_mj.reach.swivel_seeds`)."""
    anatomy = SignerAnatomy(solver.model, smap)
    arms = list(anatomy.arms)
    if not arms:
        return None
    # each arm's forearm pronation and wrist flexion: the track's joints after the elbow
    turns = {}
    for a in arms:
        track = next((t for t in smap.tracks.values() if a.elbow in t), ())
        k = list(track).index(a.elbow) if track else -1
        if 0 <= k and k + 2 < len(track):
            turns[a] = (track[k + 1], track[k + 2])
    return lambda s, problem, q: reach.swivel_seeds(s, arms, anatomy.hand_of, problem, q, turns)


# ---------------------------------------------------------------------------------------
# Score -> IK constraints, and the tracks each drives
# ---------------------------------------------------------------------------------------


def clip_scalar(x: float, lo: float, hi: float) -> float:
    """``np.clip(x, lo, hi)`` of one number, to the bit (a NaN stays NaN; where ``x`` equals
    a bound, ``x``: ``-0.0`` clipped to ``[0.0, 1.0]`` stays ``-0.0``), without the call cost
    of a ufunc on a scalar."""
    return min(max(x, lo), hi)


class Compiler:
    """Translates score records into :mod:`azee_mj.constraints` on one signer, and names the
    tracks each drives."""

    def __init__(
        self, model: mujoco.MjModel, smap: SignerMap, anatomy: SignerAnatomy | None = None
    ):
        self.m, self.smap = model, smap
        self.anatomy = anatomy or SignerAnatomy(model, smap)
        self.joint_track: dict[int, str] = {}
        for track, joints in smap.tracks.items():
            for j in joints:
                self.joint_track[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j)] = track
        self._morph_targets: dict[tuple[str, str], cn.JointTarget] = {}
        self._ranges: dict[str, tuple[np.float64, np.float64, np.float64]] = {}
        self._body_tracks: dict[tuple[int, bool], frozenset[str]] = {}
        self._palm_tracks: dict[int, str] | None = None

    # expressions
    def site(self, ref: sc.SiteRef) -> str:
        return ref.model_site(self.smap)

    # constraints
    def constraint(self, c, label: str):
        """The IK constraint of a place / orient / look, or None for morph / trill."""
        if isinstance(c, sc.Place):
            site, at = self.site(c.site), compile_point(c.at, self.smap)
            ends = None
            if isinstance(at, SitePos) and not c.at.ref.locus:
                ends = contact.rolling(self.m, self.smap, site, at.site)
            if ends is None:
                return cn.Place(site, at, c.tol, label)
            return cn.Place(site, at, c.tol, label, shift=ends[0], gap=ends[1])
        if isinstance(c, sc.Orient):
            b = c.bone.bone_map(self.smap)
            local = b.dir if c.axis is sc.Axis.DIR else b.nrm
            return cn.Orient(
                b.body, local, c.rel, compile_vector(c.vector, self.smap), c.tol, label
            )
        if isinstance(c, sc.Look):
            eyes = tuple(
                (self.smap.bones[e].body, self.smap.bones[e].dir) for e in ("eye_L", "eye_R")
            )
            return cn.Look(eyes, compile_point(c.at, self.smap), np.deg2rad(1.0), label)
        return None

    def morph_changes(self, c: sc.MorphC) -> dict[str, float]:
        """Joint name -> change from ``qpos0`` [rad] of morph ``c`` (at its weight)."""
        return {j: c.weight * v for j, v in self.smap.morphs[c.id].joint_changes(c.side).items()}

    def morph_targets(self, changes: dict[str, float]) -> list[cn.JointTarget]:
        """Joint targets for joint changes from ``qpos0`` [rad], clipped to the joints'
        ranges, within ``MORPH_TOL``."""
        out = []
        for j, v in changes.items():
            zero, lo, hi = self._joint_range(j)
            val = float(clip_scalar(zero + v, lo, hi))
            # one record per joint and value, shared by every key that holds it (each
            # key's own copies grew by about 0.8 MB per minute of score)
            key = (j, val.hex())  # hex: 0.0 and -0.0 stay apart
            target = self._morph_targets.get(key)
            if target is None:
                target = self._morph_targets[key] = cn.JointTarget(j, val, MORPH_TOL, f"morph:{j}")
            out.append(target)
        return out

    def _joint_range(self, joint: str) -> tuple[np.float64, np.float64, np.float64]:
        """Joint ``joint``'s ``qpos0`` and range (looked up once)."""
        out = self._ranges.get(joint)
        if out is None:
            m = self.m
            jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, joint)
            lo, hi = m.jnt_range[jid]
            out = self._ranges[joint] = (m.qpos0[m.jnt_qposadr[jid]], lo, hi)
        return out

    # tracks
    def body_tracks(self, body: int, own_only: bool) -> set[str]:
        """Tracks owning the joints of ``body`` (and, unless ``own_only``, its ancestors'):
        a new set (worked out once per body)."""
        key = (int(body), bool(own_only))
        out = self._body_tracks.get(key)
        if out is None:
            out = self._body_tracks[key] = frozenset(self._body_tracks_of(body, own_only))
        return set(out)

    def _body_tracks_of(self, body: int, own_only: bool) -> set[str]:
        out: set[str] = set()
        while body > 0:
            for j in range(
                self.m.body_jntadr[body], self.m.body_jntadr[body] + self.m.body_jntnum[body]
            ):
                if j in self.joint_track:
                    out.add(self.joint_track[j])
            if own_only and out:
                return out
            body = int(self.m.body_parentid[body])
        return out

    def site_tracks(self, site: str) -> set[str]:
        """A placed site moves its limb: the tracks above it, without hands (shaped by
        morphs) and without the spine unless nothing else can move it."""
        sid = mujoco.mj_name2id(self.m, mujoco.mjtObj.mjOBJ_SITE, site)
        tracks = self.body_tracks(int(self.m.site_bodyid[sid]), own_only=False)
        limb = {t for t in tracks if not t.startswith(("hand", "spine"))}
        return limb or tracks

    def contact_sites(self, c) -> tuple[str, ...]:
        """Model sites a placement ``c`` may touch: the target of a placement at a bare body
        site, or the sites of another arm or hand its target point is built from."""
        if not isinstance(c, sc.Place):
            return ()
        if isinstance(c.at, sc.PSite):
            return () if c.at.ref.locus else (self.site(c.at.ref),)
        return self.partner_sites(c)

    def partner_sites(self, c) -> tuple[str, ...]:
        """Model sites of another arm or hand that placement ``c`` brings its site to.

        That arm moves too, both parts meeting (a hand on the other hand or forearm, a point
        beside the other wrist). A target on the head, the trunk, a shoulder or an upper arm
        is a location the body holds where it is: the hand goes to the face, not the face to
        the hand.
        """
        if not isinstance(c, sc.Place):
            return ()
        own = self.site_tracks(self.site(c.site))
        if isinstance(c.at, sc.PSite):
            sites = [] if c.at.ref.locus else [self.site(c.at.ref)]
        else:
            sites = [self.site(r) for r in sc.referenced_sites(c.at) if not r.locus]
        return tuple(
            s
            for s in sites
            if self.anatomy.on_forearm(s)
            and any(t.startswith("arm") for t in self.site_tracks(s) - own)
        )

    def pinch_track(self, c) -> str | None:
        """The hand track of a placement joining two digits of one hand (a thumb tip on the
        index tip), else None: only the fingers can bring them together, the arm cannot."""
        if not isinstance(c, sc.Place) or not isinstance(c.at, sc.PSite) or c.at.ref.locus:
            return None
        sid, tid = (
            mujoco.mj_name2id(self.m, mujoco.mjtObj.mjOBJ_SITE, self.site(r))
            for r in (c.site, c.at.ref)
        )
        a, b = (int(self.m.site_bodyid[i]) for i in (sid, tid))
        hands = [
            {t for t in self.body_tracks(x, own_only=False) if t.startswith("hand")} for x in (a, b)
        ]
        if a == b or len(hands[0]) != 1 or hands[0] != hands[1]:
            return None
        return next(iter(hands[0]))

    def palm_hands(self, c) -> set[str]:
        """The hand tracks of the palms a contact ``c`` touches with (its placed site or
        the site it meets on a hand's palm, not a finger: the palm, its back or edge): a
        hand given no shape opens its fingers as far as the palms need to meet (curled
        resting fingers are in the way); the comfort rows keep them relaxed otherwise."""
        sites = self.contact_sites(c)
        if not sites:
            return set()
        if self._palm_tracks is None:
            self._palm_tracks = self._hand_tracks_by_palm()
        bodies = (self.anatomy.site_body(s) for s in (self.site(c.site), *sites))
        return {self._palm_tracks[b] for b in bodies if b in self._palm_tracks}

    def _hand_tracks_by_palm(self) -> dict[int, str]:
        """Palm body -> the hand track owning the joints of its fingers."""
        out = {}
        for j, track in self.joint_track.items():
            if track.startswith("hand"):
                body = int(self.m.jnt_bodyid[j])
                for palm in self.anatomy.hands:
                    if descends(self.m, body, palm):
                        out[palm] = track
        return out

    def tracks_of(self, c) -> set[str]:
        """Tracks a score constraint drives (see :func:`constraint_tracks`)."""
        if isinstance(c, sc.Place):
            pinch = self.pinch_track(c)
            if pinch is not None:
                return {pinch}
            out = self.site_tracks(self.site(c.site))
            for s in self.partner_sites(c):  # both parts move
                out |= self.site_tracks(s)
            return out
        if isinstance(c, sc.Orient):
            body = mujoco.mj_name2id(self.m, mujoco.mjtObj.mjOBJ_BODY, c.bone.model_body(self.smap))
            own = self.body_tracks(body, own_only=True)
            if all(t.startswith("hand") for t in own):
                # a finger points with the whole arm, not by bending against its hand shape
                own |= {t for t in self.body_tracks(body, own_only=False) if t.startswith("arm")}
            return own
        if isinstance(c, sc.MorphC):
            out = set()
            for j in self.morph_changes(c):
                out.add(self.joint_track[mujoco.mj_name2id(self.m, mujoco.mjtObj.mjOBJ_JOINT, j)])
            return out
        if isinstance(c, sc.Look):
            return {"eyes", "head"}
        if isinstance(c, sc.Trill):
            if c.site is not None:
                return self.site_tracks(self.site(c.site))
            body = mujoco.mj_name2id(self.m, mujoco.mjtObj.mjOBJ_BODY, c.bone.model_body(self.smap))
            return self.body_tracks(body, own_only=True)
        raise TypeError(c)


def constraint_tracks(c, model: mujoco.MjModel | None = None, signer_map: SignerMap = DEFAULT_MAP):
    """The tracks a score constraint drives (a contact drives both sides it joins)."""
    from azee_mj.model import load_model

    return Compiler(model or load_model(), signer_map).tracks_of(c)


@dataclasses.dataclass(frozen=True)
class TrackInterval:
    """Track ``track`` driven by block ``block`` over ``[start, end)`` [s]."""

    track: str
    block: str
    start: float
    end: float


@dataclasses.dataclass(frozen=True)
class ContactWindow:
    """A contact constraint's interval ``[start, end)`` [s] and the pairs of model bodies
    it brings together (allowed to touch then), each pair in both orders (shared by the
    windows of every contact between the same parts: one set per kind of contact, not one
    record per pair of bodies and block)."""

    start: float
    end: float
    pairs: frozenset[tuple[int, int]]


@dataclasses.dataclass(frozen=True)
class DrivenConstraint:
    """A score constraint of a cstr block: its solver constraint (None for a morph or a
    trill), the joint changes of a morph, the tracks it drives, and the score record."""

    con: cn.Constraint | None
    morph: dict[str, float]
    tracks: set[str]
    source: sc.Constraint


class Schedule:
    """A score laid on a signer: the tracks each block drives, the segments' boundaries and
    the contact windows (no solving)."""

    def __init__(self, score: sc.Score, solver: ik.Solver, signer_map: SignerMap = DEFAULT_MAP):
        self.score, self.solver = score, solver
        self.m = solver.model
        self.smap = signer_map
        self.anatomy = SignerAnatomy(self.m, signer_map)
        self.comp = Compiler(self.m, self.smap, self.anatomy)
        self.track_joints = {t: tuple(js) for t, js in self.smap.tracks.items()}
        self.track_dofs = {
            t: np.array([self.m.jnt_dofadr[solver.joint_id(j)] for j in js], int)
            for t, js in self.track_joints.items()
        }
        self.home = solver.natural.copy()
        self.blocks = [b for b in score.blocks()]
        self.by_path = {b.path: b for b in self.blocks}
        self.contacts = self._contact_windows()
        self._contact_index: IntervalIndex | None = None
        self._unions: dict[tuple[int, ...], frozenset[tuple[int, int]]] = {}
        self._moved_cache: dict = {}
        self._shaped: dict[str, frozenset[str]] = {}
        self._morphed: list[tuple[float, float, frozenset[str]]] | None = None
        self._track_sets: dict[frozenset[str], frozenset[str]] = {}
        self.body_names = [
            mujoco.mj_id2name(self.m, mujoco.mjtObj.mjOBJ_BODY, b) for b in range(self.m.nbody)
        ]

    def _contact_windows(self) -> list[ContactWindow]:
        """The windows of the body pairs each contact constraint of the score may bring
        together: a hand counts as one part (its fingers touch too), except in a contact
        of two digits of one hand (a pinch), which brings only their two phalanges
        together: the rest of that hand keeps clear of itself."""
        out, shared = [], {}
        part, site_body = self.anatomy.part, self.anatomy.site_body
        for b in self.blocks:
            for c in b.constraints if b.kind is sc.BlockKind.CSTR else ():
                partners = self.comp.contact_sites(c)
                if partners:
                    body = site_body(self.comp.site(c.site))
                    mine = part(body)
                for s in partners:
                    other = part(site_body(s))
                    pair = ((body,), (site_body(s),)) if other == mine else (mine, other)
                    pairs = frozenset(
                        p for x in pair[0] for y in pair[1] if x != y for p in ((x, y), (y, x))
                    )
                    if pairs:
                        out.append(ContactWindow(b.start, b.end, shared.setdefault(pairs, pairs)))
        return out

    def allowed_at(self, t: float) -> frozenset[tuple[int, int]]:
        """Body pairs a contact active at time ``t`` [s] brings together (both orders)."""
        if self._contact_index is None:  # (in logarithmic time: asked at every frame)
            self._contact_index = IntervalIndex((w.start - 1e-9, w.end) for w in self.contacts)
        held = self._contact_index.at(t)
        if len(held) == 1:
            return self.contacts[held[0]].pairs
        key = tuple(held)
        out = self._unions.get(key)
        if out is None:  # one set per combination of contacts (its hash kept)
            out = self._unions[key] = frozenset().union(*(self.contacts[i].pairs for i in held))
        return out

    def block_constraints(self, b: sc.Block) -> list[DrivenConstraint]:
        """What each constraint of a cstr block drives, in order."""
        out = []
        for c in b.constraints:
            label = f"{b.path}#{c.index}"
            tracks = self.block_tracks(b, c)
            if isinstance(c, sc.MorphC):
                out.append(DrivenConstraint(None, self.comp.morph_changes(c), tracks, c))
            elif isinstance(c, sc.Trill):
                out.append(DrivenConstraint(None, {}, tracks, c))
            else:
                out.append(DrivenConstraint(self.comp.constraint(c, label), {}, tracks, c))
        return out

    def block_tracks(self, b: sc.Block, c) -> set[str]:
        """Tracks constraint ``c`` of cstr block ``b`` drives: the compiler's
        (:meth:`Compiler.tracks_of`), with the fingers of a palm it touches with
        (:meth:`Compiler.palm_hands`) when no morph of a block over ``b``'s time shapes
        that hand."""
        out = self.comp.tracks_of(c)
        free = self.comp.palm_hands(c)
        if free:
            out |= free - self.shaped_hands(b)
        return out

    def shaped_hands(self, b: sc.Block) -> frozenset[str]:
        """The tracks morphs of the cstr blocks overlapping block ``b`` drive (worked out
        once per block)."""
        out = self._shaped.get(b.path)
        if out is None:
            if self._morphed is None:  # (start, end, tracks) of each block with morphs
                self._morphed = [
                    (o.start, o.end, frozenset().union(*(self.comp.tracks_of(m) for m in ms)))
                    for o in self.blocks
                    if o.kind is sc.BlockKind.CSTR
                    for ms in [[m for m in o.constraints if isinstance(m, sc.MorphC)]]
                    if ms
                ]
            out = self._shaped[b.path] = frozenset().union(
                *(t for s, e, t in self._morphed if s < b.end and b.start < e)
            )
        return out

    def intervals(self) -> dict[str, tuple[TrackInterval, ...]]:
        """Per track, the intervals blocks drive it, in time order."""
        sched: dict[str, list[TrackInterval]] = {t: [] for t in self.track_joints}
        for b in self.blocks:
            if b.kind is sc.BlockKind.CSTR:
                tracks = set().union(*(self.block_tracks(b, c) for c in b.constraints))
            elif b.kind is sc.BlockKind.HOLD:
                tracks = self.held_tracks(b)
            elif b.kind is sc.BlockKind.TRANSPATH:
                tracks = self.comp.site_tracks(self.comp.site(b.transpath_site))
            else:
                continue
            for t in tracks:
                sched[t].append(TrackInterval(t, b.path, b.start, b.end))
        return {t: tuple(sorted(v, key=lambda i: (i.start, i.end))) for t, v in sched.items()}

    def held_tracks(self, hold: sc.Block) -> set[str]:
        """The tracks the block a hold keeps drove (nested holds included)."""
        held = self.by_path[hold.hold_of]
        out: set[str] = set()
        for b in held.blocks():
            if b.kind is sc.BlockKind.CSTR:
                for c in b.constraints:
                    if not isinstance(c, sc.Trill):
                        out |= self.block_tracks(b, c)
            elif b.kind is sc.BlockKind.HOLD:
                out |= self.held_tracks(b)
        return out

    def events(self) -> list[float]:
        """Block boundaries [s] that cut the score into segments, in order."""
        ts = {0.0, self.score.duration}
        for b in self.blocks:
            if b.kind in (sc.BlockKind.CSTR, sc.BlockKind.HOLD):
                ts.update((b.start, b.end))
        return sorted(t for t in ts if 0.0 <= t <= self.score.duration)

    def moved_by(self, c) -> frozenset[str]:
        """Tracks whose joints move a body that IK constraint ``c`` names."""
        if c not in self._moved_cache:
            bodies = self.solver.bodies_of(c)
            tracks = frozenset().union(*(self.comp.body_tracks(b, own_only=False) for b in bodies))
            # one set per answer, shared by every constraint giving it (a score has few)
            self._moved_cache[c] = self._track_sets.setdefault(tracks, tracks)
        return self._moved_cache[c]

    def moving_dofs(self, c) -> np.ndarray:
        """The dofs of the joints that move a body IK constraint ``c`` names (those of its
        ancestors: the jaw's opening moves the chin, the brows do not), sorted."""
        key = ("dofs", c)
        if key not in self._moved_cache:
            m, dofs = self.m, set()
            for b in self.solver.bodies_of(c):
                while b > 0:
                    dofs.update(range(m.body_dofadr[b], m.body_dofadr[b] + m.body_dofnum[b]))
                    b = int(m.body_parentid[b])
            self._moved_cache[key] = np.array(sorted(dofs), int)
        return self._moved_cache[key]


def shifted(
    intervals: Mapping[str, tuple[TrackInterval, ...]], by: float
) -> dict[str, tuple[TrackInterval, ...]]:
    """``intervals`` (per track) moved ``by`` seconds later: a score's schedule on the clock of
    a rollout whose score starts at ``by`` [s]."""
    if not by:
        return dict(intervals)
    return {
        t: tuple(dataclasses.replace(i, start=i.start + by, end=i.end + by) for i in v)
        for t, v in intervals.items()
    }


def schedule(
    score: sc.Score | str, solver: ik.Solver | None = None
) -> dict[str, tuple[TrackInterval, ...]]:
    """Per track, the intervals blocks drive it, without solving anything."""
    if not isinstance(score, sc.Score):
        score = sc.load_score(score)
    return Schedule(score, solver or make_solver()).intervals()


class FramePairs(Mapping):
    """Frame -> the body-name pairs (a frozenset) that contact constraints active then
    bring together, for the frames that have some. A frame's pairs are gathered when asked
    from the contacts' frame spans (a table of every frame's pairs took hundreds of bytes
    a frame of contact: tens of MB over an hour of score)."""

    def __init__(self, spans: dict[tuple[int, int], frozenset[tuple[str, str]]]):
        #: (first frame, frame after the last) -> the pairs brought together over them.
        self.spans = [(a, b, v) for (a, b), v in spans.items() if a < b]
        self._index = IntervalIndex((a, b) for a, b, _ in self.spans)

    def __getitem__(self, frame: int) -> frozenset[tuple[str, str]]:
        if not isinstance(frame, int | np.integer):
            raise KeyError(frame)
        held = self._index.at(int(frame))
        if not held:
            raise KeyError(frame)
        if len(held) == 1:
            return self.spans[held[0]][2]
        return frozenset().union(*(self.spans[i][2] for i in held))

    def __iter__(self):
        return iter(sorted({f for a, b, _ in self.spans for f in range(a, b)}))

    def __len__(self) -> int:
        return len({f for a, b, _ in self.spans for f in range(a, b)})


def contact_pairs(
    score: sc.Score | str | Mapping,
    times: np.ndarray,
    solver: ik.Solver | None = None,
    score_start: float = 0.0,
) -> FramePairs:
    """Frame -> body-name pairs that a contact constraint active then brings together, on
    frames at ``times`` [s] (a rollout's clock, the score's time 0 at ``score_start``)."""
    if not isinstance(score, sc.Score):
        score = sc.load_score(score)
    r = Schedule(score, solver or make_solver())
    spans: dict[tuple[int, int], set[tuple[str, str]]] = {}
    fps = (len(times) - 1) / times[-1] if len(times) > 1 and times[-1] > 0 else 1.0
    lead = round(score_start * fps)
    for w in r.contacts:
        f = frame_range(w.start, w.end, fps, len(times) - lead)
        pairs = {(r.body_names[a], r.body_names[b]) for a, b in w.pairs if a < b}
        spans.setdefault((f.start + lead, f.stop + lead), set()).update(pairs)
    return FramePairs({k: frozenset(v) for k, v in spans.items()})
