#!/usr/bin/env python3
"""Generate the bundled MJCF signer: ``azee_mj/mjcf/signer.xml`` and ``scene.xml``.

Run from the repository root::

    python tools/build_signer.py

The model is written as data here, in *world* coordinates of the rest pose (``qpos0``):
every body frame is aligned with the world at ``qpos0``, so a body's position, its geoms
and its sites are simply world points minus the body's world origin. The RIGHT arm and hand
(and every lateral feature of the head and trunk) are defined once, with ``{X}`` in their
names, and mirrored across the sagittal plane ``y = 0`` for the left side, so the model is
exactly symmetric:

* points (body origins, geom ends and centres, sites) map ``(x, y, z) -> (x, -y, z)``;
* hinge axes (axial vectors) map ``(ax, ay, az) -> (-ax, ay, -az)``, so that the same angle
  gives the mirrored motion;
* slide axes (polar vectors) map like points.

Sources of the numbers are in ``azee_mj/mjcf/README.md``.
"""

from __future__ import annotations

import dataclasses
import itertools
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from azee_mj.sites import (
    ARM_R_ORIGIN,
    CLAV_R_ORIGIN,
    THUMB_DIR_R,
    THUMB_NRM_R,
)

OUT_DIR = ROOT / "azee_mj" / "mjcf"

# ---------------------------------------------------------------------------------------
# Dimensions [m] (stature H = 1.70 m; README.md gives the sources)
# ---------------------------------------------------------------------------------------
H = 1.70
UPPER_ARM = 0.316  # 0.186 H, shoulder joint centre to elbow
FOREARM = 0.248  # 0.146 H, elbow to wrist
HAND = 0.184  # 0.108 H, wrist joint to the tip of the middle finger

#: Buchholz et al. (1992): bone lengths as fractions of hand length
#: (metacarpal, proximal, middle, distal).
BUCHHOLZ = {
    "index": (0.374, 0.265, 0.143, 0.097),
    "middle": (0.373, 0.277, 0.170, 0.108),
    "ring": (0.336, 0.259, 0.165, 0.107),
    "little": (0.295, 0.206, 0.117, 0.093),
    "thumb": (0.251, 0.196, 0.158),  # metacarpal, proximal, distal
}
#: Phalanx lengths [m] (proximal, middle, distal) and thumb (metacarpal, proximal, distal).
PHALANX_LEN = {f: tuple(HAND * x for x in v[1:]) for f, v in BUCHHOLZ.items() if f != "thumb"}
THUMB_LEN = tuple(HAND * x for x in BUCHHOLZ["thumb"])
#: Wrist joint to the middle finger's MCP joint: the hand length minus the middle finger.
PALM_LEN = HAND - sum(PHALANX_LEN["middle"])

#: MCP joint centres relative to the wrist (x toward the thumb side, z down the hand).
#: The middle MCP lies on the palm's DIR line (x = 0); the knuckle arcade follows the
#: metacarpal lengths (ring and little MCPs sit higher than the middle's).
MCP = {
    "index": (0.0197, 0.0, -(PALM_LEN - 0.0014)),
    "middle": (0.0, 0.0, -PALM_LEN),
    "ring": (-0.0193, 0.0, -(PALM_LEN - 0.0029)),
    "little": (-0.0372, 0.0, -(PALM_LEN - 0.0089)),
}
#: Collision radii of the phalanges (proximal, middle, distal).
PHALANX_RAD = {
    "index": (0.0090, 0.0078, 0.0068),
    "middle": (0.0092, 0.0080, 0.0070),
    "ring": (0.0086, 0.0076, 0.0066),
    "little": (0.0078, 0.0069, 0.0061),
}
THUMB_RAD = (0.0115, 0.0095, 0.0085)
#: Thumb CMC joint relative to the wrist (toward the thumb side, in the palm's mid-plane,
#: down): the adducted thumb (``THUMB_DIR_R``) then clears the palm's radial edge by 2.8 mm
#: from its MCP on, and its capsules are flush with the palm's face.
THUMB_CMC = (0.0220, 0.0, -0.0180)
PALM_HALF_THICK = 0.0140

# World positions of the joint centres at qpos0 (signer frame: +x forward, +y left, +z up).
PELVIS = np.zeros(3)
BACK_1 = np.array([-0.02, 0.0, 0.10])  # lumbar (L3-L4 region)
BACK_2 = np.array([-0.02, 0.0, 0.28])  # thoraco-lumbar (T11-T12 region)
NECK = np.array([-0.02, 0.0, 0.52])  # cervico-thoracic (C7-T1)
HEAD = np.array([-0.02, 0.0, 0.635])  # atlanto-occipital
JAW = np.array([0.0, 0.0, 0.655])  # temporo-mandibular joints' axis
EYE_R = np.array([0.072, -0.032, 0.692])
CLAV_R = np.array(CLAV_R_ORIGIN)
ARM_R = np.array(ARM_R_ORIGIN)
ELBOW_R = ARM_R + [0.0, 0.0, -UPPER_ARM]
WRIST_R = ELBOW_R + [0.0, 0.0, -FOREARM]

#: Head shapes (world, qpos0): cranium and mid-face ellipsoids (centre, semi-axes).
CRANIUM = (np.array([-0.010, 0.0, 0.700]), np.array([0.097, 0.079, 0.098]))
FACE = (np.array([0.030, 0.0, 0.650]), np.array([0.058, 0.060, 0.062]))
CHIN = (np.array([0.056, 0.0, 0.598]), np.array([0.032, 0.038, 0.026]))
CHEST = (np.array([-0.015, 0.0, 0.375]), np.array([0.100, 0.130, 0.165]))
ABDOMEN = (np.array([-0.010, 0.0, 0.190]), np.array([0.095, 0.125, 0.115]))
HIPS = (np.array([-0.020, 0.0, 0.030]), np.array([0.100, 0.145, 0.100]))
NECK_RAD = 0.045
#: The larynx (the thyroid cartilage, the Adam's apple) on the front of the neck capsule. The
#: capsule alone is round, 90 mm across, and put the throat 21 mm behind the sternoclavicular
#: joints, the chest's top 29 mm under it: a pointing index could not lay its pad there
#: without its curled fingers in the chest. The larynx stands 29 mm proud of the capsule (the
#: neck 119 mm deep there, an adult's depth at the larynx), 40 mm wide and 56 mm tall, its
#: back inside the capsule, 29 mm or more from the clavicles at any shrug.
LARYNX = (np.array([0.020, 0.0, 0.555]), np.array([0.033, 0.020, 0.028]))
#: Height of `NK` (the throat) on the larynx: on its upper front, where the prominence turns
#: up toward the chin (outward normal 12 degrees above the horizontal), 40 mm above the neck
#: joint.
NK_Z = 0.560
#: Hair cap (collision too: the top and back of the head are hair), ears, nose base.
HAIR = (np.array([-0.022, 0.0, 0.718]), np.array([0.098, 0.085, 0.090]))
EAR_R_SHAPE = (np.array([-0.012, -0.079, 0.672]), np.array([0.013, 0.007, 0.027]))
#: The right ear site's outward normal: turned 60 degrees forward from the side, 20 down.
_F, _D = np.radians(60.0), np.radians(20.0)
EAR_R_NORMAL = np.array([np.cos(_D) * np.sin(_F), -np.cos(_D) * np.cos(_F), -np.sin(_D)])
NOSE_BASE = (np.array([0.096, 0.0, 0.651]), np.array([0.010, 0.013, 0.008]))
#: The eyeball's collision radius: the closed lid's (the visual eyeball is 12 mm).
EYE_RAD = 0.0125

THUMB_D = np.array(THUMB_DIR_R)
THUMB_N = np.array(THUMB_NRM_R)
DOWN = np.array([0.0, 0.0, -1.0])
PALMAR_R = np.array([0.0, 1.0, 0.0])


def surface(ellipsoid, direction) -> np.ndarray:
    """The point where the ray from an ellipsoid's centre along ``direction`` leaves it."""
    c, r = ellipsoid
    d = np.asarray(direction, float)
    return c + d / np.sqrt(np.sum((d / r) ** 2))


def surface_normal(ellipsoid, normal) -> np.ndarray:
    """The point of an ellipsoid whose outward normal is ``normal``."""
    c, r = ellipsoid
    n = unit(normal)
    return c + r**2 * n / np.linalg.norm(r * n)


def front(ellipsoid, y, z) -> np.ndarray:
    """The front (+x) surface point of an axis-aligned ellipsoid at world ``y``, ``z``."""
    c, r = ellipsoid
    s = 1.0 - ((y - c[1]) / r[1]) ** 2 - ((z - c[2]) / r[2]) ** 2
    return np.array([c[0] + r[0] * np.sqrt(max(s, 0.0)), y, z])


def unit(v) -> np.ndarray:
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


# ---------------------------------------------------------------------------------------
# A tiny scene graph in world coordinates, mirrored for the left side
# ---------------------------------------------------------------------------------------


@dataclasses.dataclass
class Joint:
    name: str
    cls: str
    axis: tuple
    range: tuple
    type: str = "hinge"
    home: float = 0.0  # value in the `home` keyframe [rad or m]
    mirror: bool = True  # False: the left joint keeps the right's axis (the eyes' conjugate motion)


@dataclasses.dataclass
class Geom:
    attrs: dict  # numeric vectors in world coordinates under "pos" / "fromto"


@dataclasses.dataclass
class Site:
    name: str
    pos: np.ndarray


@dataclasses.dataclass
class Body:
    name: str
    pos: np.ndarray  # world origin at qpos0
    joints: list = dataclasses.field(default_factory=list)
    geoms: list = dataclasses.field(default_factory=list)
    sites: list = dataclasses.field(default_factory=list)
    children: list = dataclasses.field(default_factory=list)
    inertial: dict | None = None
    comment: str | None = None
    cameras: list = dataclasses.field(default_factory=list)  # (name, world pos, target, fovy)

    def add(self, child: Body) -> Body:
        self.children.append(child)
        return child

    def geom(self, **attrs) -> None:
        self.geoms.append(Geom(attrs))

    def site(self, name: str, pos) -> None:
        self.sites.append(Site(name, np.asarray(pos, float)))


def mirror_point(p):
    return np.array([p[0], -p[1], p[2]], float)


def mirror_hinge(a):
    return (-a[0], a[1], -a[2])


def mirror_slide(a):
    return (a[0], -a[1], a[2])


def sided(name: str, side: str) -> str:
    return name.replace("{X}", side)


def realize(body: Body, side: str) -> Body:
    """A concrete copy of a templated right-side subtree for ``side`` (``"R"`` or ``"L"``)."""
    m = side == "L"

    def pt(p):
        return mirror_point(p) if m else np.asarray(p, float)

    inertial = body.inertial
    if inertial and "pos" in inertial:
        inertial = {**inertial, "pos": pt(inertial["pos"])}
    out = Body(sided(body.name, side), pt(body.pos), inertial=inertial, comment=body.comment)
    out.cameras = list(body.cameras)
    for j in body.joints:
        axis = j.axis
        if m and j.mirror:
            axis = mirror_hinge(axis) if j.type == "hinge" else mirror_slide(axis)
        lo, hi = j.range
        if isinstance(lo, dict):  # side-dependent range (the eyes)
            lo, hi = lo[side], hi[side]
        out.joints.append(
            dataclasses.replace(j, name=sided(j.name, side), axis=axis, range=(lo, hi))
        )
    for g in body.geoms:
        a = dict(g.attrs)
        if "pos" in a:
            a["pos"] = pt(a["pos"])
        if "fromto" in a:
            ft = np.asarray(a["fromto"], float)
            a["fromto"] = np.concatenate([pt(ft[:3]), pt(ft[3:])])
        if "xyaxes" in a:  # symmetric shapes only: mirror both frame vectors
            xy = np.asarray(a["xyaxes"], float)
            a["xyaxes"] = np.concatenate([pt(xy[:3]), pt(xy[3:])])
        out.geoms.append(Geom(a))
    for s in body.sites:
        out.sites.append(Site(sided(s.name, side), pt(s.pos)))
    for c in body.children:
        out.children.append(realize(c, side))
    return out


def both_sides(add_right, body: Body) -> None:
    """Call ``add_right(tmp)`` on a scratch body and copy its R and L realizations in."""
    tmp = Body("tmp", body.pos)
    add_right(tmp)
    for side in ("R", "L"):
        r = realize(tmp, side)
        body.geoms += r.geoms
        body.sites += r.sites


# ---------------------------------------------------------------------------------------
# The model
# ---------------------------------------------------------------------------------------


def hinge(name, cls, axis, lo, hi, home=0.0):
    return Joint(name, cls, tuple(float(a) for a in axis), (lo, hi), "hinge", home)


def slide(name, axis, lo, hi, home=0.0):
    return Joint(name, "face_slide", tuple(float(a) for a in axis), (lo, hi), "slide", home)


def spine_joints(stem, cls, flex, lat, rot):
    return [
        hinge(f"{stem}_flex", cls, (0, 1, 0), *flex),
        hinge(f"{stem}_lat", cls, (-1, 0, 0), *lat),
        hinge(f"{stem}_rot", cls, (0, 0, 1), *rot),
    ]


def col(**a):
    return dict(cls="collision", **a)


def shell(**a):
    """A collision geom that overlaps the body's massive geoms (hair, ears, lips, the
    deltoid...): it shapes the skin but adds no mass (density 0)."""
    return dict(cls="collision", density=0, **a)


def vis(material, **a):
    return dict(cls="visual", material=material, **a)


def ellipsoid(e, cls_attrs):
    c, r = e
    return dict(type="ellipsoid", pos=c, size=r, **cls_attrs)


def build_pelvis() -> Body:
    pelvis = Body("pelvis", PELVIS, comment="root: fixed at the world origin (hip-joint height)")
    pelvis.geom(**ellipsoid(HIPS, col()))
    pelvis.geom(**ellipsoid(HIPS, vis("trousers")))
    pelvis.geom(
        type="cylinder", fromto=[-0.02, 0, 0.085, -0.02, 0, 0.115], size=[0.113], **vis("belt")
    )

    def legs(b):  # visual only: the model is articulated from the pelvis up
        b.geom(
            type="capsule",
            fromto=[-0.015, -0.085, -0.02, 0.0, -0.095, -0.47],
            size=[0.072],
            **vis("trousers"),
        )
        b.geom(
            type="capsule",
            fromto=[0.0, -0.095, -0.47, -0.02, -0.10, -0.86],
            size=[0.052],
            **vis("trousers"),
        )
        b.geom(type="box", pos=[0.03, -0.10, -0.915], size=[0.125, 0.045, 0.035], **vis("shoe"))

    both_sides(legs, pelvis)
    # abdomen below the navel
    pelvis.site("ABST", front(HIPS, 0.0, 0.075))

    def sites(b):
        b.site("ABST_{X}", front(HIPS, -0.07, 0.075))
        # the side of the hips, under the belt, where a hand rests on the hip
        b.site("HIP_{X}", surface(HIPS, [0.2, -1.0, 0.35]))

    both_sides(sites, pelvis)
    return pelvis


def build_spine(pelvis: Body) -> tuple[Body, Body]:
    b1 = pelvis.add(Body("back_1", BACK_1, comment="lumbar spine and abdomen"))
    b1.joints = spine_joints("back_1", "spine", (-15, 30), (-15, 15), (-18, 18))
    b1.geom(**ellipsoid(ABDOMEN, col()))
    b1.geom(**ellipsoid(ABDOMEN, vis("shirt")))
    b1.geom(
        type="ellipsoid", pos=[-0.013, 0, 0.275], size=[0.096, 0.126, 0.085], **vis("shirt")
    )  # fmt: skip  (waist, blending abdomen and chest)
    b1.site("AB", front(ABDOMEN, 0.0, 0.20))

    def ab(b):
        b.site("AB_{X}", front(ABDOMEN, -0.07, 0.20))

    both_sides(ab, b1)

    b2 = b1.add(Body("back_2", BACK_2, comment="thorax"))
    b2.joints = spine_joints("back_2", "spine", (-15, 30), (-15, 15), (-18, 18))
    b2.geom(**ellipsoid(CHEST, col()))
    b2.geom(**ellipsoid(CHEST, vis("shirt")))
    b2.geom(
        type="capsule", fromto=[-0.04, 0, 0.50, -0.04, 0, 0.53], size=[0.05], **vis("shirt")
    )  # fmt: skip  (collar at the back of the neck)
    b2.site("ST", front(CHEST, 0.0, 0.40))

    def st(b):
        b.site("ST_{X}", front(CHEST, -0.07, 0.40))

    both_sides(st, b2)
    # signing-space loci, carried by the chest so that they follow a leaning torso
    b2.site("ssp", [0.32, 0.0, 0.33])
    b2.site("Rssp", [0.32, -0.20, 0.33])
    b2.site("Lssp", [0.32, 0.20, 0.33])
    return b1, b2


def build_neck_head(b2: Body) -> Body:
    neck = b2.add(Body("neck", NECK, comment="cervical spine"))
    neck.joints = spine_joints("neck", "neck", (-40, 35), (-25, 25), (-45, 45))
    neck_ft = [-0.020, 0, 0.50, -0.022, 0, 0.585]
    neck.geom(type="capsule", fromto=neck_ft, size=[NECK_RAD], **col())
    neck.geom(type="capsule", fromto=neck_ft, size=[NECK_RAD + 0.001], **vis("skin"))
    nk_axis = np.array(neck_ft[:3]) + (0.555 - neck_ft[2]) / (neck_ft[5] - neck_ft[2]) * (
        np.array(neck_ft[3:]) - neck_ft[:3]
    )
    nk_fwd = unit(np.cross([0, 1, 0], np.subtract(neck_ft[3:], neck_ft[:3])))
    neck.geom(**ellipsoid(LARYNX, shell()))
    neck.geom(**ellipsoid((LARYNX[0], LARYNX[1] + 0.001), vis("skin")))
    neck.site("NK", front(LARYNX, 0.0, NK_Z))
    neck.site("NAPE", nk_axis - NECK_RAD * nk_fwd)  # the back of the neck, opposite NK

    def nk(b):
        b.site("NK_{X}", nk_axis + [0, -NECK_RAD, 0])

    both_sides(nk, neck)

    head = neck.add(Body("head", HEAD, comment="skull; the face articulators are its children"))
    head.joints = spine_joints("head", "neck", (-30, 25), (-20, 20), (-25, 25))
    head.geom(**ellipsoid(CRANIUM, col()))
    head.geom(**ellipsoid(FACE, col()))
    nose_ft = [0.086, 0, 0.690, 0.100, 0, 0.656]
    head.geom(type="capsule", fromto=nose_ft, size=[0.008], **col())
    head.geom(**ellipsoid(NOSE_BASE, shell()))
    head.geom(**ellipsoid(HAIR, shell()))
    head.geom(**ellipsoid(CRANIUM, vis("skin")))
    head.geom(**ellipsoid(FACE, vis("skin")))
    head.geom(type="capsule", fromto=nose_ft, size=[0.008], **vis("skin"))
    head.geom(**ellipsoid(NOSE_BASE, vis("skin")))
    # hair cap: a little larger than the cranium, shifted up and back
    head.geom(**ellipsoid(HAIR, vis("hair")))

    # every skin site lies on the collision surface (README.md, "Sites")
    head.site("HEAD", surface(HAIR, [0, 0, 1]))  # on the hair
    head.site("FH", front(CRANIUM, 0.0, 0.745))
    head.site("NO", np.array(nose_ft[3:]) + [0.008, 0, 0])  # front of the nose capsule's end
    head.site("NSP", front(FACE, 0.0, 0.637))
    # front of the upper lip, where it meets the lower one
    head.site("MO", [0.085, 0.0, 0.624] + 0.0032 * unit([1.0, 0, -0.6]))
    head.site("BEB", surface(HAIR, [-1, 0, 0]))  # on the hair

    def lateral(b):
        # ears
        b.geom(**ellipsoid(EAR_R_SHAPE, shell()))
        b.geom(**ellipsoid(EAR_R_SHAPE, vis("skin")))
        # the eyeball (under the lid): the eye bodies carry the visual eye, the head its
        # collision sphere (a sphere about the eye's centre does not change as it turns)
        b.geom(type="sphere", pos=EYE_R, size=[EYE_RAD], **shell())
        # the upper lip's skin for contacts (static); what shows moves with lip_up_X
        for ft in (
            [0.0740, -0.020, 0.6225, 0.0850, -0.003, 0.6250],
            [0.0850, -0.003, 0.6250, 0.0850, 0.0, 0.6240],
        ):
            b.geom(type="capsule", fromto=ft, size=[0.0032], **shell())
        for y, z, stem in ((-0.033, 0.714, "EB"), (-0.017, 0.712, "EBi"), (-0.050, 0.712, "EBe")):
            b.site(f"{stem}_{{X}}", front(CRANIUM, y, z))
        b.site("EYE_{X}", EYE_R + [EYE_RAD, 0, 0])
        b.site("TE_{X}", surface(CRANIUM, unit([0.55, -0.82, 0.12])))
        b.site("CK_{X}", front(FACE, -0.045, 0.648))
        # EAR on the front rim of the ear, by the tragus, where an index meets it coming from
        # the front and below (README.md, "Sites")
        b.site("EAR_{X}", surface_normal(EAR_R_SHAPE, EAR_R_NORMAL))
        b.site("LOBE_{X}", surface(EAR_R_SHAPE, [0.3, -0.5, -1.0]))
        b.site("MO_{X}", front(FACE, -0.0245, 0.6195))
        b.site("NO_{X}", surface(NOSE_BASE, [0.3, -1.0, -0.2]))

    both_sides(lateral, head)

    build_face(head)
    return neck


# ---------------------------------------------------------------------------------------
# The face rig: small bodies under the head and the jaw, moved only by morphs
# ---------------------------------------------------------------------------------------

#: Eyelids: skin spheres of radius LID_RAD whose centres sit LID_OFF from the eye's centre;
#: each covers the eyeball on its side of a margin LID_EDGE from its centre direction.
LID_OFF, LID_RAD = 0.0015, 0.01215
LID_EDGE = np.degrees(np.arccos((0.012**2 + LID_OFF**2 - LID_RAD**2) / (2 * 0.012 * LID_OFF)))
#: The open lids' margins [deg above the eye's axis]: the upper lid covers the top of the
#: iris (its rim is 27.8 deg from the axis), the lower lid is at its lower rim.
UPPER_MARGIN, LOWER_MARGIN = 26.0, -30.0
#: Lips at rest (world, right half): upper and lower lip capsules, the corner.
LIP_UP = (
    [0.0740, -0.020, 0.6225, 0.0850, -0.003, 0.6250],
    [0.0850, -0.003, 0.6250, 0.0850, 0.0, 0.6240],
)
LIP_LOW = (
    [0.0740, -0.020, 0.6160, 0.0840, -0.003, 0.6135],
    [0.0840, -0.003, 0.6135, 0.0840, 0.0, 0.6135],
)
CORNER_R = np.array([0.0745, -0.0235, 0.6190])
#: The face articulators' inertias: the upper lids, inner brows and mouth corners weigh
#: 1 g each, as the rig's first articulators did, the others next to nothing, so that the
#: head loads the neck as it did (the postures of the manual articulators stay the same).
FACE_INERTIA = {"mass": 1e-7, "diaginertia": [1e-12, 1e-12, 1e-12]}
FACE_INERTIA_1G = {"mass": 0.001, "diaginertia": [1e-7, 1e-7, 1e-7]}
#: The cheek: a skin sphere under the face's surface by the mouth, puffed out along CHEEK_OUT.
CHEEK_AT = front(FACE, -0.048, 0.630)
CHEEK_OUT = unit([0.45, -0.85, -0.2])


def _dir(deg: float) -> np.ndarray:
    """The unit vector ``deg`` degrees from +x toward +z (in the eye's sagittal plane)."""
    a = np.radians(deg)
    return np.array([np.cos(a), 0.0, np.sin(a)])


def rotate(v, axis, deg: float) -> np.ndarray:
    """``v`` turned ``deg`` degrees about the unit ``axis`` (Rodrigues)."""
    a, k = np.radians(deg), unit(axis)
    return v * np.cos(a) + np.cross(k, v) * np.sin(a) + k * np.dot(k, v) * (1 - np.cos(a))


def face_body(name, pos, joints, comment) -> Body:
    b = Body(name, np.asarray(pos, float), joints=joints, comment=comment)
    b.inertial = FACE_INERTIA_1G if name in ("lid_{X}", "brow_{X}", "mouth_{X}") else FACE_INERTIA
    return b


def at_centre(inertia: dict, pos) -> dict:
    """``inertia`` with its centre of mass at world ``pos``."""
    return {**inertia, "pos": np.asarray(pos, float)}


def build_eye() -> Body:
    eye = Body("eye_{X}", EYE_R, comment="eyeball; origin at its centre of rotation")
    # both eyes: + yaw looks left, + pitch looks down (conjugate gaze, axes not mirrored)
    eye.joints = [
        hinge("eye_{X}_yaw", "eye", (0, 0, 1), {"R": -46, "L": -47}, {"R": 47, "L": 46}),
        hinge("eye_{X}_pitch", "eye", (0, 1, 0), -32, 48),
    ]
    for j in eye.joints:
        j.mirror = False
    eye.inertial = {"mass": 0.0075, "diaginertia": [4.3e-7, 4.3e-7, 4.3e-7]}
    eye.geom(type="sphere", pos=EYE_R, size=[0.012], **vis("sclera"))
    # iris and pupil: flat ellipsoids that follow the eyeball's curve (0.15 mm proud at most)
    eye.geom(
        type="ellipsoid", pos=EYE_R + [0.0100, 0, 0], size=[0.0021, 0.0056, 0.0056], **vis("iris")
    )
    eye.geom(
        type="ellipsoid", pos=EYE_R + [0.0106, 0, 0], size=[0.0016, 0.0025, 0.0025], **vis("pupil")
    )
    return eye


def build_lids() -> list[Body]:
    """Upper and lower eyelids: hinges through the eye's centre (+ closes each)."""
    up = face_body(
        "lid_{X}",
        EYE_R,
        [hinge("lid_{X}_close", "face_hinge", (0, 1, 0), -25, 75)],
        "upper eyelid; hinge through the eye's centre",
    )
    up.geom(
        type="sphere",
        pos=EYE_R + LID_OFF * _dir(UPPER_MARGIN + LID_EDGE),
        size=[LID_RAD],
        **vis("skin"),
    )
    # the lash line along the upper lid's margin, 0.4 mm out of the eyeball
    axis = _dir(UPPER_MARGIN + LID_EDGE)
    edge = [0.0124 * rotate(_dir(UPPER_MARGIN), axis, a) for a in (-55.0, -20.0, 20.0, 55.0)]
    for a, b in itertools.pairwise(edge):
        up.geom(type="capsule", fromto=np.r_[EYE_R + a, EYE_R + b], size=[0.0006], **vis("brow"))
    low = face_body(
        "lid_low_{X}",
        EYE_R,
        [hinge("lid_low_{X}_raise", "face_hinge", (0, -1, 0), -10, 40)],
        "lower eyelid; hinge through the eye's centre",
    )
    low.geom(
        type="sphere",
        pos=EYE_R + LID_OFF * _dir(LOWER_MARGIN - LID_EDGE),
        size=[LID_RAD],
        **vis("skin"),
    )
    return [up, low]


def build_brows() -> list[Body]:
    """Each brow in two parts hinged where they meet: the inner part raises, knits and
    tilts (its inner end up), the outer part raises and tilts (its outer end up)."""
    pts = [
        front(CRANIUM, y, z) + [0.0025, 0, 0]
        for y, z in ((-0.014, 0.7105), (-0.033, 0.7145), (-0.052, 0.7115))
    ]
    inner = face_body(
        "brow_{X}",
        pts[1],
        [
            slide("brow_{X}_raise", (0, 0, 1), -0.006, 0.012),
            slide("brow_{X}_knit", (0, 1, 0), 0.0, 0.008),
            hinge("brow_{X}_tilt", "face_hinge", (1, 0, 0), -25, 35),
        ],
        "inner eyebrow: raise (+z), knit (toward the midline), tilt (inner end up)",
    )
    # (3 mm past the joint: the two parts still overlap when the inner one knits)
    past = pts[1] + 0.003 * unit(pts[1] - pts[0])
    inner.geom(type="capsule", fromto=np.r_[pts[0], past], size=[0.0032], **vis("brow"))
    # the brow's mass where the one-piece brow had its centre
    inner.inertial = at_centre(FACE_INERTIA_1G, front(CRANIUM, -0.033, 0.714))
    outer = face_body(
        "brow_out_{X}",
        pts[1],
        [
            slide("brow_out_{X}_raise", (0, 0, 1), -0.006, 0.012),
            hinge("brow_out_{X}_tilt", "face_hinge", (-1, 0, 0), -25, 35),
        ],
        "outer eyebrow: raise (+z), tilt (outer end up)",
    )
    outer.geom(type="capsule", fromto=np.r_[pts[1], pts[2]], size=[0.0028], **vis("brow"))
    return [inner, outer]


def build_cheek_nose() -> list[Body]:
    cheek = face_body(
        "cheek_{X}",
        CHEEK_AT,
        [
            slide("cheek_{X}_puff", CHEEK_OUT, 0.0, 0.010),
            slide("cheek_{X}_raise", (0, 0, 1), -0.005, 0.006),
        ],
        "cheek: puff (out of the face) and raise (a squint, a smile)",
    )
    normal = unit((CHEEK_AT - FACE[0]) / FACE[1] ** 2)
    cheek.geom(type="sphere", pos=CHEEK_AT - 0.023 * normal, size=[0.022], **vis("skin"))
    wing = surface(NOSE_BASE, [0.3, -1.0, -0.2])
    nose = face_body(
        "nose_{X}",
        wing,
        [slide("nose_{X}_sneer", (0, 0, 1), 0.0, 0.005)],
        "nostril wing: raised by a sneer",
    )
    nose.geom(
        type="ellipsoid",
        pos=wing + [-0.002, 0.0025, 0.0005],
        size=[0.0055, 0.0040, 0.0045],
        **vis("skin"),
    )
    return [cheek, nose]


def lip_joints(stem: str, vertical: str, up: float) -> list[Joint]:
    """A lip half's slides: ``vertical`` (+z for the upper lip's raise, -z for the lower's
    down), ``out`` (forward), ``in`` (toward the midline); and ``tilt``, a hinge at the
    midline that lifts the half's outer end (a smile's curve)."""
    return [
        slide(f"{stem}_{vertical}", (0, 0, up), -0.004, 0.008),
        slide(f"{stem}_out", (1, 0, 0), -0.006, 0.008),
        slide(f"{stem}_in", (0, 1, 0), -0.007, 0.008),
        hinge(f"{stem}_tilt", "face_hinge", (-1, 0, 0), -20, 25),
    ]


def build_lips() -> list[Body]:
    """The upper lip's halves and the mouth corners (on the head)."""
    lip = face_body(
        "lip_up_{X}",
        LIP_UP[1][3:],
        lip_joints("lip_up_{X}", "raise", 1),
        "upper lip, one half; origin on the midline",
    )
    for ft in LIP_UP:
        lip.geom(type="capsule", fromto=ft, size=[0.0045], **vis("lips"))
    corner = face_body(
        "mouth_{X}",
        CORNER_R,
        [
            slide("mouth_{X}_up", (0, 0, 1), -0.008, 0.008),
            slide("mouth_{X}_out", (0, -1, 0), -0.012, 0.010),
            slide("mouth_{X}_fwd", (1, 0, 0), -0.006, 0.008),
        ],
        "mouth corner: up, out (away from the midline), forward",
    )
    corner.geom(type="sphere", pos=CORNER_R + [-0.0015, 0, 0], size=[0.0036], **vis("lips"))
    return [lip, corner]


def build_jaw(head: Body) -> Body:
    jaw = head.add(Body("jaw", JAW, comment="lower jaw; hinge at the temporo-mandibular joints"))
    jaw.joints = [
        hinge("jaw_open", "face_hinge", (0, 1, 0), -2, 30),
        slide("jaw_fwd", (1, 0, 0), -0.002, 0.006),
        slide("jaw_lat", (0, 1, 0), -0.006, 0.006),
    ]
    jaw.geom(**ellipsoid(CHIN, col()))
    jaw.geom(**ellipsoid(CHIN, vis("skin")))
    # the jaw's sides and underside (visual): fills the lower face between chin and ears
    jaw.geom(type="ellipsoid", pos=[0.026, 0, 0.619], size=[0.050, 0.060, 0.028], **vis("skin"))
    # the inside of the mouth behind the lower lip (shows when the jaw opens)
    jaw.geom(type="ellipsoid", pos=[0.074, 0, 0.622], size=[0.009, 0.019, 0.010], **vis("mouth"))

    def jaw_lat(b):  # the lower lip's skin for contacts (what shows moves with lip_low_X)
        for ft in LIP_LOW:
            b.geom(type="capsule", fromto=ft, size=[0.0036], **shell())

    both_sides(jaw_lat, jaw)
    jaw.site("CH", surface(CHIN, unit([1.0, 0, -0.9])))
    jaw.site("TO", [0.082, 0.0, 0.618])
    lip = face_body(
        "lip_low_{X}",
        LIP_LOW[1][3:],
        lip_joints("lip_low_{X}", "down", -1),
        "lower lip, one half; origin on the midline",
    )
    for ft in LIP_LOW:
        lip.geom(type="capsule", fromto=ft, size=[0.0049], **vis("lips"))
    for side in ("L", "R"):
        jaw.add(realize(lip, side))
    tongue = jaw.add(
        face_body(
            "tongue",
            [0.048, 0.0, 0.619],
            [slide("tongue_out", (1, 0, 0), 0.0, 0.030)],
            "tongue: out between the lips",
        )
    )
    tongue.geom(
        type="ellipsoid", pos=[0.057, 0.0, 0.6185], size=[0.017, 0.013, 0.0055], **vis("tongue")
    )
    return jaw


def build_face(head: Body) -> None:
    """The jaw, eyes, lids, brows, cheeks, nostrils, lips and tongue under ``head``; the
    inside of the mouth (dark) on the head, behind the lips."""
    head.geom(type="ellipsoid", pos=[0.072, 0, 0.612], size=[0.0105, 0.019, 0.018], **vis("mouth"))
    # the face close-up: straight in front, the brows to the chin at 640 x 480
    head.cameras.append(("face", [0.62, 0.0, 0.672], [0.05, 0.0, 0.667], 20))
    build_jaw(head)
    templates = [build_eye(), *build_lids(), *build_brows(), *build_cheek_nose(), *build_lips()]
    for tmpl in templates:
        for side in ("L", "R"):
            head.add(realize(tmpl, side))


def build_finger(f: str, palm_origin: np.ndarray) -> Body:
    """A finger's three phalanges (right side, templated) hanging straight down."""
    lens, rads = PHALANX_LEN[f], PHALANX_RAD[f]
    letter = {"index": "I", "middle": "M", "ring": "R", "little": "L"}[f]
    spread_rng = {"index": (-15, 25), "middle": (-15, 15), "ring": (-20, 10), "little": (-30, 10)}[
        f
    ]
    origin = palm_origin + MCP[f]
    top = None
    parent = None
    home = {1: 0.20, 2: 0.25, 3: 0.15}
    for n in (1, 2, 3):
        b = Body(f"{f}_{{X}}_{n}", origin.copy())
        b.joints.append(
            hinge(
                f"{f}_{{X}}_{n}_flex",
                "finger",
                (1, 0, 0),
                *{1: (-30, 90), 2: (0, 100), 3: (0, 90)}[n],
                home=home[n],
            )
        )
        if n == 1:
            b.joints.append(hinge(f"{f}_{{X}}_1_spread", "finger", (0, -1, 0), *spread_rng))
        L, r = lens[n - 1], rads[n - 1]
        end = origin + L * DOWN
        # the distal capsule ends a radius short of the tip so the pad surface ends there
        tip_end = end - r * DOWN if n == 3 else end
        b.geom(type="capsule", fromto=np.r_[origin, tip_end], size=[r], **col())
        b.geom(type="capsule", fromto=np.r_[origin, tip_end], size=[r], **vis("skin"))
        mid = origin + 0.5 * L * DOWN
        b.site(f"{letter}_KN_{{X}}_{n}", origin - r * PALMAR_R)
        b.site(f"{letter}_KNi_{{X}}_{n}", origin + r * PALMAR_R)
        b.site(f"{letter}_BACK_{{X}}_{n}", mid - r * PALMAR_R)
        b.site(f"{letter}_INT_{{X}}_{n}", mid + r * PALMAR_R)
        if n == 3:
            pad = origin + 0.55 * L * DOWN
            b.geom(
                type="box",
                pos=pad - 0.62 * r * PALMAR_R,
                size=[0.72 * r, 0.45 * r, 0.36 * L],
                **vis("nail"),
            )
            b.site(f"{letter}_TIP_{{X}}", end)
            b.site(f"{letter}_PAD_{{X}}", pad + r * PALMAR_R)
            b.site(f"{letter}_NA_{{X}}", pad - r * PALMAR_R)
        if parent is None:
            top = b
        else:
            parent.add(b)
        parent = b
        origin = end
    return top


def build_thumb(palm_origin: np.ndarray) -> Body:
    origin = palm_origin + THUMB_CMC
    abd_axis = unit(np.cross(THUMB_D, [0, 1, 0]))  # palmar abduction: away from the palm
    flex_axis = unit(np.cross(THUMB_D, THUMB_N))  # curls the tip toward the pad
    top = parent = None
    home = {1: 0.0, 2: 0.10, 3: 0.10}
    for n in (1, 2, 3):
        b = Body(f"thumb_{{X}}_{n}", origin.copy())
        if n == 1:
            b.joints = [
                # CMC flexion: across the palm toward the little finger (about the palm normal)
                hinge("thumb_{X}_1_flex", "thumb", (0, 1, 0), -25, 35, home=0.05),
                hinge("thumb_{X}_1_abd", "thumb", abd_axis, 0, 70, home=0.10),
            ]
        else:
            b.joints = [
                hinge(
                    f"thumb_{{X}}_{n}_flex",
                    "thumb",
                    flex_axis,
                    *{2: (0, 60), 3: (-20, 80)}[n],
                    home=home[n],
                )
            ]
        L, r = THUMB_LEN[n - 1], THUMB_RAD[n - 1]
        end = origin + L * THUMB_D
        tip_end = end - r * THUMB_D if n == 3 else end
        b.geom(type="capsule", fromto=np.r_[origin, tip_end], size=[r], **col())
        b.geom(type="capsule", fromto=np.r_[origin, tip_end], size=[r], **vis("skin"))
        mid = origin + 0.5 * L * THUMB_D
        b.site(f"T_KN_{{X}}_{n}", origin - r * THUMB_N)
        b.site(f"T_KNi_{{X}}_{n}", origin + r * THUMB_N)
        b.site(f"T_BACK_{{X}}_{n}", mid - r * THUMB_N)
        b.site(f"T_INT_{{X}}_{n}", mid + r * THUMB_N)
        if n == 3:
            pad = origin + 0.55 * L * THUMB_D
            side_ax = unit(np.cross(THUMB_D, THUMB_N))
            # nail: a thin box aligned with the thumb (zaxis = -NRM, x along the width)
            b.geom(
                type="ellipsoid",
                pos=pad - 0.62 * r * THUMB_N,
                size=[0.74 * r, 0.38 * L, 0.45 * r],
                xyaxes=np.r_[side_ax, THUMB_D],
                **vis("nail"),
            )
            b.site("T_TIP_{X}", end)
            b.site("T_PAD_{X}", pad + r * THUMB_N)
            b.site("T_NA_{X}", pad - r * THUMB_N)
        if parent is None:
            top = b
        else:
            parent.add(b)
        parent = b
        origin = end
    return top


def build_arm() -> Body:
    """The right shoulder girdle, arm and hand, templated with ``{X}``."""
    clav = Body("clav_{X}", CLAV_R, comment="clavicle: sternoclavicular joint")
    clav.joints = [
        hinge("clav_{X}_elev", "girdle", (-1, 0, 0), -10, 40),
        hinge("clav_{X}_prot", "girdle", (0, 0, 1), -25, 25),
    ]
    clav_end = np.array([-0.002, -0.150, 0.492])
    clav.geom(type="capsule", fromto=np.r_[CLAV_R, clav_end], size=[0.018], **col())
    # shoulder slope (trapezius) under the shirt; a sphere inscribed in its outer end (over
    # the acromion, clear of the neck at any elevation) collides, and SH is on its top
    trap = np.array([-0.028, -0.035, 0.515, -0.008, -0.150, 0.495])
    clav.geom(type="capsule", fromto=trap, size=[0.032], **vis("shirt"))
    axis = unit(trap[3:] - trap[:3])
    acromion = trap[:3] + (0.140 - 0.035) / (0.150 - 0.035) * (trap[3:] - trap[:3])
    clav.geom(type="sphere", pos=acromion, size=[0.032], **shell())
    # SH on the front of the cap, where a hand pats a shoulder: its normal turned 65 degrees
    # forward from the cap's top (24 degrees above the horizontal), so that a fingertip
    # meets it coming from the front and above with the elbow low (README.md, "Sites")
    up = np.array([0.0, 0.0, 1.0])
    cap_top = unit(up - np.dot(up, axis) * axis)
    turn = np.radians(65.0)
    sh_normal = unit(np.cos(turn) * cap_top + np.sin(turn) * np.array([1.0, 0.0, 0.0]))
    clav.site("SH_{X}", acromion + 0.032 * sh_normal)

    arm = clav.add(Body("arm_{X}", ARM_R, comment="upper arm: shoulder joint centre"))
    arm.joints = [
        hinge("arm_{X}_flex", "shoulder", (0, -1, 0), -60, 180),
        hinge("arm_{X}_abd", "shoulder", (-1, 0, 0), -45, 180, home=0.14),
        hinge("arm_{X}_rot", "shoulder", (0, 0, 1), -90, 70),
    ]
    arm_ft = np.r_[ARM_R + [0, 0, -0.005], ELBOW_R + [0, 0, 0.030]]
    arm.geom(type="capsule", fromto=arm_ft, size=[0.040], **col())
    arm.geom(type="capsule", fromto=arm_ft, size=[0.041], **vis("shirt"))
    # the deltoid's roundness over the shoulder joint (collision: ARMsh is on it)
    deltoid = ARM_R + [-0.002, -0.004, 0.002]
    arm.geom(type="sphere", pos=deltoid, size=[0.045], **shell())
    arm.geom(type="sphere", pos=deltoid, size=[0.046], **vis("shirt"))
    arm.site("ARMsh_{X}", deltoid + 0.045 * unit([0.0, -0.25, 1.0]))
    arm.site("ARM_{X}", ARM_R + [0.0, -0.040, -0.15])
    arm.site("ARMpit_{X}", ARM_R + [0.0, 0.040, -0.060])
    # front of the elbow, on the end of the upper arm's capsule (its axis ends 30 mm above)
    arm.site("ELi_{X}", ELBOW_R + [0, 0, 0.030] + 0.040 * unit([1.0, 0, -0.26]))

    farm = arm.add(Body("f_arm_{X}", ELBOW_R, comment="forearm: elbow joint centre"))
    farm.joints = [
        hinge("f_arm_{X}_flex", "elbow", (0, -1, 0), 0, 150, home=0.15),
        hinge("f_arm_{X}_pron", "elbow", (0, 0, 1), -80, 80, home=0.10),
    ]
    fa1 = np.r_[ELBOW_R + [0, 0, -0.015], ELBOW_R + [0, 0, -0.140]]
    fa2 = np.r_[ELBOW_R + [0, 0, -0.120], WRIST_R + [0, 0, 0.026]]
    farm.geom(type="capsule", fromto=fa1, size=[0.030], **col())
    farm.geom(type="capsule", fromto=fa2, size=[0.025], **col())
    farm.geom(type="capsule", fromto=fa1, size=[0.031], **vis("shirt"))
    farm.geom(type="capsule", fromto=fa2, size=[0.026], **vis("shirt"))
    farm.geom(
        type="cylinder",
        fromto=np.r_[WRIST_R + [0, 0, 0.028], WRIST_R + [0, 0, 0.04]],
        size=[0.0272],
        **vis("cuff"),
    )
    # olecranon: a sphere on the forearm, posterior to the elbow centre; EL is its proximal
    # apex, the elbow's lowest point with the forearm vertical (an elbow resting on a hand);
    # with the arm straight it sits in the upper arm's end, as in the olecranon fossa
    olecranon = ELBOW_R + [-0.022, 0.0, 0.006]
    farm.geom(type="sphere", pos=olecranon, size=[0.016], **shell())
    farm.geom(type="sphere", pos=olecranon, size=[0.017], **vis("shirt"))
    farm.site("EL_{X}", olecranon + [0.0, 0.0, 0.016])
    farm.site("F_ARM_{X}", ELBOW_R + [0.0, -0.030, -0.11])
    farm.site("F_ARMi_{X}", ELBOW_R + [0.0, 0.030, -0.11])
    farm.site("WR_{X}", WRIST_R)
    # back of the wrist and pulse side: where a watch sits, on the forearm capsule's end
    farm.site("WRt_{X}", WRIST_R + [0.0, 0.0, 0.026] + 0.025 * unit([0.0, -1.0, 0.0]))
    farm.site("WRi_{X}", WRIST_R + [0.0, 0.0, 0.026] + 0.025 * unit([0.18, 1.0, 0.0]))

    palm = farm.add(Body("palm_{X}", WRIST_R, comment="hand: wrist joint centre"))
    palm.joints = [
        hinge("palm_{X}_flex", "wrist", (1, 0, 0), -70, 80, home=0.05),
        hinge("palm_{X}_dev", "wrist", (0, -1, 0), -30, 20),
    ]
    x_lo = MCP["little"][0] - PHALANX_RAD["little"][0] - 0.0005
    x_hi = MCP["index"][0] + PHALANX_RAD["index"][0] + 0.0005
    z_lo, z_hi = -(PALM_LEN - 0.004), 0.002
    box_pos = WRIST_R + [(x_lo + x_hi) / 2, 0, (z_lo + z_hi) / 2]
    box_size = [(x_hi - x_lo) / 2, PALM_HALF_THICK, (z_hi - z_lo) / 2]
    palm.geom(type="box", pos=box_pos, size=box_size, **col())
    palm.geom(type="box", pos=box_pos, size=box_size, **vis("skin"))
    # wrist, thenar and hypothenar eminences (visual)
    # (no deeper than the palm's box: the palm's face is flat, so that it can lie on a palm,
    # the back of a hand, the chest or a cheek)
    palm.geom(
        type="ellipsoid",
        pos=WRIST_R + [0.0, 0.0, 0.002],
        size=[0.027, PALM_HALF_THICK, 0.016],
        **vis("skin"),
    )
    palm.geom(
        type="ellipsoid",
        pos=WRIST_R + [0.020, 0.001, -0.036],
        size=[0.016, PALM_HALF_THICK - 0.001, 0.026],
        **vis("skin"),
    )
    palm.geom(
        type="ellipsoid",
        pos=WRIST_R + [-0.030, 0.002, -0.040],
        size=[0.012, PALM_HALF_THICK - 0.002, 0.026],
        **vis("skin"),
    )
    zc = -0.045
    palm.site("PA_{X}", WRIST_R + [0.0, PALM_HALF_THICK, zc])
    palm.site("H_BACK_{X}", WRIST_R + [0.0, -PALM_HALF_THICK, zc])
    palm.site("H_EDGE_{X}", WRIST_R + [x_lo, 0.0, -0.050])
    palm.site("viande_{X}", WRIST_R + [0.020, PALM_HALF_THICK, -0.034])

    palm.add(build_thumb(WRIST_R))
    for f in ("index", "middle", "ring", "little"):
        palm.add(build_finger(f, WRIST_R))
    return clav


def build_model() -> Body:
    pelvis = build_pelvis()
    _, b2 = build_spine(pelvis)
    build_neck_head(b2)
    arm = build_arm()
    for side in ("L", "R"):
        b2.add(realize(arm, side))
    return pelvis


# ---------------------------------------------------------------------------------------
# MJCF writing
# ---------------------------------------------------------------------------------------

MATERIALS = {
    "skin": "0.87 0.68 0.56 1",
    "shirt": "0.16 0.22 0.36 1",
    "cuff": "0.12 0.16 0.27 1",
    "trousers": "0.22 0.22 0.24 1",
    "belt": "0.10 0.08 0.07 1",
    "shoe": "0.12 0.10 0.09 1",
    "hair": "0.20 0.13 0.08 1",
    "brow": "0.17 0.11 0.07 1",
    "sclera": "0.96 0.96 0.94 1",
    "iris": "0.30 0.20 0.10 1",
    "pupil": "0.03 0.03 0.03 1",
    "lips": "0.75 0.38 0.38 1",
    "mouth": "0.16 0.04 0.05 1",
    "tongue": "0.80 0.40 0.42 1",
    "nail": "0.95 0.80 0.76 1",
}

#: Joint classes: damping [N m s/rad or N s/m] and armature [kg m^2 or kg].
JOINT_CLASSES = {
    "spine": {"damping": "8", "armature": "0.1"},
    "neck": {"damping": "2", "armature": "0.03"},
    "girdle": {"damping": "3", "armature": "0.05"},
    "shoulder": {"damping": "2", "armature": "0.05"},
    "elbow": {"damping": "1", "armature": "0.02"},
    "wrist": {"damping": "0.3", "armature": "0.005"},
    "finger": {"damping": "0.03", "armature": "0.0005"},
    "thumb": {"damping": "0.03", "armature": "0.0005"},
    "eye": {"damping": "0.005", "armature": "0.0001"},
    "face_hinge": {"damping": "0.005", "armature": "0.0001"},
    "face_slide": {"type": "slide", "damping": "0.5", "armature": "0.02"},
}

#: Pairs of bodies whose contacts are excluded (besides parent-child, see README.md).
EXCLUDES = [
    ("pelvis", "back_1", "parent and child; MuJoCo does not filter a world-welded parent"),
    ("neck", "jaw", "two steps apart; the jaw sits over the top of the neck capsule"),
]


def fmt(x) -> str:
    if isinstance(x, str):
        return x
    arr = np.atleast_1d(np.asarray(x, float))
    out = []
    for v in arr:
        if v != 0 and abs(v) < 1e-3:
            s = f"{v:.3g}"
        else:
            s = f"{v:.6f}".rstrip("0").rstrip(".")
        out.append("0" if s in ("-0", "") else s)
    return " ".join(out)


def write_body(parent_el, body: Body, parent_pos) -> None:
    if body.comment:
        parent_el.append(ET.Comment(f" {body.name}: {body.comment} "))
    attrs = {"name": body.name, "pos": fmt(body.pos - parent_pos)}
    if body.joints:  # the fixed pelvis needs none
        attrs["gravcomp"] = "1"
    el = ET.SubElement(parent_el, "body", attrs)
    if body.inertial:
        ET.SubElement(
            el,
            "inertial",
            pos=fmt(np.asarray(body.inertial.get("pos", body.pos)) - body.pos),
            mass=fmt(body.inertial["mass"]),
            diaginertia=fmt(body.inertial["diaginertia"]),
        )
    for j in body.joints:
        ja = {"name": j.name, "class": j.cls, "axis": fmt(j.axis), "range": fmt(j.range)}
        ET.SubElement(el, "joint", ja)
    for g in body.geoms:
        a = dict(g.attrs)
        ga = {"class": a.pop("cls")}
        if "material" in a:
            ga["material"] = a.pop("material")
        ga["type"] = a.pop("type")
        if "pos" in a:
            ga["pos"] = fmt(np.asarray(a.pop("pos")) - body.pos)
        if "fromto" in a:
            ft = np.asarray(a.pop("fromto"), float)
            ga["fromto"] = fmt(np.r_[ft[:3] - body.pos, ft[3:] - body.pos])
        for k, v in a.items():
            ga[k] = fmt(v)
        ET.SubElement(el, "geom", ga)
    for s in body.sites:
        ET.SubElement(el, "site", name=s.name, pos=fmt(s.pos - body.pos))
    for name, pos, target, fovy in body.cameras:
        # "track": follows the body's position, keeps its world orientation (a head that
        # nods or turns is seen doing it)
        pos = np.asarray(pos, float)
        ET.SubElement(
            el,
            "camera",
            name=name,
            mode="track",
            pos=fmt(pos - body.pos),
            xyaxes=look_at(pos, target),
            fovy=fmt(fovy),
        )
    for c in body.children:
        write_body(el, c, body.pos)


def walk(body: Body):
    yield body
    for c in body.children:
        yield from walk(c)


def signer_xml(root: Body) -> ET.ElementTree:
    mj = ET.Element("mujoco", model="azee signer")
    ET.SubElement(mj, "compiler", angle="degree", autolimits="true")
    ET.SubElement(mj, "option", timestep="0.002", integrator="implicitfast")

    default = ET.SubElement(mj, "default")
    top = ET.SubElement(default, "default", {"class": "signer"})
    ET.SubElement(top, "joint", type="hinge", limited="true", damping="1", armature="0.01")
    ET.SubElement(
        top,
        "geom",
        density="1050",
        friction="0.8 0.02 0.001",
        solref="0.01 1",
        solimp="0.95 0.99 0.001",
    )
    ET.SubElement(top, "site", size="0.003", group="4", rgba="0.9 0.2 0.2 1")
    for cls, attrs in JOINT_CLASSES.items():
        d = ET.SubElement(top, "default", {"class": cls})
        ET.SubElement(d, "joint", attrs)
    d = ET.SubElement(top, "default", {"class": "visual"})
    ET.SubElement(d, "geom", contype="0", conaffinity="0", group="2", density="0")
    d = ET.SubElement(top, "default", {"class": "collision"})
    ET.SubElement(d, "geom", group="3", rgba="0.6 0.7 0.5 0.4")

    asset = ET.SubElement(mj, "asset")
    for name, rgba in MATERIALS.items():
        kw = {"name": name, "rgba": rgba}
        if name in ("skin", "lips"):
            kw.update(specular="0.15", shininess="0.3")
        elif name in ("sclera", "nail", "pupil"):
            kw.update(specular="0.5", shininess="0.8")
        else:
            kw.update(specular="0.05", shininess="0.1")
        ET.SubElement(asset, "material", kw)

    wb = ET.SubElement(mj, "worldbody")
    holder = ET.SubElement(wb, "frame", childclass="signer")
    write_body(holder, root, np.zeros(3))

    contact = ET.SubElement(mj, "contact")
    for b1, b2, why in EXCLUDES:
        contact.append(ET.Comment(f" {why} "))
        ET.SubElement(contact, "exclude", body1=b1, body2=b2)

    joints = [j for b in walk(root) for j in b.joints]
    kf = ET.SubElement(mj, "keyframe")
    kf.append(ET.Comment(" relaxed: arms slightly abducted, elbows and fingers a little bent "))
    ET.SubElement(kf, "key", name="home", qpos=fmt([j.home for j in joints]))
    return ET.ElementTree(mj)


def look_at(pos, target, up=(0, 0, 1)) -> str:
    f = unit(np.subtract(target, pos))
    x = unit(np.cross(f, up))
    y = np.cross(x, f)
    return fmt(np.r_[x, y])


def scene_xml() -> ET.ElementTree:
    mj = ET.Element("mujoco", model="azee signer scene")
    ET.SubElement(mj, "include", file="signer.xml")
    ET.SubElement(mj, "statistic", center="0 0 0.4", extent="1.0")
    visual = ET.SubElement(mj, "visual")
    ET.SubElement(
        visual, "headlight", diffuse="0.5 0.5 0.5", ambient="0.35 0.35 0.35", specular="0 0 0"
    )
    ET.SubElement(visual, "rgba", haze="0.15 0.25 0.35 1")
    ET.SubElement(
        visual, "global", azimuth="150", elevation="-15", offwidth="1280", offheight="960"
    )
    asset = ET.SubElement(mj, "asset")
    ET.SubElement(
        asset,
        "texture",
        type="skybox",
        builtin="gradient",
        rgb1="0.55 0.65 0.75",
        rgb2="0.2 0.25 0.3",
        width="512",
        height="3072",
    )
    ET.SubElement(
        asset,
        "texture",
        type="2d",
        name="groundplane",
        builtin="checker",
        mark="edge",
        rgb1="0.45 0.47 0.5",
        rgb2="0.4 0.42 0.45",
        markrgb="0.6 0.6 0.6",
        width="300",
        height="300",
    )
    ET.SubElement(
        asset,
        "material",
        name="groundplane",
        texture="groundplane",
        texuniform="true",
        texrepeat="4 4",
        reflectance="0.1",
    )
    wb = ET.SubElement(mj, "worldbody")
    ET.SubElement(
        wb,
        "light",
        name="key",
        pos="1.5 -1.0 2.2",
        dir=fmt(unit([-1.5, 1.0, -1.8])),
        directional="true",
        diffuse="0.55 0.55 0.55",
    )
    ET.SubElement(
        wb,
        "light",
        name="fill",
        pos="1.2 1.5 1.2",
        dir=fmt(unit([-1.2, -1.5, -0.8])),
        directional="true",
        diffuse="0.25 0.25 0.25",
        castshadow="false",
    )
    ET.SubElement(
        wb,
        "geom",
        name="floor",
        type="plane",
        pos="0 0 -0.95",
        size="0 0 0.05",
        material="groundplane",
        contype="1",
        conaffinity="1",
    )
    target = (0.0, 0.0, 0.30)  # frames the signing space: head to the hands at rest
    cams = {
        "front": ((2.0, 0.0, 0.45), target, (0, 0, 1)),
        "side": ((0.0, -2.0, 0.45), target, (0, 0, 1)),
        "three-quarter": ((1.55, -1.25, 0.65), target, (0, 0, 1)),
        "top": ((0.35, 0.0, 2.10), (0.05, 0.0, 0.35), (1, 0, 0)),
    }
    for name, (pos, tgt, up) in cams.items():
        ET.SubElement(
            wb, "camera", name=name, pos=fmt(pos), xyaxes=look_at(pos, tgt, up), fovy="40"
        )
    return ET.ElementTree(mj)


HEADER = (
    "\n  Generated by tools/build_signer.py; do not edit by hand.\n"
    "  The AZee signer: an adult of stature 1.70 m from the pelvis up, facing +x, +y to the\n"
    "  signer's left, +z up; root body 'pelvis' fixed at the world origin (hip-joint height).\n"
    "  Every body frame is aligned with the world at qpos0. See README.md.\n"
)


def write(tree: ET.ElementTree, path: Path, header: str) -> None:
    ET.indent(tree, space="  ")
    text = ET.tostring(tree.getroot(), encoding="unicode").replace(" />", "/>")
    path.write_text(f"<!--{header}-->\n{text}\n")


def check_skin(path: Path) -> list[str]:
    """Problems with the catalogue's surface sites on the written model: each must lie on
    its body's collision surface (within 0.01 mm) with the catalogue's outward normal
    (within 0.1 degree). Prints the normals table of ``azee_mj/sites.py`` when they differ."""
    import mujoco

    from azee_mj.sites import DEFAULT_MAP
    from azee_mj.surface import skin_distance

    m = mujoco.MjModel.from_xml_path(str(path))
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    problems, table = [], []
    for name, normal in DEFAULT_MAP.normals.items():
        s = m.site(DEFAULT_MAP.sites[name])
        dist, n, _ = skin_distance(m, d, s.bodyid[0], d.site_xpos[s.id])
        local = d.xmat[s.bodyid[0]].reshape(3, 3).T @ n
        if abs(dist) > 1e-5:
            problems.append(f"{name}: {dist * 1000:.3f} mm off its body's collision surface")
        if np.degrees(np.arccos(np.clip(local @ normal, -1, 1))) > 0.1:
            problems.append(f"{name}: catalogue normal {normal}, surface normal {local.round(4)}")
        if name.endswith("_R") or "_" not in name:
            table.append(f'    "{name}": {tuple(round(float(x), 4) for x in local)},')
    if any("normal" in p for p in problems):
        print("surface normals (sites.py _NORMALS, lateral sites written with {X}):")
        print("\n".join(table))
    return problems


def main() -> None:
    root = build_model()
    write(signer_xml(root), OUT_DIR / "signer.xml", HEADER)
    write(
        scene_xml(),
        OUT_DIR / "scene.xml",
        "\n  Generated by tools/build_signer.py: the signer on a floor, lights, cameras.\n",
    )
    print(f"wrote {OUT_DIR / 'signer.xml'} and {OUT_DIR / 'scene.xml'}")
    problems = check_skin(OUT_DIR / "signer.xml")
    if problems:
        sys.exit("surface sites:\n  " + "\n  ".join(problems))


if __name__ == "__main__":
    main()
