"""Natural preferences a key posture is solved with, below the score's constraints: two
skin surfaces that touch face to face, two hands meeting in the signing space, elbows low,
the chest upright once the trunk is recruited.

The tolerances are data (module constants); :class:`Preferences` turns them into the
constraints and preference rows of one group's solve.

Units: metres, radians (the tolerance tables in degrees, as named).
"""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np

from azee_mj import constraints as cn
from azee_mj import ik, natural
from azee_mj.anatomy import SignerAnatomy
from azee_mj.kinematics import BodyAxis, BodyOrigin, Const, SitePos
from azee_mj.sites import DIGITS, SignerMap

#: How nearly two skin surfaces a placement joins face each other [deg], by the hand part
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
#: Two parts neither of which is a hand part (an elbow on the chest) [deg].
FACING_TOL_BODY = 20.0
#: An elbow held below its shoulder, as a natural preference when the hand is placed
#: below the brows: (how far below [m], the height above that costs one unit [m]). As
#: low as ``ELBOW_RAISED``: an elbow higher holds the upper arm nearly horizontal.
ELBOW_LOW = (0.08, 0.02)
#: How far above the highest brow (or eye) site a placed hand still keeps its elbow low [m].
BROW_MARGIN = 0.005
#: How far from vertical [deg] the forearm of a hand placed on the face may be in the solves
#: that bring the hand up from below (:meth:`Preferences.forearms_under`), each tried.
UNDER_TOL_DEG = (20.0, 30.0, 45.0, 60.0)
#: An elbow less than this below its shoulder holds the upper arm nearly horizontal [m]: a
#: hand on the face held so is solved again from below.
ELBOW_RAISED = 0.08
#: Rounded parts of the body [deg]: a fingertip meets them from a range of directions
#: around the site's normal (the shoulder's cap, the forehead's and the temple's curve),
#: as far as the fingertip's own roundness lets the site meet within its tolerance without
#: sinking in.
FACING_TOL_ROUNDED = {"SH": 45.0, "FH": 40.0, "TE": 40.0}
#: How far the chest may lean from upright for one unit of naturalness cost, once the trunk
#: is recruited [deg]: far dearer than any joint's comfort, so the trunk leans only as much
#: as the constraints need.
UPRIGHT_TOL_DEG = 3.0


def facing_tol(a: str, b: str) -> float:
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


def widened(facing, factor: float = FACING_WIDEN) -> list[cn.Orient]:
    """The facing constraints ``facing`` with their tolerances ``factor`` times wider."""
    return [dataclasses.replace(f, tol=factor * f.tol) for f in facing]


class Preferences:
    """The natural preferences of the signer mapped by ``smap``, evaluated with
    ``solver`` (its kinematics) and ``anatomy``."""

    def __init__(self, solver: ik.Solver, anatomy: SignerAnatomy, smap: SignerMap):
        self.solver, self.anatomy, self.smap = solver, anatomy, smap
        self.azee_site = {model: azee for azee, model in smap.sites.items()}
        self._bone_of = {b.body: b for b in smap.bones.values()}  # see _on_face
        ssp = smap.loci.get("ssp")
        #: The model site where two hands meet (the neutral signing space), or None.
        self.meet = (
            ssp
            if ssp is not None
            and mujoco.mj_name2id(solver.model, mujoco.mjtObj.mjOBJ_SITE, ssp) >= 0
            else None
        )
        self.chest = chest = smap.bones.get("back_2")
        #: The chest upright, a preference once the trunk is recruited (least recruitment).
        self.upright = (
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

    def joins_hands(self, c) -> bool:
        """Whether constraint ``c`` places a site of one hand on a site of the other."""
        return (
            isinstance(c, cn.Place)
            and isinstance(c.target, SitePos)
            and self.anatomy.joins_hands(c.site, c.target.site)
        )

    def facing(self, cons) -> list[cn.Orient]:
        """For each placement of a skin site on another, the two surfaces face to face:
        outward normals opposed (within :func:`facing_tol`), unless the score orients one
        of the two bodies itself."""
        oriented = {c.body for c in cons if isinstance(c, cn.Orient)}
        normals, m = self.smap.normals, self.solver.model
        out = []
        for c in cons:
            if not isinstance(c, cn.Place) or not isinstance(c.target, SitePos):
                continue
            a, b = self.azee_site.get(c.site), self.azee_site.get(c.target.site)
            if a not in normals or b not in normals:
                continue
            ba, bb = (m.body(self.anatomy.site_body(s)).name for s in (c.site, c.target.site))
            if ba in oriented or bb in oriented:
                continue
            label = f"{c.label}:facing"
            out.append(
                cn.Orient(
                    ba,
                    normals[a],
                    cn.Rel.OPP,
                    BodyAxis(bb, normals[b]),
                    facing_tol(a, b),
                    label,
                    ranged=False,
                )
            )
        return out

    def meeting_place(self, cons) -> tuple[cn.Place, ...]:
        """Where two hands meet when nothing else places them: a preference (with the
        naturalness, below the constraints) for the contact in the neutral signing space,
        where signers join their hands, rather than low where holding them costs least.
        A hand that touches the other arm (its elbow, forearm or upper arm) meets it in
        front of the body too: that arm's palm prefers ``ACROSS``, its forearm raised in
        front with the elbow bent and low, instead of the arm held out to the side."""
        if self.meet is None:
            return ()
        placed = [c for c in cons if isinstance(c, cn.Place)]
        if len(placed) != 1 or not isinstance(placed[0].target, SitePos):
            return ()
        c = placed[0]
        arm = self.anatomy.hand_of(c.site)
        if arm is None:
            return ()
        if self.joins_hands(c):
            return (cn.Place(c.site, SitePos(self.meet), MEET_TOL, "meet"),)
        held = self.anatomy.carried_by(c.target.site)
        if held is not None and held.arm is not arm:
            return (cn.Place(held.palm, held.rest, MEET_TOL, "meet"),)
        return ()

    def _below_brows(self, cons, free, q: np.ndarray):
        """(arm, target [m, world]) of each free arm whose hand ``cons`` place below the
        brows (the eyes, the temples, the face below), its first placement, on posture
        ``q``."""
        brows = [s for a, s in self.smap.sites.items() if a.startswith(("EB_", "EYE_"))]
        if not brows:
            return []
        k = self.solver.at(q)
        brow_z = max(k.value(SitePos(s))[2] for s in brows) + BROW_MARGIN
        out, done = [], set()
        free = set(free)
        for c in cons:
            if not isinstance(c, cn.Place) or (arm := self.anatomy.hand_of(c.site)) is None:
                continue
            if arm in done or not {arm.flex, arm.abd, arm.rot, arm.elbow} <= free:
                continue
            done.add(arm)
            target = k.value(c.target)
            if target[2] < brow_z:
                out.append((arm, target))
        return out

    def elbows_low(self, cons, free, q: np.ndarray) -> tuple[natural.Below, ...]:
        """A preference, with the naturalness, for each free arm whose hand is placed below
        the brows (the eyes, the temples, the face below): its elbow no higher than its
        shoulder (``ELBOW_LOW``). Comfort alone would sometimes fold a raised arm (the
        upper arm up, the forearm back, or sideways to the horizontal for a temple) rather
        than bend the wrist; a signer keeps the elbow down unless the hand goes higher."""
        margin, tol = ELBOW_LOW
        return tuple(
            natural.Below(arm.fore, arm.upper, margin, tol, "elbow low")
            for arm, _ in self._below_brows(cons, free, q)
        )

    def _on_face(self, cons, free, q: np.ndarray):
        """(arm, its forearm's bone, its elbow's height above its shoulder [m]) of each
        free arm whose hand ``cons`` place on the face (above the shoulder, below the
        brows), on posture ``q``."""
        below = self._below_brows(cons, free, q)  # (its kinematics on q, when any)
        k = self.solver.kinematics()
        out = []
        for arm, target in below:
            bone, shoulder = self._bone_of.get(arm.fore), k.value(BodyOrigin(arm.upper))[2]
            if bone is not None and target[2] > shoulder:
                out.append((arm, bone, k.value(BodyOrigin(arm.fore))[2] - shoulder))
        return out

    def raised_on_face(self, cons, free, q: np.ndarray) -> frozenset:
        """The free arms whose hand ``cons`` place on the face (above the shoulder, below
        the brows) with the elbow, on posture ``q``, less than ``ELBOW_RAISED`` below the
        shoulder or above it: the arms whose hand the realizer tries bringing up from
        below (see :meth:`~azee_mj.keyposes.GroupPoser.from_below`)."""
        on_face = self._on_face(cons, free, q)
        return frozenset(arm for arm, _, h in on_face if h > -ELBOW_RAISED)

    def forearms_under(self, arms, tol: float) -> tuple[cn.Orient, ...]:
        """For each arm of ``arms``, its forearm within ``tol`` [rad] of vertical: not a
        preference but the constraints of another solve, the hand brought up from below
        with the elbow low in front (see
        :meth:`~azee_mj.keyposes.GroupPoser.from_below`)."""
        up = Const((0.0, 0.0, 1.0))
        return tuple(
            cn.Orient(arm.fore, self._bone_of[arm.fore].dir, cn.Rel.ALONG, up, tol, "forearm under")
            for arm in sorted(arms, key=lambda a: a.upper)
        )

    def elbows_up(self, cons, free, q: np.ndarray) -> set[str]:
        """The upper arms (body names) whose elbow posture ``q`` raises above the shoulder
        while :meth:`elbows_low` prefers it low."""
        k = self.solver.at(q, jacobians=True)
        low = self.elbows_low(cons, free, q)
        return {b.ref for b in low if b.rows(k)[0][0] * b.tol > b.margin}

    def joined_behind(self, cons, q: np.ndarray) -> bool:
        """Whether a placement of ``cons`` that joins the two hands meets, in posture
        ``q``, behind the chest's frontal plane (the hands behind the back)."""
        chest = self.chest
        joined = [c for c in cons if self.joins_hands(c)]
        if chest is None or not joined:
            return False
        k = self.solver.at(q)
        origin = k.value(BodyOrigin(chest.body))
        forward = k.value(BodyAxis(chest.body, chest.nrm))
        return any((k.value(SitePos(c.site)) - origin) @ forward < 0.0 for c in joined)
