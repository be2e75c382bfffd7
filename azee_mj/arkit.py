"""The face vocabulary: Apple ARKit's 52 blend shapes as joint changes of the bundled rig.

ARKit names its shapes for the face's own sides (``eyeBlinkLeft`` closes the left eye), so
here ``Left`` / ``Right`` are the signer's own left and right. Every shape whose name ends in
``Left`` or ``Right`` also has a *sided* base (the name without the suffix, e.g.
``eyeBlink``) that a score applies to a side (``"side": "s"``, ``"w"``, ``"R"``, ``"L"``),
or to both sides when it gives none.

Changes are written for the right side with two placeholders: ``{X}`` the side the shape
acts on, ``{Y}`` the other side; the rig's left joints mirror the right ones, so the same
values give the mirrored motion. The midline joints that a side's shape moves one way on
the right and the other way on the left (the jaw's sideways slide, the eyes' conjugate yaw)
are listed in ``FLIPPED``. Units: radians (hinges), metres (slides), at weight 1.

A weight is in [0, 1]. :func:`constraints` writes a set of weights as score constraints, a
Left/Right pair with equal weights as its base name without a side (both sides).
"""

from __future__ import annotations

from collections.abc import Mapping

#: The 52 blend shapes, in the order of ARKit's ``ARFaceAnchor.BlendShapeLocation`` list as
#: Live Link Face writes its columns.
ARKIT_SHAPES = (
    "eyeBlinkLeft",
    "eyeLookDownLeft",
    "eyeLookInLeft",
    "eyeLookOutLeft",
    "eyeLookUpLeft",
    "eyeSquintLeft",
    "eyeWideLeft",
    "eyeBlinkRight",
    "eyeLookDownRight",
    "eyeLookInRight",
    "eyeLookOutRight",
    "eyeLookUpRight",
    "eyeSquintRight",
    "eyeWideRight",
    "jawForward",
    "jawRight",
    "jawLeft",
    "jawOpen",
    "mouthClose",
    "mouthFunnel",
    "mouthPucker",
    "mouthRight",
    "mouthLeft",
    "mouthSmileLeft",
    "mouthSmileRight",
    "mouthFrownLeft",
    "mouthFrownRight",
    "mouthDimpleLeft",
    "mouthDimpleRight",
    "mouthStretchLeft",
    "mouthStretchRight",
    "mouthRollLower",
    "mouthRollUpper",
    "mouthShrugLower",
    "mouthShrugUpper",
    "mouthPressLeft",
    "mouthPressRight",
    "mouthLowerDownLeft",
    "mouthLowerDownRight",
    "mouthUpperUpLeft",
    "mouthUpperUpRight",
    "browDownLeft",
    "browDownRight",
    "browInnerUp",
    "browOuterUpLeft",
    "browOuterUpRight",
    "cheekPuff",
    "cheekSquintLeft",
    "cheekSquintRight",
    "noseSneerLeft",
    "noseSneerRight",
    "tongueOut",
)

_U, _W, _C = "lip_up_{X}", "lip_low_{X}", "mouth_{X}"

#: Sided shapes (base name -> right-side changes): ``<base>Right`` is the shape on the
#: right, ``<base>Left`` its mirror.
SIDED = {
    "eyeBlink": {"lid_{X}_close": 1.15},
    "eyeLookDown": {"eye_{X}_pitch": 0.55, "lid_{X}_close": 0.30, "lid_low_{X}_raise": -0.10},
    "eyeLookIn": {"eye_{X}_yaw": 0.50},
    "eyeLookOut": {"eye_{X}_yaw": -0.60},
    "eyeLookUp": {"eye_{X}_pitch": -0.50, "lid_{X}_close": -0.25},
    "eyeSquint": {"lid_low_{X}_raise": 0.30, "lid_{X}_close": 0.12, "cheek_{X}_raise": 0.002},
    "eyeWide": {"lid_{X}_close": -0.35, "lid_low_{X}_raise": -0.08},
    "jaw": {"jaw_lat": -0.006},
    "mouth": {
        "mouth_{X}_out": 0.006,
        "mouth_{Y}_out": -0.006,
        f"{_U}_in": -0.006,
        "lip_up_{Y}_in": 0.006,
        f"{_W}_in": -0.006,
        "lip_low_{Y}_in": 0.006,
    },
    "mouthSmile": {
        f"{_C}_up": 0.008,
        f"{_C}_out": 0.004,
        f"{_U}_tilt": 0.10,
        f"{_W}_tilt": 0.16,
        f"{_C}_fwd": -0.002,
        f"{_U}_raise": 0.0015,
        f"{_U}_in": -0.003,
        f"{_W}_in": -0.003,
        f"{_W}_down": 0.001,
        "cheek_{X}_raise": 0.004,
    },
    "mouthFrown": {
        f"{_C}_up": -0.006,
        f"{_C}_out": 0.001,
        f"{_U}_tilt": -0.12,
        f"{_W}_tilt": -0.08,
        f"{_W}_down": -0.001,
    },
    "mouthDimple": {
        f"{_C}_fwd": -0.004,
        f"{_C}_out": 0.003,
        f"{_U}_in": -0.002,
        f"{_W}_in": -0.002,
    },
    "mouthStretch": {
        f"{_C}_out": 0.007,
        f"{_C}_up": -0.002,
        f"{_W}_down": 0.002,
        f"{_U}_in": -0.004,
        f"{_W}_in": -0.004,
    },
    "mouthPress": {
        f"{_U}_raise": -0.0015,
        f"{_W}_down": -0.0015,
        f"{_U}_in": -0.001,
        f"{_W}_in": -0.001,
    },
    "mouthLowerDown": {f"{_W}_down": 0.006},
    "mouthUpperUp": {f"{_U}_raise": 0.005},
    "browDown": {
        "brow_{X}_raise": -0.003,
        "brow_{X}_knit": 0.004,
        "brow_{X}_tilt": -0.30,
        "brow_out_{X}_raise": -0.003,
    },
    "browOuterUp": {"brow_out_{X}_tilt": 0.40},
    "cheekSquint": {"cheek_{X}_raise": 0.005, "lid_low_{X}_raise": 0.10},
    "noseSneer": {"nose_{X}_sneer": 0.004, f"{_U}_raise": 0.0015, "brow_{X}_raise": -0.002},
}

#: Midline joints a sided shape moves the other way on the left.
FLIPPED = frozenset({"jaw_lat", "eye_{X}_yaw"})

#: Shapes of both sides at once or of the midline (written with ``{X}`` for both sides).
BOTH = {
    "browInnerUp": {
        "brow_{X}_raise": 0.003,
        "brow_{X}_knit": 0.002,
        "brow_{X}_tilt": 0.40,
        "brow_out_{X}_raise": 0.003,
    },
    "cheekPuff": {"cheek_{X}_puff": 0.008, f"{_U}_out": 0.001, f"{_W}_out": 0.001},
    "jawOpen": {"jaw_open": 0.35, "jaw_fwd": 0.003, f"{_C}_up": -0.008, f"{_C}_out": -0.003},
    "jawForward": {"jaw_fwd": 0.004, f"{_W}_down": -0.003},
    "mouthClose": {f"{_U}_raise": -0.002, f"{_W}_down": -0.002},
    "mouthFunnel": {
        f"{_U}_out": 0.005,
        f"{_W}_out": 0.005,
        f"{_U}_raise": 0.002,
        f"{_W}_down": 0.003,
        f"{_U}_in": 0.004,
        f"{_W}_in": 0.004,
        f"{_C}_out": -0.008,
        f"{_C}_fwd": 0.004,
        "jaw_open": 0.06,
    },
    "mouthPucker": {
        f"{_U}_out": 0.006,
        f"{_W}_out": 0.006,
        f"{_U}_in": 0.006,
        f"{_W}_in": 0.006,
        f"{_U}_raise": -0.001,
        f"{_W}_down": -0.001,
        f"{_C}_out": -0.011,
        f"{_C}_fwd": 0.005,
    },
    "mouthRollLower": {f"{_W}_out": -0.004, f"{_W}_down": -0.0015},
    "mouthRollUpper": {f"{_U}_out": -0.005, f"{_U}_raise": -0.0015},
    "mouthShrugLower": {f"{_W}_down": -0.003, f"{_W}_out": 0.002},
    "mouthShrugUpper": {f"{_U}_raise": 0.002, f"{_U}_out": 0.001},
    "tongueOut": {"tongue_out": 0.028, "jaw_open": 0.15, f"{_W}_down": 0.006},
}

SIDE_SUFFIX = {"L": "Left", "R": "Right"}


def side_changes(
    changes: Mapping[str, float], side: str, flipped: frozenset[str] = FLIPPED
) -> dict[str, float]:
    """A sided shape's changes on ``side`` (``"R"`` or ``"L"``), with concrete joint names
    (the joints of ``flipped`` change the other way on the left)."""
    other = "L" if side == "R" else "R"
    out: dict[str, float] = {}
    for j, v in changes.items():
        if side == "L" and j in flipped:
            v = -v
        name = j.format(X=side, Y=other)
        out[name] = out.get(name, 0.0) + v
    return out


def both_changes(changes: dict[str, float]) -> dict[str, float]:
    """A two-sided shape's changes with concrete joint names (midline joints once)."""
    return {j.format(X=s): v for s in ("R", "L") for j, v in changes.items()}


def shape_changes() -> dict[str, dict[str, float]]:
    """Each of the 52 ARKit shapes -> its joint changes at weight 1, in ``ARKIT_SHAPES``
    order."""
    out = {name: both_changes(ch) for name, ch in BOTH.items()}
    for base, ch in SIDED.items():
        for side, suffix in SIDE_SUFFIX.items():
            out[base + suffix] = side_changes(ch, side)
    return {name: out[name] for name in ARKIT_SHAPES}


#: Bases of the Left/Right pairs whose two sides add up (``eyeBlink`` for ``eyeBlinkLeft``
#: and ``eyeBlinkRight``). ``mouthLeft`` / ``mouthRight`` and ``jawLeft`` / ``jawRight`` are
#: movements toward a side: the same weight on both cancels, so they are not written as one.
PAIRS: tuple[str, ...] = tuple(
    n.removesuffix(SIDE_SUFFIX["L"])
    for n in ARKIT_SHAPES
    if n.endswith(SIDE_SUFFIX["L"]) and n not in ("mouthLeft", "jawLeft")
)


def split(name: str) -> tuple[str, str | None]:
    """``("eyeBlink", "L")`` for ``eyeBlinkLeft``; ``(name, None)`` for an unpaired one."""
    for side, suffix in SIDE_SUFFIX.items():
        base = name.removesuffix(suffix)
        if base != name and base in PAIRS:
            return base, side
    return name, None


def is_shape(name: str) -> bool:
    """Whether ``name`` is an ARKit shape or a pair's base (the morphs weighted in [0, 1])."""
    return name in ARKIT_SHAPES or name in PAIRS or name in SIDED


def constraints(weights: Mapping[str, float], digits: int = 3) -> list[dict]:
    """Score morph constraints for ``weights`` (ARKit name -> [0, 1]), rounded to
    ``digits`` decimals, zero weights kept (they return a shape to rest). A pair with equal
    weights becomes its base name without a side; the order follows :data:`ARKIT_SHAPES`."""
    out: list[dict] = []
    done: set[str] = set()
    for name in ARKIT_SHAPES:
        if name not in weights or name in done:
            continue
        base, side = split(name)
        w = round(float(weights[name]), digits)
        if side is not None:
            other = base + SIDE_SUFFIX["R" if side == "L" else "L"]
            if other in weights and round(float(weights[other]), digits) == w:
                out.append({"type": "morph", "id": base, "weight": w})
                done.add(other)
                continue
        out.append({"type": "morph", "id": name, "weight": w})
    return out
