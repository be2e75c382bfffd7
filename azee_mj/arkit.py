"""The 52 ARKit face blend shapes: their names, pairs and how a set of weights becomes
score constraints.

The names are ARKit's own (``eyeBlinkLeft`` ...), Left and Right being the signer's own
sides; a weight is in [0, 1]. :data:`NAMES` is in the order of Apple's
``ARFaceAnchor.BlendShapeLocation`` list as Live Link Face writes it (left eye, right eye,
jaw, mouth, brows, cheeks, nose, tongue). In a score a Left/Right pair with equal weights
is written as its base name without a side (``{"type": "morph", "id": "eyeBlink",
"weight": 1}``: both sides), as the catalogue's side-relative form allows.
"""

from __future__ import annotations

from collections.abc import Mapping

#: The 52 blend shapes in Live Link Face's column order.
NAMES: tuple[str, ...] = (
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

#: Base names of the Left/Right pairs (``eyeBlink`` for ``eyeBlinkLeft`` /
#: ``eyeBlinkRight``). ``mouthLeft`` / ``mouthRight`` and ``jawLeft`` / ``jawRight`` are
#: movements toward a side, not pairs.
PAIRS: tuple[str, ...] = tuple(
    n.removesuffix("Left")
    for n in NAMES
    if n.endswith("Left") and n not in ("mouthLeft", "jawLeft")
)


def split(name: str) -> tuple[str, str | None]:
    """``("eyeBlink", "L")`` for ``eyeBlinkLeft``; ``(name, None)`` for an unpaired one."""
    for suffix, side in (("Left", "L"), ("Right", "R")):
        base = name.removesuffix(suffix)
        if base != name and base in PAIRS:
            return base, side
    return name, None


def check_weights(weights: Mapping[str, float], where: str) -> None:
    """Raise :class:`ValueError` naming ``where`` for an unknown name or a weight outside
    [0, 1]."""
    for name, w in weights.items():
        if name not in NAMES:
            from azee_mj.sites import suggest

            raise ValueError(f"{where}: unknown ARKit blend shape {name!r}{suggest(name, NAMES)}")
        if not 0.0 <= float(w) <= 1.0:
            raise ValueError(f"{where}: weight of {name} must be in [0, 1], got {w}")


def constraints(weights: Mapping[str, float], digits: int = 3) -> list[dict]:
    """Score morph constraints for ``weights`` (ARKit name -> [0, 1]), rounded to
    ``digits`` decimals, zero weights kept (they return a shape to rest). A pair with equal
    weights becomes its base name without a side; the order follows :data:`NAMES`."""
    out: list[dict] = []
    done: set[str] = set()
    for name in NAMES:
        if name not in weights or name in done:
            continue
        base, side = split(name)
        w = round(float(weights[name]), digits)
        if side is not None:
            other = base + ("Right" if side == "L" else "Left")
            if other in weights and round(float(weights[other]), digits) == w:
                out.append({"type": "morph", "id": base, "weight": w})
                done.add(other)
                continue
        out.append({"type": "morph", "id": name, "weight": w})
    return out
