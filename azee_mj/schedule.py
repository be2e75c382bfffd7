"""The signer as the realizer drives it: a solver for a signer, and the tracks (articulator
groups) that score constraints drive.
"""

from __future__ import annotations

import os

import mujoco
import numpy as np

from azee_mj import constraints as cn
from azee_mj import ik
from azee_mj import score as sc
from azee_mj.kinematics import compile_point, compile_vector
from azee_mj.model import MODEL_PATH
from azee_mj.sites import DEFAULT_MAP, SignerMap

#: How dear moving a track's joints is, relative to an arm joint (1): the trunk and neck are
#: dearer to move than the arms, and a clavicle joint costs CLAVICLE_WEIGHT.
TRACK_WEIGHTS = {"spine": 8.0, "head": 4.0}
CLAVICLE_WEIGHT = 3.0


def joint_weights(signer_map: SignerMap) -> dict[str, float]:
    """Joint name -> weight for :class:`~azee_mj.ik.Solver` from the tracks of ``signer_map``."""
    return {j: TRACK_WEIGHTS.get(track, CLAVICLE_WEIGHT if "clav" in j else 1.0)
            for track, joints in signer_map.tracks.items() for j in joints}  # fmt: skip


def make_solver(
    model: str | os.PathLike | mujoco.MjSpec | None = None,
    signer_map: SignerMap | None = None,
    **options,
) -> ik.Solver:
    """An :class:`~azee_mj.ik.Solver` for a signer: ``model`` (default the bundled one) with
    the joint weights of ``signer_map`` (default :data:`~azee_mj.sites.DEFAULT_MAP`);
    ``options`` go to the solver (``seed``, ``max_iter``, ``on_solve``, ...)."""
    smap = signer_map or DEFAULT_MAP
    return ik.Solver(MODEL_PATH if model is None else model, joint_weights=joint_weights(smap),
                     **options)  # fmt: skip


# ---------------------------------------------------------------------------------------
# Score -> IK constraints, and the tracks each drives
# ---------------------------------------------------------------------------------------


class Compiler:
    """Translates score records into :mod:`azee_mj.constraints` on one signer, and names the
    tracks each drives."""

    def __init__(self, model: mujoco.MjModel, smap: SignerMap):
        self.m, self.smap = model, smap
        self.joint_track: dict[int, str] = {}
        for track, joints in smap.tracks.items():
            for j in joints:
                self.joint_track[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j)] = track

    # expressions
    def site(self, ref: sc.SiteRef) -> str:
        return ref.model_site(self.smap)

    # constraints
    def constraint(self, c, label: str):
        """The IK constraint of a place / orient / look, or None for morph / trill."""
        if isinstance(c, sc.Place):
            return cn.Place(self.site(c.site), compile_point(c.at, self.smap), c.tol, label)
        if isinstance(c, sc.Orient):
            b = c.bone.bone_map(self.smap)
            local = b.dir if c.axis is sc.Axis.DIR else b.nrm
            return cn.Orient(b.body, local, cn.Rel(c.rel.value), compile_vector(c.vector, self.smap), c.tol,
                             label)  # fmt: skip
        if isinstance(c, sc.Look):
            eyes = tuple((self.smap.bones[e].body, self.smap.bones[e].dir)
                         for e in ("eye_L", "eye_R"))  # fmt: skip
            return cn.Look(eyes, compile_point(c.at, self.smap), np.deg2rad(1.0), label)
        return None

    def morph_changes(self, c: sc.MorphC) -> dict[str, float]:
        return {j: c.weight * v for j, v in self.smap.morphs[c.id].joint_changes(c.side).items()}

    # tracks
    def body_tracks(self, body: int, own_only: bool) -> set[str]:
        """Tracks owning the joints of ``body`` (and, unless ``own_only``, its ancestors')."""
        out: set[str] = set()
        while body > 0:
            for j in range(self.m.body_jntadr[body],
                           self.m.body_jntadr[body] + self.m.body_jntnum[body]):  # fmt: skip
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

    def partner_sites(self, c) -> tuple[str, ...]:
        """Model sites of the other part when placement ``c`` brings two parts together.

        A placement at a bare body site is a contact: both parts move to meet. A placement
        at a point that reads sites of an arm or hand (``@I_TIP(w)`` translated, the middle
        of two fingertips) also moves that arm, since the point rides on it; a point that
        reads only the head or trunk is a location that stays where the body holds it.
        """
        if not isinstance(c, sc.Place):
            return ()
        if isinstance(c.at, sc.PSite):
            return () if c.at.ref.locus else (self.site(c.at.ref),)
        own = self.site_tracks(self.site(c.site))
        sites = [self.site(r) for r in sc.referenced_sites(c.at) if not r.locus]
        return tuple(s for s in sites
                     if any(t.startswith("arm") for t in self.site_tracks(s) - own))  # fmt: skip

    def tracks_of(self, c) -> set[str]:
        """Tracks a score constraint drives (see :func:`constraint_tracks`)."""
        if isinstance(c, sc.Place):
            out = self.site_tracks(self.site(c.site))
            for s in self.partner_sites(c):  # both parts move
                out |= self.site_tracks(s)
            return out
        if isinstance(c, sc.Orient):
            body = mujoco.mj_name2id(self.m, mujoco.mjtObj.mjOBJ_BODY, c.bone.model_body(self.smap))
            return self.body_tracks(body, own_only=True)
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
