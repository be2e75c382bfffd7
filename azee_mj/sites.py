"""The AZee vocabulary (sites, bones, loci, morphs) and its map onto an MJCF signer.

AZee speaks of an abstract skeleton (44 bones, each with a DIR and an NRM axis) and named
body points (sites). A :class:`SignerMap` says which model body carries each bone, which
model site is each AZee site, and which joint changes each morph makes. The bundled signer's
map is :data:`DEFAULT_MAP`; another MJCF signer is used by building a ``SignerMap`` for it
(see ``docs/retargeting.md``).

Vectors are unit vectors in the body frame; joint changes are in radians (hinges) or metres
(slides).
"""

from __future__ import annotations

import dataclasses
import difflib
from collections.abc import Mapping
from types import MappingProxyType

import numpy as np

from azee_mj import arkit

SIDES = ("L", "R")

#: Digit letters used in site names, and the bone stem of each digit.
DIGITS = {"T": "thumb", "I": "index", "M": "middle", "R": "ring", "L": "little"}
FINGERS = ("index", "middle", "ring", "little")

#: Sites on the midline: the AZee name is the stem itself.
MIDLINE_STEMS = (
    "HEAD",
    "FH",
    "NO",
    "NSP",
    "MO",
    "TO",
    "CH",
    "BEB",
    "NK",
    "NAPE",
    "ST",
    "AB",
    "ABST",
)
#: Lateral stems: the AZee name is ``STEM_L`` / ``STEM_R``.
LATERAL_STEMS = (
    "EB",
    "EBi",
    "EBe",
    "EYE",
    "TE",
    "CK",
    "EAR",
    "LOBE",
    "MO",
    "NO",
    "NK",
    "ST",
    "AB",
    "ABST",
    "HIP",
    "SH",
    "ARMpit",
    "ARM",
    "ARMsh",
    "EL",
    "ELi",
    "F_ARM",
    "F_ARMi",
    "WR",
    "WRt",
    "WRi",
    "PA",
    "H_BACK",
    "H_EDGE",
    "viande",
)
#: Per-digit stems: ``X_STEM_side`` (e.g. ``I_TIP_R``).
DIGIT_STEMS = ("TIP", "PAD", "NA")
#: Per-phalanx stems: ``X_STEM_side_n`` (e.g. ``L_KN_L_1``), n = 1 proximal .. 3 distal.
PHALANX_STEMS = ("KN", "KNi", "BACK", "INT")
PHALANGES = (1, 2, 3)
#: Signing-space loci (scores write ``^ssp``).
LOCI = ("ssp", "Rssp", "Lssp")
#: The face rig's joints (the ``face`` track: moved by morphs only, never by the solver for
#: a placement).
FACE_JOINTS = (
    ("jaw_open", "jaw_fwd", "jaw_lat")
    + tuple(
        f"{stem}_{s}_{m}"
        for stem, motions in (
            ("lip_low", ("down", "out", "in", "tilt")),
            ("lid", ("close",)),
            ("lid_low", ("raise",)),
            ("brow", ("raise", "knit", "tilt")),
            ("brow_out", ("raise", "tilt")),
            ("cheek", ("puff", "raise")),
            ("nose", ("sneer",)),
            ("lip_up", ("raise", "out", "in", "tilt")),
            ("mouth", ("up", "out", "fwd")),
        )
        for s in SIDES
        for m in motions
    )
    + ("tongue_out",)
)


def azee_site_names() -> tuple[str, ...]:
    """Every AZee site name of the catalogue, midline first, then lateral, then digits."""
    names = list(MIDLINE_STEMS)
    for side in SIDES:
        names += [f"{stem}_{side}" for stem in LATERAL_STEMS]
    for side in SIDES:
        for d in DIGITS:
            names += [f"{d}_{stem}_{side}" for stem in DIGIT_STEMS]
            names += [f"{d}_{stem}_{side}_{n}" for stem in PHALANX_STEMS for n in PHALANGES]
    return tuple(names)


def azee_bone_names() -> tuple[str, ...]:
    """The 44 AZee bones: spine, head, eyes, then each side's arm and digits."""
    names = ["back_1", "back_2", "neck", "head", "eye_L", "eye_R"]
    for side in SIDES:
        names += [f"clav_{side}", f"arm_{side}", f"f_arm_{side}", f"palm_{side}"]
        names += [f"{d}_{side}_{n}" for d in DIGITS.values() for n in PHALANGES]
    return tuple(names)


def other_side(side: str) -> str:
    """``"R"`` for ``"L"`` and back."""
    return {"L": "R", "R": "L"}[side]


def resolve_side(side: str, strong_side: str = "R") -> str:
    """Resolve an AZee side (``s`` strong, ``w`` weak, ``R``, ``L``) to ``R`` or ``L``."""
    if side == "s":
        return strong_side
    if side == "w":
        return other_side(strong_side)
    if side in SIDES:
        return side
    raise ValueError(f"side {side!r} is not one of 's', 'w', 'R', 'L'")


def suggest(name: str, valid: list[str] | tuple[str, ...]) -> str:
    """A ``"; did you mean 'X'?"`` suffix for the closest valid name, or ``""``."""
    match = difflib.get_close_matches(name, list(valid), n=1, cutoff=0.6)
    return f"; did you mean {match[0]!r}?" if match else ""


@dataclasses.dataclass(frozen=True)
class BoneMap:
    """One AZee bone on the model: its body and its DIR / NRM unit axes in the body frame."""

    body: str
    dir: tuple[float, float, float]
    nrm: tuple[float, float, float]


@dataclasses.dataclass(frozen=True)
class Morph:
    """A named joint-space change: ``changes[joint]`` at weight 1 [rad or m].

    ``sided`` morphs name joints with a ``{X}`` placeholder for the side they act on (``L``
    or ``R``) and ``{Y}`` for the other side, with the right side's values; applying one
    without a side applies it to both sides (the changes summed). The joints of ``flipped``
    (midline joints, or joints whose left twin is not mirrored) change the other way on the
    left side.
    """

    changes: Mapping[str, float]
    sided: bool
    flipped: frozenset[str] = frozenset()

    def joint_changes(self, side: str | None) -> dict[str, float]:
        """The change per model joint for ``side`` (``"L"``, ``"R"`` or None for both)."""
        if not self.sided:
            return dict(self.changes)
        out: dict[str, float] = {}
        for s in SIDES if side is None else (side,):
            for name, v in arkit.side_changes(self.changes, s, self.flipped).items():
                out[name] = out.get(name, 0.0) + v
        return out


@dataclasses.dataclass(frozen=True)
class SignerMap:
    """How the AZee vocabulary lands on one MJCF signer.

    Attributes:
      sites: AZee site name -> model site name.
      bones: AZee bone name -> :class:`BoneMap`.
      loci: locus name (``ssp``) -> model site name.
      morphs: morph id -> :class:`Morph`.
      tracks: articulator track -> model joint names it owns (used by the scheduler).
      normals: AZee site -> outward unit normal of the skin at the site, in its body frame,
        for every site on the skin (on the collision surface of its body part): a contact
        between two such sites meets face to face, normals opposed.
      interior: the AZee sites that are not on the skin (joint centres, the tongue tip).
    """

    sites: Mapping[str, str]
    bones: Mapping[str, BoneMap]
    loci: Mapping[str, str]
    morphs: Mapping[str, Morph]
    tracks: Mapping[str, tuple[str, ...]]
    normals: Mapping[str, tuple[float, float, float]] = dataclasses.field(
        default_factory=lambda: MappingProxyType({})
    )
    interior: tuple[str, ...] = ()

    def to_json(self) -> dict:
        """The catalogue as printed by ``azee-mj sites --json``."""
        return {
            "sites": dict(self.sites),
            "bones": {
                k: {"body": b.body, "dir": list(b.dir), "nrm": list(b.nrm)}
                for k, b in self.bones.items()
            },
            "loci": dict(self.loci),
            "morphs": list(self.morphs),
            "normals": {k: list(v) for k, v in self.normals.items()},
            "interior": list(self.interior),
        }

    def renamed(self, rename_site=None, rename_body=None, rename_joint=None) -> SignerMap:
        """A copy for a model whose names differ by the given functions (str -> str)."""
        rs = rename_site or (lambda s: s)
        rb = rename_body or (lambda s: s)
        rj = rename_joint or (lambda s: s)
        return SignerMap(
            sites=_frozen({k: rs(v) for k, v in self.sites.items()}),
            bones=_frozen(
                {k: dataclasses.replace(b, body=rb(b.body)) for k, b in self.bones.items()}
            ),
            loci=_frozen({k: rs(v) for k, v in self.loci.items()}),
            morphs=_frozen(
                {
                    k: Morph(
                        _frozen({_rename_templ(j, rj): v for j, v in m.changes.items()}),
                        m.sided,
                        frozenset(_rename_templ(j, rj) for j in m.flipped),
                    )
                    for k, m in self.morphs.items()
                }
            ),
            tracks=_frozen({k: tuple(rj(j) for j in v) for k, v in self.tracks.items()}),
            normals=self.normals,
            interior=self.interior,
        )


def _rename_templ(joint: str, rename) -> str:
    # Keep the {X} / {Y} placeholders: rename the name with markers in them, then restore.
    marks = {"{X}": "\x00", "{Y}": "\x01"}
    for k, v in marks.items():
        joint = joint.replace(k, v)
    joint = rename(joint)
    for k, v in marks.items():
        joint = joint.replace(v, k)
    return joint


def _frozen(d: dict) -> Mapping:
    return MappingProxyType(dict(d))


def _unit(v) -> tuple[float, float, float]:
    a = np.asarray(v, float)
    a = a / np.linalg.norm(a)
    return tuple(round(float(x), 6) + 0.0 for x in a)  # + 0.0: no -0.0


def _mirror(v) -> tuple[float, float, float]:
    """Mirror a (polar) vector across the sagittal plane y = 0."""
    return (v[0], -v[1], v[2])


# ---------------------------------------------------------------------------------------
# The bundled signer (azee_mj/mjcf/signer.xml). Every body frame is aligned with the world
# at qpos0, so DIR / NRM below are also the world directions at the rest pose. Right-side
# vectors are given; the left side mirrors them (y -> -y).
# ---------------------------------------------------------------------------------------

#: Right-hand thumb axis and pad normal at qpos0. The thumb is adducted: it lies along the
#: radial (index) edge of the hand in the palm plane, diverging 25 degrees from the hand's
#: long axis and tilted 3 degrees palmar so that its three capsules (radii 11.5, 9.5 and
#: 8.5 mm) are flush with the palm's face; its pad faces the index finger (ulnar, in the
#: palm plane), so that MCP and IP flexion curl it across the palm.
_THUMB_DIVERGE, _THUMB_TILT = np.radians(25.0), np.radians(3.0)
THUMB_DIR_R = _unit(
    (
        np.sin(_THUMB_DIVERGE) * np.cos(_THUMB_TILT),
        np.sin(_THUMB_TILT),
        -np.cos(_THUMB_DIVERGE) * np.cos(_THUMB_TILT),
    )
)
THUMB_NRM_R = _unit(np.cross((0.0, 1.0, 0.0), THUMB_DIR_R))
#: The thumb of the `fist` morph [rad]: abducted out of the palm plane and curled over the
#: index and middle fingers' middle phalanges.
FIST_THUMB = MappingProxyType(
    {
        "thumb_{X}_1_flex": -0.2,
        "thumb_{X}_1_abd": 0.9,
        "thumb_{X}_2_flex": 0.5,
        "thumb_{X}_3_flex": 0.9,
    }
)
#: A thumb-up hand's thumb [rad]: straight, along the radial side of the closed fingers.
THUMB_UP = MappingProxyType(
    {
        "thumb_{X}_1_flex": -0.2,
        "thumb_{X}_1_abd": 0.15,
        "thumb_{X}_2_flex": 0.0,
        "thumb_{X}_3_flex": 0.0,
    }
)
#: Thumb MCP flexion [rad] that lays the adducted thumb's phalanges along the index finger.
THUMB_FLAT_MCP = round(float(np.radians(25.0)), 6)

_UP, _DOWN, _FWD = (0.0, 0.0, 1.0), (0.0, 0.0, -1.0), (1.0, 0.0, 0.0)
_PALMAR_R = (0.0, 1.0, 0.0)  # the right palm faces the body's midline at rest

#: Right clavicle: sternoclavicular joint to shoulder joint centre (body origins in the XML).
CLAV_R_ORIGIN = (0.045, -0.025, 0.475)
ARM_R_ORIGIN = (-0.005, -0.18, 0.48)


def _bundled_bones() -> dict[str, BoneMap]:
    bones = {
        "back_1": BoneMap("back_1", _UP, _FWD),
        "back_2": BoneMap("back_2", _UP, _FWD),
        "neck": BoneMap("neck", _UP, _FWD),
        "head": BoneMap("head", _UP, _FWD),
        "eye_L": BoneMap("eye_L", _FWD, _UP),
        "eye_R": BoneMap("eye_R", _FWD, _UP),
    }
    clav_dir = _unit(np.subtract(ARM_R_ORIGIN, CLAV_R_ORIGIN))
    right = {
        "clav": (clav_dir, _unit(np.subtract(_FWD, np.dot(_FWD, clav_dir) * np.array(clav_dir)))),
        "arm": (_DOWN, _FWD),
        "f_arm": (_DOWN, _PALMAR_R),
        "palm": (_DOWN, _PALMAR_R),
    }
    for f in FINGERS:
        for n in PHALANGES:
            right[f"{f}_R_{n}"] = (_DOWN, _PALMAR_R)
    for n in PHALANGES:
        right[f"thumb_R_{n}"] = (THUMB_DIR_R, THUMB_NRM_R)
    for side in SIDES:
        for key, (d, n) in right.items():
            name = key.replace("_R_", f"_{side}_") if "_R_" in key else f"{key}_{side}"
            if side == "L":
                d, n = _mirror(d), _mirror(n)
            bones[name] = BoneMap(name, tuple(d), tuple(n))
    return {b: bones[b] for b in azee_bone_names()}


def _bundled_tracks() -> dict[str, tuple[str, ...]]:
    tracks: dict[str, list[str]] = {
        "spine": [f"{b}_{m}" for b in ("back_1", "back_2") for m in ("flex", "lat", "rot")],
        "head": [f"{b}_{m}" for b in ("neck", "head") for m in ("flex", "lat", "rot")],
        "eyes": [f"eye_{s}_{m}" for s in SIDES for m in ("yaw", "pitch")],
        "face": list(FACE_JOINTS),
    }
    for s in SIDES:
        tracks[f"arm_{s}"] = [
            f"clav_{s}_elev",
            f"clav_{s}_prot",
            f"arm_{s}_flex",
            f"arm_{s}_abd",
            f"arm_{s}_rot",
            f"f_arm_{s}_flex",
            f"f_arm_{s}_pron",
            f"palm_{s}_flex",
            f"palm_{s}_dev",
        ]
        hand = [f"thumb_{s}_1_flex", f"thumb_{s}_1_abd", f"thumb_{s}_2_flex", f"thumb_{s}_3_flex"]
        for f in FINGERS:
            hand += [f"{f}_{s}_1_flex", f"{f}_{s}_1_spread", f"{f}_{s}_2_flex", f"{f}_{s}_3_flex"]
        tracks[f"hand_{s}"] = hand
    return {k: tuple(v) for k, v in tracks.items()}


def _finger_joints(fingers=FINGERS) -> list[str]:
    return [f"{f}_{{X}}_{n}_flex" for f in fingers for n in PHALANGES]


#: Handshape joint angles [rad]: a thumb (1_flex, 1_abd, 2_flex, 3_flex) and a finger
#: (1_flex, 1_spread, 2_flex, 3_flex).
_STRAIGHT = (0.0, 0.0, 0.0, 0.0)
_CLOSED = (1.5, 0.0, 1.65, 1.0)  # curled into the palm, as the fist morph
_T_SIDE = (0.0, 0.0, THUMB_FLAT_MCP, 0.0)  # adducted along the index, as the flat morph
_THUMB = ("1_flex", "1_abd", "2_flex", "3_flex")
_T_ACROSS = tuple(FIST_THUMB[f"thumb_{{X}}_{j}"] for j in _THUMB)  # over the closed fingers
_T_OUT = (-0.4, 0.2, 0.0, 0.0)  # away from the palm, in its plane
_T_UP = tuple(THUMB_UP[f"thumb_{{X}}_{j}"] for j in _THUMB)  # straight up from a fist
_T_IN = _T_ACROSS  # folded across the palm
_T_OPP = (-0.3, 1.0, 0.3, 1.2)  # opposed: its tip 3 mm from the curved index's tip
_CURVED = (1.0, 0.0, 1.1, 0.7)  # curved to meet the opposed thumb
# A pinch: the index's tip on the thumb's tip (0.45 mm apart, the skins touching). The
# thumb cannot turn its pad toward the index (no axial rotation): the tips meet at 26
# degrees from end to end, the thumb's MCP and the index's DIP near their limits.
_T_PINCH = (-0.154, 0.485, 1.005, -0.059)
_I_PINCH = (0.336, -0.081, 1.278, 1.529)


def _hs(thumb, index, middle, ring, little) -> tuple[tuple[float, ...], ...]:
    return (thumb, index, middle, ring, little)


def _sp(f, spread):
    return (f[0], spread, f[2], f[3])


#: Named handshapes of French Sign Language and HamNoSys (morphs ``hs_NAME``), as joint
#: angles of one hand: (thumb, index, middle, ring, little), see ``_hs``. A score applies
#: one at weight 1 from the rest hand; other morphs add to it.
HANDSHAPES: dict[str, tuple[tuple[float, ...], ...]] = {
    "flat": _hs(_T_SIDE, _STRAIGHT, _STRAIGHT, _STRAIGHT, _STRAIGHT),
    "bent": _hs(_T_SIDE, *[(1.3, 0.0, 0.0, 0.0)] * 4),
    "a": _hs(_T_SIDE, *[_CLOSED] * 4),
    "s": _hs(_T_ACROSS, *[_CLOSED] * 4),
    "index": _hs(_T_ACROSS, _STRAIGHT, _CLOSED, _CLOSED, _CLOSED),
    "v": _hs(_T_ACROSS, _sp(_STRAIGHT, 0.25), _sp(_STRAIGHT, -0.15), _CLOSED, _CLOSED),
    "h": _hs(_T_ACROSS, _STRAIGHT, _STRAIGHT, _CLOSED, _CLOSED),
    "3": _hs(_T_OUT, _sp(_STRAIGHT, 0.25), _sp(_STRAIGHT, -0.15), _CLOSED, _CLOSED),
    "w": _hs(_T_IN, _sp(_STRAIGHT, 0.25), _STRAIGHT, _sp(_STRAIGHT, -0.25), _CLOSED),
    "4": _hs(_T_IN, _sp(_STRAIGHT, 0.15), _STRAIGHT, _sp(_STRAIGHT, -0.1), _sp(_STRAIGHT, -0.2)),
    "5": _hs(_T_OUT, _sp(_STRAIGHT, 0.3), _STRAIGHT, _sp(_STRAIGHT, -0.2), _sp(_STRAIGHT, -0.4)),
    "claw": _hs(
        (-0.3, 0.3, 0.5, 0.5),
        (0.3, 0.3, 1.0, 0.8),
        (0.3, 0.0, 1.0, 0.8),
        (0.3, -0.2, 1.0, 0.8),
        (0.3, -0.4, 1.0, 0.8),
    ),
    "l": _hs(_T_OUT, _STRAIGHT, _CLOSED, _CLOSED, _CLOSED),
    "y": _hs(_T_OUT, _CLOSED, _CLOSED, _CLOSED, _sp(_STRAIGHT, -0.4)),
    "i": _hs(_T_ACROSS, _CLOSED, _CLOSED, _CLOSED, _STRAIGHT),
    "horns": _hs(_T_ACROSS, _STRAIGHT, _CLOSED, _CLOSED, _STRAIGHT),
    "x": _hs(_T_ACROSS, (0.3, 0.0, 1.3, 1.0), _CLOSED, _CLOSED, _CLOSED),
    "bent_v": _hs(_T_ACROSS, (0.0, 0.25, 1.3, 1.0), (0.0, -0.15, 1.3, 1.0), _CLOSED, _CLOSED),
    "thumb": _hs(_T_UP, *[_CLOSED] * 4),
    "c": _hs((0.0, 0.35, 0.1, 0.1), *[(0.6, 0.0, 0.7, 0.4)] * 4),
    "o": _hs(_T_OPP, *[_CURVED] * 4),
    "flat_o": _hs((0.4, 0.7, 0.1, -0.05), *[(1.05, 0.0, 0.35, 0.2)] * 4),
    "f": _hs(_T_PINCH, _I_PINCH, _sp(_STRAIGHT, 0.05), _sp(_STRAIGHT, -0.15), _sp(_STRAIGHT, -0.3)),
    "pinch": _hs(_T_PINCH, _I_PINCH, _CLOSED, _CLOSED, _CLOSED),
}


def handshape_changes(name: str) -> dict[str, float]:
    """The joint changes [rad] of morph ``hs_<name>`` (joint names with ``{X}``)."""
    thumb, *fingers = HANDSHAPES[name]
    out = {f"thumb_{{X}}_{j}": v for j, v in zip(_THUMB, thumb)}
    for f, angles in zip(FINGERS, fingers):
        out.update(
            {
                f"{f}_{{X}}_{j}": v
                for j, v in zip(("1_flex", "1_spread", "2_flex", "3_flex"), angles)
            }
        )
    return out


def _bundled_morphs() -> dict[str, tuple]:
    """Morph id -> (joint change at weight 1 [rad / m], sided[, flipped joints])."""
    m: dict[str, tuple] = {}
    for f in FINGERS:
        m[f"{f}_bend"] = ({f"{f}_{{X}}_1_flex": 1.45}, True)
        m[f"{f}_hook"] = ({f"{f}_{{X}}_2_flex": 1.5, f"{f}_{{X}}_3_flex": 1.2}, True)
    # (the thumb leaves the palm plane, palmar, before it curls: it curls across the palm)
    m["thumb_bend"] = (
        {"thumb_{X}_1_abd": 0.5, "thumb_{X}_2_flex": 0.9, "thumb_{X}_3_flex": 0.6},
        True,
    )
    m["thumb_hook"] = ({"thumb_{X}_1_abd": 0.3, "thumb_{X}_3_flex": 1.2}, True)
    m["thumb_opposed"] = ({"thumb_{X}_1_flex": 0.5, "thumb_{X}_1_abd": 0.9}, True)
    m["thumb_spread"] = ({"thumb_{X}_1_flex": -0.4, "thumb_{X}_1_abd": 0.2}, True)
    # Morphs add (clipped to the ranges): thumb_extended is the change from the fist's thumb
    # to a straight thumb along the fist's radial side, so fist + thumb_extended (a thumb-up
    # hand) has a straight thumb. Alone (or with `flat`) its negative changes clip at the
    # ranges: a straight thumb, its tip bent back 20 degrees.
    m["thumb_extended"] = ({j: THUMB_UP[j] - FIST_THUMB[j] for j in FIST_THUMB}, True)
    # The thumb spreads too: it lies along the index finger, which spreads toward it, in
    # the palm's plane (its base unflexed: from home's 0.05 rad of flexion, abducted 0.24 to
    # 0.32 rad, its proximal phalanx sank up to 0.19 mm into the palm's edge).
    m["fingers_spread"] = (
        {
            "index_{X}_1_spread": 0.3,
            "middle_{X}_1_spread": 0.0,
            "ring_{X}_1_spread": -0.2,
            "little_{X}_1_spread": -0.4,
            "thumb_{X}_1_abd": 0.3,
            "thumb_{X}_1_flex": 0.0,
        },
        True,
    )
    fist = {
        j: v
        for f in FINGERS
        for j, v in (
            (f"{f}_{{X}}_1_flex", 1.5),
            (f"{f}_{{X}}_2_flex", 1.65),
            (f"{f}_{{X}}_3_flex", 1.0),
        )
    }
    # thumb curled over the index and middle fingers' middle phalanges, 1 mm clear of them
    fist.update(FIST_THUMB)
    m["fist"] = (fist, True)
    flat = {j: 0.0 for j in _finger_joints()}
    flat.update({f"{f}_{{X}}_1_spread": 0.0 for f in FINGERS})
    # the thumb adducted along the index finger, in the palm plane (its phalanges parallel)
    flat.update(
        {
            "thumb_{X}_1_flex": 0.0,
            "thumb_{X}_1_abd": 0.0,
            "thumb_{X}_2_flex": THUMB_FLAT_MCP,
            "thumb_{X}_3_flex": 0.0,
        }
    )
    m["flat"] = (flat, True)
    for name in HANDSHAPES:  # the rest hand is at 0 on every hand joint
        m[f"hs_{name}"] = (handshape_changes(name), True)
    m["shoulder_raise"] = ({"clav_{X}_elev": 0.45}, True)
    m["shoulder_shrug"] = ({"clav_{X}_elev": 0.35, "clav_{X}_prot": 0.15}, True)
    m["spine_extended"] = ({"back_1_flex": -0.15, "back_2_flex": -0.15}, False)
    m.update(_face_morphs())
    return m


def _compose(weights: Mapping[str, float]) -> dict[str, float]:
    """A weighted sum of ARKit shapes' right-side templates (``arkit.SIDED`` bases and
    ``arkit.BOTH`` shapes)."""
    out: dict[str, float] = {}
    for name, w in weights.items():
        for j, v in {**arkit.SIDED, **arkit.BOTH}[name].items():
            out[j] = out.get(j, 0.0) + w * v
    return {j: round(v, 6) for j, v in out.items()}


def _face_morphs() -> dict[str, tuple]:
    """The 52 ARKit shapes, their sided bases, and the catalogue's first face morphs as
    compositions of them."""
    m: dict[str, tuple] = {name: (ch, False) for name, ch in arkit.shape_changes().items()}
    for base, ch in arkit.SIDED.items():
        m[base] = (dict(ch), True, arkit.FLIPPED & set(ch))
    m["blink"] = (_compose({"eyeBlink": 1.0}), True)
    m["eyes_wide"] = (_compose({"eyeWide": 1.0}), True)
    m["brows_raise"] = (_compose({"browInnerUp": 0.8, "browOuterUp": 0.8}), True)
    m["brows_frown"] = (_compose({"browDown": 1.0}), True)
    m["jaw_open"] = (arkit.both_changes(_compose({"jawOpen": 0.85})), False)
    m["smile"] = (_compose({"mouthSmile": 1.0}), True)
    m["mouth_down"] = (_compose({"mouthFrown": 1.0}), True)
    return m


#: AZee sites of the bundled signer that are not on the skin: the wrist joint centres and
#: the tongue tip (inside the closed mouth).
_INTERIOR = ("TO", "WR_L", "WR_R")

#: Outward skin normals at qpos0 (= in the body frame) of the midline sites and the right
#: side's lateral sites (``{X}``), computed from the collision geometry by
#: ``tools/build_signer.py`` (which checks them); the left side mirrors them.
_NORMALS = {
    "HEAD": (0.0, 0.0, 1.0),
    "FH": (0.8902, 0.0, 0.4555),
    "NO": (1.0, 0.0, -0.0),
    "NSP": (0.9805, 0.0, -0.1967),
    "MO": (0.8575, -0.0, -0.5144),
    "CH": (0.5914, 0.0, -0.8063),
    "BEB": (-1.0, 0.0, 0.0),
    "NK": (0.9779, 0.0, 0.2092),
    "NAPE": (-0.9997, 0.0, -0.0235),
    "ST": (0.9957, 0.0, 0.0925),
    "AB": (0.9974, 0.0, 0.0719),
    "ABST": (0.893, 0.0, 0.45),
    "EB_{X}": (0.8602, -0.4917, 0.1356),
    "EBi_{X}": (0.9578, -0.2612, 0.1198),
    "EBe_{X}": (0.697, -0.7085, 0.1105),
    "EYE_{X}": (1.0, 0.0, 0.0),
    "TE_{X}": (0.405, -0.9102, 0.0866),
    "CK_{X}": (0.6732, -0.7388, -0.0308),
    "EAR_{X}": (0.8138, -0.4698, -0.342),
    "LOBE_{X}": (0.1699, -0.9767, -0.1313),
    "MO_{X}": (0.7853, -0.4031, -0.47),
    "NO_{X}": (0.4091, -0.8069, -0.4261),
    "NK_{X}": (0.0, -1.0, 0.0),
    "ST_{X}": (0.8902, -0.4448, 0.0986),
    "AB_{X}": (0.8858, -0.4576, 0.0772),
    "ABST_{X}": (0.8019, -0.3554, 0.4803),
    "HIP_{X}": (0.3208, -0.7629, 0.5614),
    "SH_{X}": (0.9085, -0.0696, 0.412),
    "ARMpit_{X}": (0.0, 1.0, 0.0),
    "ARM_{X}": (0.0, -1.0, 0.0),
    "ARMsh_{X}": (0.0, -0.2425, 0.9701),
    "EL_{X}": (0.0, 0.0, 1.0),
    "ELi_{X}": (0.9678, 0.0, -0.2516),
    "F_ARM_{X}": (0.0, -1.0, 0.0),
    "F_ARMi_{X}": (0.0, 1.0, 0.0),
    "WRt_{X}": (0.0, -1.0, -0.0),
    "WRi_{X}": (0.1772, 0.9842, -0.0),
    "PA_{X}": (0.0, 1.0, 0.0),
    "H_BACK_{X}": (0.0, -1.0, 0.0),
    "H_EDGE_{X}": (-1.0, 0.0, 0.0),
    "viande_{X}": (0.0, 1.0, 0.0),
}

#: Digit sites' normals from the phalanx's bone axes: ``+1`` / ``-1`` times NRM (pad /
#: back), or DIR (the tip).
_DIGIT_NORMALS = {
    "KN": ("nrm", -1),
    "KNi": ("nrm", 1),
    "BACK": ("nrm", -1),
    "INT": ("nrm", 1),
    "PAD": ("nrm", 1),
    "NA": ("nrm", -1),
    "TIP": ("dir", 1),
}


def _bundled_normals(bones: Mapping[str, BoneMap]) -> dict[str, tuple[float, float, float]]:
    out = {}
    for key, v in _NORMALS.items():
        if "{X}" not in key:
            out[key] = _unit(v)
            continue
        for side in SIDES:
            out[key.format(X=side)] = _unit(_mirror(v) if side == "L" else v)
    for side in SIDES:
        for letter, digit in DIGITS.items():
            for stem in DIGIT_STEMS:
                axis, sign = _DIGIT_NORMALS[stem]
                b = bones[f"{digit}_{side}_3"]
                out[f"{letter}_{stem}_{side}"] = _unit(sign * np.asarray(getattr(b, axis)))
            for stem in PHALANX_STEMS:
                axis, sign = _DIGIT_NORMALS[stem]
                for n in PHALANGES:
                    b = bones[f"{digit}_{side}_{n}"]
                    out[f"{letter}_{stem}_{side}_{n}"] = _unit(sign * np.asarray(getattr(b, axis)))
    return {name: out[name] for name in azee_site_names() if name in out}


def _bundled_map() -> SignerMap:
    sites = {name: name for name in azee_site_names()}
    morphs = {
        k: Morph(_frozen(v[0]), v[1], frozenset(v[2]) if len(v) > 2 else frozenset())
        for k, v in _bundled_morphs().items()
    }
    bones = _bundled_bones()
    return SignerMap(
        sites=_frozen(sites),
        bones=_frozen(bones),
        loci=_frozen({name: name for name in LOCI}),
        morphs=_frozen(morphs),
        tracks=_frozen(_bundled_tracks()),
        normals=_frozen(_bundled_normals(bones)),
        interior=_INTERIOR,
    )


#: The map of the bundled signer ``azee_mj/mjcf/signer.xml``.
DEFAULT_MAP = _bundled_map()
