"""The records of a loaded score: blocks, constraints, references, point and vector
expressions, transpath routes. Small frozen dataclasses; times absolute [s], angles [rad],
lengths [m] (see :mod:`azee_mj.score`)."""

from __future__ import annotations

import dataclasses
import enum
import math
from collections.abc import Iterator, Mapping
from types import MappingProxyType
from typing import Any, ClassVar

from azee_mj.sites import DEFAULT_MAP, BoneMap, SignerMap
from azee_mj.timing import exact_time

FORMAT = "azee-score"
VERSION = 1
#: Default ``place`` tolerance [m] and ``orient`` tolerance [deg] of the format.
DEFAULT_TOL = 0.001
DEFAULT_TOL_DEG = 1.0
#: Slack [s] allowed when checking that a child lies inside its parent.
TIME_SLACK = 1e-9
#: Below this norm a constant direction is "zero".
ZERO_NORM = 1e-9

#: The unit axes of the signer frame (+x forward, +y the signer's left, +z up).
NAMED_DIRECTIONS: Mapping[str, tuple[float, float, float]] = MappingProxyType(
    {
        "fwd": (1.0, 0.0, 0.0),
        "back": (-1.0, 0.0, 0.0),
        "left": (0.0, 1.0, 0.0),
        "right": (0.0, -1.0, 0.0),
        "up": (0.0, 0.0, 1.0),
        "down": (0.0, 0.0, -1.0),
    }
)

# ---------------------------------------------------------------------------------------
# Closed sets
# ---------------------------------------------------------------------------------------


class BlockKind(enum.Enum):
    """The kind of a block (its ``kind`` in the JSON)."""

    SYNC = "sync"
    CSTR = "cstr"
    HOLD = "hold"
    TRANSPATH = "transpath"


class Axis(enum.Enum):
    """A bone axis: DIR (along the bone) or NRM (its normal)."""

    DIR = "dir"
    NRM = "nrm"


class Rel(enum.Enum):
    """How an ``orient`` relates the bone axis to its vector."""

    ALONG = "along"
    OPP = "opp"
    PERP = "perp"


# ---------------------------------------------------------------------------------------
# References
# ---------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class SiteRef:
    """A resolved body site (``name`` is the AZee site name, e.g. ``I_TIP_R``) or, with
    ``locus=True``, a signing-space locus (``name`` is e.g. ``ssp``)."""

    name: str
    locus: bool = False

    def model_site(self, signer_map: SignerMap = DEFAULT_MAP) -> str:
        """The model site name of this site or locus on ``signer_map``'s model."""
        return (signer_map.loci if self.locus else signer_map.sites)[self.name]

    def __str__(self) -> str:
        return ("^" if self.locus else "@") + self.name


@dataclasses.dataclass(frozen=True)
class BoneRef:
    """A resolved AZee bone (``name`` e.g. ``index_R_2``, ``f_arm_L``, ``head``)."""

    name: str

    def bone_map(self, signer_map: SignerMap = DEFAULT_MAP) -> BoneMap:
        """The bone's body and DIR / NRM axes on ``signer_map``'s model."""
        return signer_map.bones[self.name]

    def model_body(self, signer_map: SignerMap = DEFAULT_MAP) -> str:
        """The model body that carries this bone."""
        return signer_map.bones[self.name].body

    def __str__(self) -> str:
        return "!" + self.name


# ---------------------------------------------------------------------------------------
# Point and vector expressions
# ---------------------------------------------------------------------------------------

Vec3 = tuple[float, float, float]


@dataclasses.dataclass(frozen=True)
class PSite:
    """The position of a body site or locus on the current posture."""

    ref: SiteRef


@dataclasses.dataclass(frozen=True)
class PLiteral:
    """A literal point in the signer frame [m]."""

    xyz: Vec3


@dataclasses.dataclass(frozen=True)
class PTranslate:
    """``p + v`` (``v`` in metres)."""

    p: PointExpr
    v: VectorExpr


@dataclasses.dataclass(frozen=True)
class PMid:
    """The midpoint of ``p`` and ``q``."""

    p: PointExpr
    q: PointExpr


@dataclasses.dataclass(frozen=True)
class VAxis:
    """A named unit axis of the signer frame; ``name`` is ``fwd``, ``back``, ``left``,
    ``right``, ``up`` or ``down`` (``lat(s)`` / ``lat(w)`` are resolved to left / right)."""

    xyz: Vec3
    name: str = ""


@dataclasses.dataclass(frozen=True)
class VLiteral:
    """A literal vector in the signer frame."""

    xyz: Vec3


@dataclasses.dataclass(frozen=True)
class VBoneAxis:
    """The current DIR or NRM axis of a bone (a unit vector in the signer frame)."""

    bone: BoneRef
    axis: Axis


@dataclasses.dataclass(frozen=True)
class VOpp:
    """``-v``."""

    v: VectorExpr


@dataclasses.dataclass(frozen=True)
class VScale:
    """``k v``."""

    v: VectorExpr
    k: float


@dataclasses.dataclass(frozen=True)
class VAdd:
    """The sum of ``terms`` (at least one)."""

    terms: tuple[VectorExpr, ...]


@dataclasses.dataclass(frozen=True)
class VCross:
    """The cross product ``a x b``."""

    a: VectorExpr
    b: VectorExpr


@dataclasses.dataclass(frozen=True)
class VFrom:
    """``q - p``: the vector from point ``p`` to point ``q``."""

    p: PointExpr
    q: PointExpr


@dataclasses.dataclass(frozen=True)
class VUnit:
    """``v / |v|`` (the zero vector when ``v`` is zero at run time)."""

    v: VectorExpr


PointExpr = PSite | PLiteral | PTranslate | PMid
VectorExpr = VAxis | VLiteral | VBoneAxis | VOpp | VScale | VAdd | VCross | VFrom | VUnit


# ---------------------------------------------------------------------------------------
# Transpath routes
# ---------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Straight:
    """A straight segment from the start position to the end position."""


@dataclasses.dataclass(frozen=True)
class Arc:
    """A circular arc through start, end and the chord midpoint displaced by ``bulge`` [m]."""

    bulge: VectorExpr


@dataclasses.dataclass(frozen=True)
class Circle:
    """``turns`` full circles about ``center`` in the plane of start, end and centre; when
    start = end (known only at run time) the plane is normal to ``normal``, which must then
    be given (the realizer checks)."""

    center: PointExpr
    turns: float = 1.0
    normal: VectorExpr | None = None


Route = Straight | Arc | Circle


# ---------------------------------------------------------------------------------------
# Constraints
# ---------------------------------------------------------------------------------------


def _empty() -> Mapping[str, Any]:
    return MappingProxyType({})


_ANN = {"default_factory": _empty, "compare": False}


@dataclasses.dataclass(frozen=True)
class Place:
    """Body ``site`` at point ``at``, within ``tol`` [m]."""

    TYPE: ClassVar[str] = "place"
    site: SiteRef
    at: PointExpr
    tol: float = DEFAULT_TOL
    index: int = 0  #: 1-based position in its block's ``constraints``
    annotations: Mapping[str, Any] = dataclasses.field(**_ANN)  # type: ignore[call-overload]


@dataclasses.dataclass(frozen=True)
class Orient:
    """``bone``'s ``axis`` along / opposite / perpendicular to ``vector``, within ``tol``
    [rad]."""

    TYPE: ClassVar[str] = "orient"
    bone: BoneRef
    axis: Axis
    rel: Rel
    vector: VectorExpr
    tol: float = math.radians(DEFAULT_TOL_DEG)
    index: int = 0
    annotations: Mapping[str, Any] = dataclasses.field(**_ANN)  # type: ignore[call-overload]


@dataclasses.dataclass(frozen=True)
class MorphC:
    """Morph ``id`` at ``weight``; ``side`` is ``"L"``/``"R"`` (resolved) or None (both
    sides, or a morph without sides)."""

    TYPE: ClassVar[str] = "morph"
    id: str
    weight: float
    side: str | None = None
    index: int = 0
    annotations: Mapping[str, Any] = dataclasses.field(**_ANN)  # type: ignore[call-overload]


@dataclasses.dataclass(frozen=True)
class Look:
    """Both eyes' DIR point at ``at``."""

    TYPE: ClassVar[str] = "look"
    at: PointExpr
    index: int = 0
    annotations: Mapping[str, Any] = dataclasses.field(**_ANN)  # type: ignore[call-overload]


@dataclasses.dataclass(frozen=True)
class Trill:
    """``amplitude * sin(2 pi frequency t)`` on the posture: exactly one of ``site``
    (displaced along ``vector``, ``amplitude`` [m]) and ``bone`` (rotated about ``vector``,
    ``amplitude`` [rad]) is set; ``frequency`` [Hz]."""

    TYPE: ClassVar[str] = "trill"
    site: SiteRef | None
    bone: BoneRef | None
    vector: VectorExpr
    amplitude: float
    frequency: float
    index: int = 0
    annotations: Mapping[str, Any] = dataclasses.field(**_ANN)  # type: ignore[call-overload]


Constraint = Place | Orient | MorphC | Look | Trill
#: The ``type`` of each constraint record, in the order messages list them.
CONSTRAINT_TYPES = ("place", "orient", "morph", "look", "trill")


# ---------------------------------------------------------------------------------------
# Blocks and score
# ---------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Block:
    """One block with absolute times [s] from the root's start.

    Attributes:
      name: its name among its siblings.
      path: its dotted full name from the root (the root's path is its name).
      kind: sync (``children``), cstr (``constraints``), hold (``hold_of``) or transpath
        (``transpath_site`` and ``route``); the fields of other kinds are empty / None.
      hold_of: dotted path of the sibling block whose final posture a hold keeps.
    """

    name: str
    path: str
    kind: BlockKind
    start: float
    end: float
    children: tuple[Block, ...] = ()
    constraints: tuple[Constraint, ...] = ()
    hold_of: str | None = None
    transpath_site: SiteRef | None = None
    route: Route | None = None
    annotations: Mapping[str, Any] = dataclasses.field(**_ANN)  # type: ignore[call-overload]

    @property
    def duration(self) -> float:
        """``end - start`` [s]."""
        return self.end - self.start

    def blocks(self) -> Iterator[Block]:
        """This block and all its descendants, depth first (parents before children)."""
        yield self
        for child in self.children:
            yield from child.blocks()


@dataclasses.dataclass(frozen=True)
class Score:
    """A validated score: ``strong_side`` is ``"R"`` or ``"L"``; ``annotations`` holds the
    top-level ``x-*`` keys."""

    strong_side: str
    root: Block
    annotations: Mapping[str, Any] = dataclasses.field(**_ANN)  # type: ignore[call-overload]

    @property
    def duration(self) -> float:
        """The root's duration [s]; frames cover ``[0, duration]``."""
        return self.root.duration

    def blocks(self) -> Iterator[Block]:
        """Every block, depth first (parents before children), with absolute times."""
        return self.root.blocks()

    def at_tempo(self, tempo: float) -> Score:
        """This score played ``tempo`` times as fast: every block's start and end [s]
        divided by ``tempo`` (a trill keeps its frequency)."""

        def scaled(b: Block) -> Block:
            kids = tuple(scaled(c) for c in b.children)
            start, end = exact_time(b.start / tempo), exact_time(b.end / tempo)
            return dataclasses.replace(b, start=start, end=end, children=kids)

        return dataclasses.replace(self, root=scaled(self.root))

    def shifted(self, by: float) -> Score:
        """This score with every block ``by`` seconds later (its times on the clock of a
        rollout whose score starts at ``by`` [s])."""

        def moved(b: Block) -> Block:
            kids = tuple(moved(c) for c in b.children)
            start, end = exact_time(b.start + by), exact_time(b.end + by)
            return dataclasses.replace(b, start=start, end=end, children=kids)

        return dataclasses.replace(self, root=moved(self.root))

    def block(self, path: str) -> Block:
        """The block with dotted path ``path`` (KeyError if none)."""
        for b in self.blocks():
            if b.path == path:
                return b
        raise KeyError(path)
