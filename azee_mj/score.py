"""Load and validate an AZee score (``azee-score`` version 1) into immutable records.

The input contract is the project's score-format document (``azee-score`` version 1):
nested, timed blocks (``sync``, ``cstr``, ``hold``, ``transpath``) whose leaves are
articulation constraints (``place``, ``orient``, ``morph``, ``look``, ``trill``).
:func:`load_score` reads a JSON file or an already-parsed dict, checks *everything*, and
returns a :class:`Score`; a bad score raises :class:`~azee_mj.errors.ScoreError` before
anything is solved.

Conventions of the records:

- Times are **absolute** seconds from the root block's start: the file's relative times are
  added up at load time (the root spans ``[0, root.end - root.start]``). Intervals are
  half-open ``[start, end)`` [s].
- Angles are radians (``Orient.tol``, a bone ``Trill.amplitude``); degrees exist only in the
  JSON (fields ending in ``_deg``). Lengths are metres, frequencies hertz.
- References are resolved with the score's strong side: ``@I_TIP(s)`` becomes
  ``SiteRef("I_TIP_R")``, ``!index(s,2)`` becomes ``BoneRef("index_R_2")``, ``lat(s)``
  becomes ``VAxis((0, -1, 0), "right")`` when the strong side is ``R`` (``+y`` is the
  signer's left). Records keep AZee names; :meth:`SiteRef.model_site` and
  :meth:`BoneRef.model_body` map them onto a model with a :class:`~azee_mj.sites.SignerMap`.
- Point and vector expressions are small frozen records evaluated by :func:`eval_point`
  and :func:`eval_vector` on callables that read the current posture (pure numpy).

Error messages are one line::

    <dotted block path>: <where in the block>: <what is wrong>; <what is valid>

e.g. ``ROOT.K1: constraint 1 (place): unknown site 'I_TPI_R'; did you mean 'I_TIP_R'?
(azee-mj sites lists all)`` or ``ROOT.K1: field 'start': expected a number, got "0.4"``.
Errors outside any block start with ``score``; a block whose name is not known yet is
located by its parent and position (``ROOT: child 2: ...``, ``score: root block: ...``).
Inside a constraint the offending field is named (``field 'at.translate'``), except its
subject (its ``site`` or ``bone``), which the constraint itself names. ``ScoreError.path``
is the dotted block path ('' above the root) and ``ScoreError.field`` the offending key
(dotted inside expressions and transpath paths, e.g. ``at.mid[2]``, ``path.bulge``).
**Every index in a message is 1-based**: ``constraint 1`` is the first constraint of its
block, ``child 2`` the second block of a ``children`` list, and ``at.mid[1]`` the first
item of a list inside an expression. Lists of more than 8 valid names are abbreviated.

Beyond the format document, the loader also rejects (documented extensions): block names
that are empty or contain ``.`` (they would break dotted paths), a ``hold`` that starts
before the block it holds has ended (it keeps the posture reached at that end), a locus
where a moving body site is needed (``place``/``trill``/``transpath`` ``site``), duplicate
keys in a JSON object, and non-finite numbers. A literal full name (``@I_TIP_R``,
``!index_R_2``) is accepted as the absolute-side spelling of ``@I_TIP(R)``.
"""

from __future__ import annotations

import dataclasses
import enum
import json
import math
import re
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from types import MappingProxyType
from typing import Any, ClassVar, Union

import numpy as np

from azee_mj.errors import ScoreError
from azee_mj.sites import (
    DEFAULT_MAP,
    DIGIT_STEMS,
    DIGITS,
    LATERAL_STEMS,
    MIDLINE_STEMS,
    PHALANX_STEMS,
    BoneMap,
    SignerMap,
    azee_bone_names,
    resolve_side,
    suggest,
)

__all__ = [
    "FORMAT",
    "VERSION",
    "DEFAULT_TOL",
    "DEFAULT_TOL_DEG",
    "TIME_SLACK",
    "BlockKind",
    "Axis",
    "Rel",
    "SiteRef",
    "BoneRef",
    "PSite",
    "PLiteral",
    "PTranslate",
    "PMid",
    "PointExpr",
    "VAxis",
    "VLiteral",
    "VBoneAxis",
    "VOpp",
    "VScale",
    "VAdd",
    "VCross",
    "VFrom",
    "VUnit",
    "VectorExpr",
    "Straight",
    "Arc",
    "Circle",
    "Route",
    "Place",
    "Orient",
    "MorphC",
    "Look",
    "Trill",
    "Constraint",
    "Block",
    "Score",
    "load_score",
    "eval_point",
    "eval_vector",
    "depends_on_body",
    "referenced_sites",
    "referenced_bones",
    "NAMED_DIRECTIONS",
]

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
_SIDE_WORD = {"R": "right", "L": "left"}
_MAX_LISTED = 8


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


PointExpr = Union[PSite, PLiteral, PTranslate, PMid]
VectorExpr = Union[VAxis, VLiteral, VBoneAxis, VOpp, VScale, VAdd, VCross, VFrom, VUnit]

SitePos = Callable[[SiteRef], np.ndarray]
BoneAxisFn = Callable[[BoneRef, Axis], np.ndarray]


def eval_point(expr: PointExpr, site_pos: SitePos, bone_axis: BoneAxisFn) -> np.ndarray:
    """The value (3,) [m] of a point expression in the signer frame.

    ``site_pos(ref)`` gives a site's or locus' position (3,) and ``bone_axis(bone, axis)``
    a bone's unit DIR / NRM axis (3,), both in the signer frame on the posture at hand.
    """
    if isinstance(expr, PSite):
        return np.asarray(site_pos(expr.ref), dtype=float).reshape(3)
    if isinstance(expr, PLiteral):
        return np.array(expr.xyz, dtype=float)
    if isinstance(expr, PTranslate):
        return eval_point(expr.p, site_pos, bone_axis) + eval_vector(expr.v, site_pos, bone_axis)
    if isinstance(expr, PMid):
        p = eval_point(expr.p, site_pos, bone_axis)
        return 0.5 * (p + eval_point(expr.q, site_pos, bone_axis))
    raise TypeError(f"not a point expression: {expr!r}")


def eval_vector(expr: VectorExpr, site_pos: SitePos, bone_axis: BoneAxisFn) -> np.ndarray:
    """The value (3,) of a vector expression in the signer frame (see :func:`eval_point`).

    ``VUnit`` of a zero vector evaluates to zero; callers that need a direction check the
    norm (constant zero directions are already rejected by :func:`load_score`).
    """
    if isinstance(expr, (VAxis, VLiteral)):
        return np.array(expr.xyz, dtype=float)
    if isinstance(expr, VBoneAxis):
        return np.asarray(bone_axis(expr.bone, expr.axis), dtype=float).reshape(3)
    if isinstance(expr, VOpp):
        return -eval_vector(expr.v, site_pos, bone_axis)
    if isinstance(expr, VScale):
        return expr.k * eval_vector(expr.v, site_pos, bone_axis)
    if isinstance(expr, VAdd):
        total = np.zeros(3)
        for term in expr.terms:
            total = total + eval_vector(term, site_pos, bone_axis)
        return total
    if isinstance(expr, VCross):
        a = eval_vector(expr.a, site_pos, bone_axis)
        return np.cross(a, eval_vector(expr.b, site_pos, bone_axis))
    if isinstance(expr, VFrom):
        p = eval_point(expr.p, site_pos, bone_axis)
        return eval_point(expr.q, site_pos, bone_axis) - p
    if isinstance(expr, VUnit):
        v = eval_vector(expr.v, site_pos, bone_axis)
        n = float(np.linalg.norm(v))
        return v / n if n > 0.0 else np.zeros(3)
    raise TypeError(f"not a vector expression: {expr!r}")


def _children(expr: PointExpr | VectorExpr) -> tuple[PointExpr | VectorExpr, ...]:
    if isinstance(expr, (PTranslate,)):
        return (expr.p, expr.v)
    if isinstance(expr, (PMid, VFrom)):
        return (expr.p, expr.q)
    if isinstance(expr, (VOpp, VScale, VUnit)):
        return (expr.v,)
    if isinstance(expr, VAdd):
        return expr.terms
    if isinstance(expr, VCross):
        return (expr.a, expr.b)
    return ()


def _walk(expr: PointExpr | VectorExpr) -> Iterator[PointExpr | VectorExpr]:
    yield expr
    for child in _children(expr):
        yield from _walk(child)


def depends_on_body(expr: PointExpr | VectorExpr) -> bool:
    """Whether the expression reads the posture (any site, locus or bone axis in it)."""
    return any(isinstance(e, (PSite, VBoneAxis)) for e in _walk(expr))


def referenced_sites(expr: PointExpr | VectorExpr) -> tuple[SiteRef, ...]:
    """The sites and loci an expression reads, each once, in order of appearance."""
    return tuple(dict.fromkeys(e.ref for e in _walk(expr) if isinstance(e, PSite)))


def referenced_bones(expr: PointExpr | VectorExpr) -> tuple[BoneRef, ...]:
    """The bones whose axes an expression reads, each once, in order of appearance."""
    return tuple(dict.fromkeys(e.bone for e in _walk(expr) if isinstance(e, VBoneAxis)))


def _no_site(ref: SiteRef) -> np.ndarray:
    raise AssertionError(f"constant expression read site {ref}")


def _no_bone(bone: BoneRef, axis: Axis) -> np.ndarray:
    raise AssertionError(f"constant expression read bone {bone}")


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


Route = Union[Straight, Arc, Circle]


# ---------------------------------------------------------------------------------------
# Constraints
# ---------------------------------------------------------------------------------------


def _empty() -> Mapping[str, Any]:
    return MappingProxyType({})


_ANN = dict(default_factory=_empty, compare=False)


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


Constraint = Union[Place, Orient, MorphC, Look, Trill]
_CONSTRAINT_TYPES = ("place", "orient", "morph", "look", "trill")


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

    def block(self, path: str) -> Block:
        """The block with dotted path ``path`` (KeyError if none)."""
        for b in self.blocks():
            if b.path == path:
                return b
        raise KeyError(path)


# ---------------------------------------------------------------------------------------
# Loading
# ---------------------------------------------------------------------------------------


def load_score(
    source: str | Path | Mapping[str, Any], signer_map: SignerMap = DEFAULT_MAP
) -> Score:
    """Read, validate and resolve a score.

    Args:
      source: a path (``str`` / ``Path``) to a JSON file, or an already-parsed JSON object.
      signer_map: the vocabulary that site, bone, locus and morph names are checked against.

    Raises:
      ScoreError: the file cannot be read, is not JSON, or the score is not valid (one line
        naming the block path, the place, what is wrong and what is valid).
    """
    if isinstance(source, (str, Path)):
        data = _read_json(Path(source))
    else:
        data = source
    return _Loader(signer_map).score(data)


def _read_json(path: Path) -> Any:
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as e:
        raise ScoreError(f"{path}: cannot read the score: {e.strerror or e}") from None
    except UnicodeDecodeError as e:
        raise ScoreError(f"{path}: not a UTF-8 text file: {e.reason}") from None

    def pairs(items: list[tuple[str, Any]]) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for k, v in items:
            if k in out:
                raise _DuplicateKey(k)
            out[k] = v
        return out

    def bad_constant(name: str) -> Any:
        raise _BadConstant(name)

    try:
        return json.loads(text, object_pairs_hook=pairs, parse_constant=bad_constant)
    except json.JSONDecodeError as e:
        raise ScoreError(
            f"{path}: line {e.lineno} column {e.colno}: invalid JSON: {e.msg}"
        ) from None
    except _DuplicateKey as e:
        raise ScoreError(
            f"{path}: invalid score JSON: key '{e.args[0]}' appears twice in one object; "
            "each key may appear once"
        ) from None
    except _BadConstant as e:
        raise ScoreError(
            f"{path}: invalid JSON: {e.args[0]} is not a JSON number; use a finite number"
        ) from None


class _DuplicateKey(Exception):
    pass


class _BadConstant(Exception):
    pass


def _listing(names: Any, quote: bool = False) -> str:
    """``a, b, c`` or, beyond 8 names, ``a, ..., h, ..., and N more``."""
    names = [f"'{n}'" if quote else str(n) for n in names]
    if len(names) <= _MAX_LISTED:
        return ", ".join(names)
    return ", ".join(names[:_MAX_LISTED]) + f", ..., and {len(names) - _MAX_LISTED} more"


def _got(value: Any) -> str:
    """A value as the user wrote it (JSON), shortened."""
    try:
        text = json.dumps(value, ensure_ascii=False)
    except (TypeError, ValueError):
        text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _num(x: float) -> str:
    return f"{x:.10g}"


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _freeze(v: Any) -> Any:
    if isinstance(v, Mapping):
        return MappingProxyType({k: _freeze(x) for k, x in v.items()})
    if isinstance(v, (list, tuple)):
        return tuple(_freeze(x) for x in v)
    return v


_REF_RE = re.compile(r"^([A-Za-z][A-Za-z0-9_]*)(?:\(([^()]*)\))?$")
_LAT_RE = re.compile(r"^lat\(\s*([^()]*?)\s*\)$")

#: Site stems by the arguments they take.
_MIDLINE_SITE_STEMS = frozenset(MIDLINE_STEMS)
_LATERAL_SITE_STEMS = frozenset(LATERAL_STEMS) | {
    f"{d}_{s}" for d in DIGITS for s in DIGIT_STEMS
}
_PHALANX_SITE_STEMS = frozenset(f"{d}_{s}" for d in DIGITS for s in PHALANX_STEMS)


def _bone_stems() -> tuple[frozenset[str], frozenset[str], frozenset[str]]:
    midline, sided, phalanx = set(), set(), set()
    for name in azee_bone_names():
        if m := re.fullmatch(r"(.+)_[LR]_\d", name):
            phalanx.add(m.group(1))
        elif m := re.fullmatch(r"(.+)_[LR]", name):
            sided.add(m.group(1))
        else:
            midline.add(name)
    return frozenset(midline), frozenset(sided), frozenset(phalanx)


_MIDLINE_BONES, _SIDED_BONE_STEMS, _PHALANX_BONE_STEMS = _bone_stems()

_TOP_KEYS = ("format", "version", "strong_side", "root")
_TOP_REQUIRED = ("format", "version", "root")
_BLOCK_COMMON = ("name", "kind", "start", "end")
_BLOCK_KEYS = {
    BlockKind.SYNC: _BLOCK_COMMON + ("children",),
    BlockKind.CSTR: _BLOCK_COMMON + ("constraints",),
    BlockKind.HOLD: _BLOCK_COMMON + ("of",),
    BlockKind.TRANSPATH: _BLOCK_COMMON + ("site", "path"),
}
_CONSTRAINT_KEYS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    # type -> (required, optional)
    "place": (("type", "site", "at"), ("tol",)),
    "orient": (("type", "bone", "axis", "rel", "vector"), ("tol_deg",)),
    "morph": (("type", "id", "weight"), ("side",)),
    "look": (("type", "at"), ()),
    "trill": (
        ("type", "vector", "frequency"),
        ("site", "bone", "amplitude", "amplitude_deg"),
    ),
}
_SHAPE_KEYS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "straight": (("shape",), ()),
    "arc": (("shape", "bulge"), ()),
    "circle": (("shape", "center"), ("turns", "normal")),
}
_ARTICLE = {
    "place": "a place",
    "orient": "an orient",
    "morph": "a morph",
    "look": "a look",
    "trill": "a trill",
    "straight": "a straight",
    "arc": "an arc",
    "circle": "a circle",
}

# Expression forms: head key -> all keys of the form.
_POINT_FORMS = {"translate": ("translate", "by"), "mid": ("mid",)}
_VECTOR_FORMS = {
    "dir": ("dir",),
    "nrm": ("nrm",),
    "opp": ("opp",),
    "scale": ("scale", "by"),
    "add": ("add",),
    "cross": ("cross",),
    "from": ("from", "to"),
    "unit": ("unit",),
}
_POINT_DESC = (
    'a point ("@SITE", "^locus", [x, y, z], {"translate": P, "by": V} or {"mid": [P, Q]})'
)
_VECTOR_DESC = (
    'a vector (fwd, back, left, right, up, down, lat(s), lat(w), [x, y, z], or one of '
    '{"dir"|"nrm": BONE}, {"opp": V}, {"scale": V, "by": k}, {"add": [V, ...]}, '
    '{"cross": [V1, V2]}, {"from": P, "to": Q}, {"unit": V})'
)
_VALID_SIDES = "valid sides are s, w, L, R"
_SITES_HINT = "(azee-mj sites lists all)"


@dataclasses.dataclass(frozen=True)
class _Loc:
    """Where in the score: block path ('' above the root) and a place inside it."""

    path: str
    where: str = ""
    #: fields not named in messages (a constraint's subject: its ``site`` / ``bone``)
    unnamed: frozenset[str] = frozenset()

    def fail(
        self, what: str, valid: str = "", field: str = "", show_field: bool = True
    ) -> ScoreError:
        """The error; ``field`` is named in the message unless ``show_field`` is false (the
        message then names it itself) or it is one of ``unnamed``."""
        parts = [self.path or "score", self.where]
        if field and show_field and field not in self.unnamed:
            parts.append(f"field '{field}'")
        parts.append(what)
        message = ": ".join(p for p in parts if p)
        if valid:
            message += "; " + valid
        return ScoreError(message, path=self.path, field=field)


class _Loader:
    def __init__(self, signer_map: SignerMap):
        self.map = signer_map
        self.strong = "R"

    # -- generic checks ------------------------------------------------------------------

    def keys(
        self,
        loc: _Loc,
        obj: Mapping[str, Any],
        required: tuple[str, ...],
        optional: tuple[str, ...],
        what: str,
        order: tuple[str, ...] = (),
        prefix: str = "",
    ) -> Mapping[str, Any]:
        """Check keys (x-* allowed); return the x-* annotations. ``order`` lists the valid
        keys in the order messages show them (default: required, then optional)."""
        valid = order or required + optional
        for key in obj:
            if isinstance(key, str) and key.startswith("x-"):
                continue
            if key not in valid:
                for_what = f" for {what}" if what else ""
                raise loc.fail(
                    f"unknown key '{key}'",
                    f"valid keys{for_what} are {', '.join(valid)} (and x-* annotations)"
                    + suggest(str(key), valid),
                    field=f"{prefix}{key}",
                    show_field=False,
                )
        for key in required:
            if key not in obj:
                raise loc.fail(
                    f"missing field '{key}'",
                    f"{what or 'a score'} needs {', '.join(required)}",
                    field=f"{prefix}{key}",
                    show_field=False,
                )
        return _freeze({k: v for k, v in obj.items() if isinstance(k, str) and k.startswith("x-")})

    def number(self, loc: _Loc, field: str, v: Any) -> float:
        if not _is_number(v):
            raise loc.fail(f"expected a number, got {_got(v)}", field=field)
        if not math.isfinite(v):
            raise loc.fail(f"expected a finite number, got {_got(v)}", field=field)
        return float(v)

    def positive(self, loc: _Loc, field: str, v: Any) -> float:
        x = self.number(loc, field, v)
        if x <= 0:
            raise loc.fail(f"must be positive, got {_got(v)}", field=field)
        return x

    def string(self, loc: _Loc, field: str, v: Any) -> str:
        if not isinstance(v, str):
            raise loc.fail(f"expected a string, got {_got(v)}", field=field)
        return v

    def side(self, loc: _Loc, field: str, side: str, written: str) -> str:
        try:
            return resolve_side(side, self.strong)
        except ValueError:
            in_ = f" in '{written}'" if written != side else ""
            raise loc.fail(f"unknown side '{side}'{in_}", _VALID_SIDES, field=field) from None

    # -- top level -----------------------------------------------------------------------

    def score(self, data: Any) -> Score:
        loc = _Loc("")
        if not isinstance(data, Mapping):
            raise loc.fail(f"expected a JSON object at the top level, got {_got(data)}")
        annotations = self.keys(loc, data, _TOP_REQUIRED, ("strong_side",), "", _TOP_KEYS)
        fmt = data["format"]
        if fmt != FORMAT:
            raise loc.fail(f'expected "{FORMAT}", got {_got(fmt)}', field="format")
        version = data["version"]
        if not _is_number(version):
            raise loc.fail(f"expected a number, got {_got(version)}", field="version")
        if version != VERSION:
            raise loc.fail(
                f"unsupported version {_got(version)}",
                f"this reader reads version {VERSION}",
                field="version",
            )
        strong = data.get("strong_side", "R")
        if strong not in ("R", "L"):
            raise loc.fail(f'expected "R" or "L", got {_got(strong)}', field="strong_side")
        self.strong = strong
        root = self.block(data["root"], _Loc("", "root block"), "", 0.0, None)
        if root.kind is BlockKind.HOLD:
            raise _Loc(root.path).fail(
                f"no sibling block named '{data['root']['of']}'",
                "the root block has no siblings to hold",
                field="of",
            )
        return Score(strong_side=strong, root=root, annotations=annotations)

    # -- blocks --------------------------------------------------------------------------

    def block(
        self,
        obj: Any,
        pre: _Loc,
        parent_path: str,
        parent_abs: float,
        parent_dur: float | None,
    ) -> Block:
        """Parse one block. ``pre`` locates it before its name is known; ``parent_dur`` is
        None for the root."""
        if not isinstance(obj, Mapping):
            raise pre.fail(f"expected a block (a JSON object), got {_got(obj)}")
        if "name" not in obj:
            raise pre.fail(
                "missing field 'name'", "a block needs name, kind, start, end",
                field="name", show_field=False,
            )  # fmt: skip
        name = self.string(pre, "name", obj["name"])
        if not name:
            raise pre.fail("a block name cannot be empty", field="name")
        if "." in name:
            raise pre.fail(
                f"block name '{name}' contains '.'",
                "block paths join names with '.', so use another character",
                field="name",
            )
        path = f"{parent_path}.{name}" if parent_path else name
        loc = _Loc(path)
        if "kind" not in obj:
            raise loc.fail(
                "missing field 'kind'", "a block needs name, kind, start, end",
                field="kind", show_field=False,
            )  # fmt: skip
        kind_s = self.string(loc, "kind", obj["kind"])
        kinds = [k.value for k in BlockKind]
        if kind_s not in kinds:
            raise loc.fail(
                f"unknown block kind '{kind_s}'",
                f"valid kinds are {', '.join(kinds)}" + suggest(kind_s, kinds),
                field="kind",
            )
        kind = BlockKind(kind_s)
        annotations = self.keys(loc, obj, _BLOCK_KEYS[kind], (), f"a {kind_s} block")
        start = self.number(loc, "start", obj["start"])
        end = self.number(loc, "end", obj["end"])
        if not start < end:
            raise loc.fail(
                f"end {_got(obj['end'])} is not after start {_got(obj['start'])}",
                "a block needs start < end",
                field="end",
            )
        if parent_dur is None:
            abs_start, abs_end = 0.0, end - start
        else:
            inside = (
                "a child's times are relative to its parent's start and lie within "
                f"[0, {_num(parent_dur)}]"
            )
            if start < -TIME_SLACK:
                raise loc.fail(
                    f"{_got(obj['start'])} is before the start of its parent {parent_path}",
                    inside,
                    field="start",
                )
            if end > parent_dur + TIME_SLACK:
                raise loc.fail(
                    f"{_got(obj['end'])} is after the end of its parent {parent_path}",
                    inside,
                    field="end",
                )
            abs_start, abs_end = parent_abs + start, parent_abs + end
        fields: dict[str, Any] = {}
        if kind is BlockKind.SYNC:
            fields["children"] = self.children(loc, obj["children"], abs_start, end - start)
        elif kind is BlockKind.CSTR:
            fields["constraints"] = self.constraints(loc, obj["constraints"])
        elif kind is BlockKind.HOLD:
            of = self.string(loc, "of", obj["of"])
            fields["hold_of"] = f"{parent_path}.{of}" if parent_path else of
        else:
            fields["transpath_site"] = self.body_site(loc, "site", obj["site"], "a transpath")
            fields["route"] = self.route(loc, obj["path"])
        return Block(
            name=name,
            path=path,
            kind=kind,
            start=abs_start,
            end=abs_end,
            annotations=annotations,
            **fields,
        )

    def children(self, loc: _Loc, items: Any, abs_start: float, dur: float) -> tuple[Block, ...]:
        if not isinstance(items, (list, tuple)):
            raise loc.fail(f"expected a list of blocks, got {_got(items)}", field="children")
        blocks: list[Block] = []
        seen: dict[str, int] = {}
        for i, item in enumerate(items, 1):
            child = self.block(item, _Loc(loc.path, f"child {i}"), loc.path, abs_start, dur)
            if child.name in seen:
                raise _Loc(loc.path, f"child {i}").fail(
                    f"duplicate name '{child.name}' (child {seen[child.name]} has it too)",
                    "sibling names must be unique",
                    field="name",
                )
            seen[child.name] = i
            blocks.append(child)
        by_name = {b.name: b for b in blocks}
        for b in blocks:
            if b.kind is not BlockKind.HOLD:
                continue
            of = (b.hold_of or "")[len(loc.path) + 1 :]
            hloc = _Loc(b.path)
            others = [n for n in by_name if n != b.name]
            if of == b.name:
                raise hloc.fail(
                    f"'{of}' is this hold itself",
                    f"a hold names a sibling block: {_listing(others)}"
                    if others
                    else "a hold names a sibling block, and this block has none",
                    field="of",
                )
            if of not in by_name:
                raise hloc.fail(
                    f"no sibling block named '{of}'",
                    (f"siblings are {_listing(others)}" + suggest(of, others))
                    if others
                    else "this block has no siblings",
                    field="of",
                )
            held = by_name[of]
            if held.end > b.start + TIME_SLACK:
                raise hloc.fail(
                    f"'{of}' ends at {_num(held.end - abs_start)} s, after this hold starts"
                    f" at {_num(b.start - abs_start)} s",
                    "a hold keeps the posture reached at the end of the block it holds, "
                    "so it starts at or after that end",
                    field="of",
                )
        return tuple(blocks)

    # -- constraints ---------------------------------------------------------------------

    def constraints(self, loc: _Loc, items: Any) -> tuple[Constraint, ...]:
        if not isinstance(items, (list, tuple)):
            raise loc.fail(
                f"expected a list of constraints, got {_got(items)}", field="constraints"
            )
        return tuple(self.constraint(loc.path, i, item) for i, item in enumerate(items, 1))

    def constraint(self, path: str, index: int, obj: Any) -> Constraint:
        pre = _Loc(path, f"constraint {index}")
        if not isinstance(obj, Mapping):
            raise pre.fail(f"expected a constraint (a JSON object), got {_got(obj)}")
        types = ", ".join(_CONSTRAINT_TYPES)
        if "type" not in obj:
            raise pre.fail(
                "missing field 'type'", f"valid types are {types}", field="type", show_field=False
            )
        ctype = self.string(pre, "type", obj["type"])
        if ctype not in _CONSTRAINT_TYPES:
            raise pre.fail(
                f"unknown constraint type '{ctype}'",
                f"valid types are {types}" + suggest(ctype, _CONSTRAINT_TYPES),
                field="type",
            )
        loc = _Loc(path, f"constraint {index} ({ctype})", frozenset({"site", "bone"}))
        required, optional = _CONSTRAINT_KEYS[ctype]
        ann = self.keys(loc, obj, required, optional, f"{_ARTICLE[ctype]} constraint")
        common = dict(index=index, annotations=ann)
        if ctype == "place":
            return Place(
                site=self.body_site(loc, "site", obj["site"], "a place"),
                at=self.point(loc, "at", obj["at"]),
                tol=self.positive(loc, "tol", obj["tol"]) if "tol" in obj else DEFAULT_TOL,
                **common,
            )
        if ctype == "orient":
            tol_deg = (
                self.positive(loc, "tol_deg", obj["tol_deg"])
                if "tol_deg" in obj
                else DEFAULT_TOL_DEG
            )
            return Orient(
                bone=self.bone(loc, "bone", obj["bone"]),
                axis=self.enum(loc, "axis", obj["axis"], Axis, "axis", "axes"),
                rel=self.enum(loc, "rel", obj["rel"], Rel, "relation", "relations"),
                vector=self.direction(loc, "vector", obj["vector"]),
                tol=math.radians(tol_deg),
                **common,
            )
        if ctype == "morph":
            return self.morph(loc, obj, common)
        if ctype == "look":
            return Look(at=self.point(loc, "at", obj["at"]), **common)
        return self.trill(loc, obj, common)

    def enum(
        self, loc: _Loc, field: str, v: Any, cls: type[enum.Enum], noun: str, plural: str
    ) -> Any:
        s = self.string(loc, field, v)
        values = [m.value for m in cls]
        if s not in values:
            raise loc.fail(
                f"unknown {noun} '{s}'",
                f"valid {plural} are {', '.join(values)}" + suggest(s, values),
                field=field,
            )
        return cls(s)

    def morph(self, loc: _Loc, obj: Mapping[str, Any], common: dict[str, Any]) -> MorphC:
        mid = self.string(loc, "id", obj["id"])
        ids = list(self.map.morphs)
        if mid not in self.map.morphs:
            raise loc.fail(
                f"unknown morph '{mid}'",
                f"valid ids are {_listing(ids)}" + suggest(mid, ids),
                field="id",
            )
        weight = self.number(loc, "weight", obj["weight"])
        side = None
        if "side" in obj:
            written = self.string(loc, "side", obj["side"])
            side = self.side(loc, "side", written, written)
            if not self.map.morphs[mid].sided:
                raise loc.fail(
                    f"morph '{mid}' has no sides", "remove 'side'", field="side"
                )
        return MorphC(id=mid, weight=weight, side=side, **common)

    def trill(self, loc: _Loc, obj: Mapping[str, Any], common: dict[str, Any]) -> Trill:
        has_site, has_bone = "site" in obj, "bone" in obj
        if has_site == has_bone:
            what = "both 'site' and 'bone' given" if has_site else "missing field 'site' or 'bone'"
            raise loc.fail(
                what,
                "a trill moves a site (with 'amplitude' [m]) or turns a bone "
                "(with 'amplitude_deg')",
            )
        site = bone = None
        if has_site:
            site = self.body_site(loc, "site", obj["site"], "a trill")
            amp_key, wrong_key = "amplitude", "amplitude_deg"
        else:
            bone = self.bone(loc, "bone", obj["bone"])
            amp_key, wrong_key = "amplitude_deg", "amplitude"
        mover = "site" if has_site else "bone"
        unit = "metres" if has_site else "degrees"
        if wrong_key in obj:
            raise loc.fail(
                f"a {mover} trill takes '{amp_key}', not '{wrong_key}'",
                f"give '{amp_key}' in {unit}",
                field=wrong_key,
            )
        if amp_key not in obj:
            raise loc.fail(
                f"missing field '{amp_key}'", f"a {mover} trill needs its amplitude in {unit}",
                field=amp_key, show_field=False,
            )  # fmt: skip
        amplitude = self.positive(loc, amp_key, obj[amp_key])
        if bone is not None:
            amplitude = math.radians(amplitude)
        return Trill(
            site=site,
            bone=bone,
            vector=self.direction(loc, "vector", obj["vector"]),
            amplitude=amplitude,
            frequency=self.positive(loc, "frequency", obj["frequency"]),
            **common,
        )

    # -- transpath routes ----------------------------------------------------------------

    def route(self, loc: _Loc, obj: Any) -> Route:
        shapes = list(_SHAPE_KEYS)
        if not isinstance(obj, Mapping):
            raise loc.fail(
                f"expected a path (a JSON object with 'shape'), got {_got(obj)}", field="path"
            )
        ploc = _Loc(loc.path, "field 'path'")
        if "shape" not in obj:
            raise ploc.fail(
                "missing field 'shape'", f"valid shapes are {', '.join(shapes)}",
                field="path.shape", show_field=False,
            )  # fmt: skip
        shape = self.string(loc, "path.shape", obj["shape"])
        if shape not in _SHAPE_KEYS:
            raise loc.fail(
                f"unknown shape '{shape}'",
                f"valid shapes are {', '.join(shapes)}" + suggest(shape, shapes),
                field="path.shape",
            )
        required, optional = _SHAPE_KEYS[shape]
        self.keys(ploc, obj, required, optional, f"{_ARTICLE[shape]} path", prefix="path.")
        if shape == "straight":
            return Straight()
        if shape == "arc":
            return Arc(bulge=self.direction(loc, "path.bulge", obj["bulge"]))
        center = self.point(loc, "path.center", obj["center"])
        turns = self.positive(loc, "path.turns", obj["turns"]) if "turns" in obj else 1.0
        normal = self.direction(loc, "path.normal", obj["normal"]) if "normal" in obj else None
        return Circle(center=center, turns=turns, normal=normal)

    # -- references ----------------------------------------------------------------------

    def _parse_ref(self, loc: _Loc, field: str, text: str, kind: str, sigil: str):
        """Split ``STEM`` / ``STEM(side)`` / ``STEM(side,n)``: (stem, side, n)."""
        m = _REF_RE.match(text[1:])
        example = (
            "'@STEM', '@STEM(side)' or '@STEM(side,n)', e.g. '@FH', '@I_TIP(s)', '@I_KN(s,2)'"
            if sigil == "@"
            else "'!bone', '!bone(side)' or '!bone(side,n)', e.g. '!head', '!f_arm(s)', "
            "'!index(s,2)'"
        )
        if not m:
            raise loc.fail(f"malformed {kind} reference '{text}'", f"write {example}", field=field)
        stem, args = m.group(1), m.group(2)
        if args is None:
            return stem, None, None
        parts = [a.strip() for a in args.split(",")]
        if len(parts) > 2 or not parts[0]:
            raise loc.fail(f"malformed {kind} reference '{text}'", f"write {example}", field=field)
        side = self.side(loc, field, parts[0], text)
        n = None
        if len(parts) == 2:
            if parts[1] not in ("1", "2", "3"):
                raise loc.fail(
                    f"phalanx '{parts[1]}' in '{text}' is not 1, 2 or 3",
                    "phalanges are numbered 1 (proximal) to 3 (distal)",
                    field=field,
                )
            n = int(parts[1])
        return stem, side, n

    def _forms(self, sigil: str, stem: str, how: str) -> str:
        if how == "side":
            return ", ".join(f"'{sigil}{stem}({s})'" for s in "swR") + f" or '{sigil}{stem}(L)'"
        return f"e.g. '{sigil}{stem}(s,1)' (1 proximal to 3 distal)"

    def site_ref(self, loc: _Loc, field: str, text: str) -> SiteRef:
        """A body site ``@...`` or a locus ``^...``."""
        if text.startswith("^"):
            name = text[1:]
            loci = list(self.map.loci)
            if name not in self.map.loci:
                shown = [f"^{n}" for n in loci]
                raise loc.fail(
                    f"unknown locus '{text}'",
                    f"valid loci are {_listing(shown)}" + suggest(text, shown),
                    field=field,
                )
            return SiteRef(name, locus=True)
        stem, side, n = self._parse_ref(loc, field, text, "site", "@")
        sites = self.map.sites
        if side is None and stem in sites:
            return SiteRef(stem)
        if side is not None and stem in _MIDLINE_SITE_STEMS and stem not in _LATERAL_SITE_STEMS:
            raise loc.fail(
                f"site '{stem}' is on the midline and takes no side",
                f"write '@{stem}'",
                field=field,
            )
        if stem in _LATERAL_SITE_STEMS:
            if side is None:
                raise loc.fail(
                    f"site '{stem}' needs a side",
                    "write " + self._forms("@", stem, "side"),
                    field=field,
                )
            if n is not None:
                raise loc.fail(
                    f"site '{stem}' takes no phalanx number", f"write '@{stem}(s)'", field=field
                )
        if stem in _PHALANX_SITE_STEMS and (side is None or n is None):
            raise loc.fail(
                f"site '{stem}' needs a side and a phalanx number",
                "write " + self._forms("@", stem, "phalanx"),
                field=field,
            )
        name = stem + (f"_{side}" if side else "") + (f"_{n}" if n else "")
        if name not in sites:
            raise loc.fail(
                f"unknown site '{name}'", self._did_you_mean(name, list(sites)), field=field
            )
        return SiteRef(name)

    @staticmethod
    def _did_you_mean(name: str, valid: list[str]) -> str:
        hint = suggest(name, valid)
        if hint:
            return f"{hint[2:]} {_SITES_HINT}"
        return "azee-mj sites lists all valid names"

    def body_site(self, loc: _Loc, field: str, v: Any, user: str) -> SiteRef:
        if not isinstance(v, str) or not v.startswith(("@", "^")):
            raise loc.fail(
                f"expected a body site such as '@I_TIP(s)', got {_got(v)}", field=field
            )
        if v.startswith("^"):
            raise loc.fail(
                f"'{v}' is a signing-space locus, not a body site",
                f"{user} moves a body site ('@...')",
                field=field,
            )
        return self.site_ref(loc, field, v)

    def bone(self, loc: _Loc, field: str, v: Any) -> BoneRef:
        if not isinstance(v, str) or not v.startswith("!"):
            raise loc.fail(f"expected a bone such as '!f_arm(s)', got {_got(v)}", field=field)
        stem, side, n = self._parse_ref(loc, field, v, "bone", "!")
        bones = self.map.bones
        if side is None and stem in bones:
            return BoneRef(stem)
        if side is not None and stem in _MIDLINE_BONES:
            raise loc.fail(
                f"bone '{stem}' is on the midline and takes no side",
                f"write '!{stem}'",
                field=field,
            )
        if stem in _SIDED_BONE_STEMS:
            if side is None:
                raise loc.fail(
                    f"bone '{stem}' needs a side",
                    "write " + self._forms("!", stem, "side"),
                    field=field,
                )
            if n is not None:
                raise loc.fail(
                    f"bone '{stem}' takes no phalanx number", f"write '!{stem}(s)'", field=field
                )
        if stem in _PHALANX_BONE_STEMS and (side is None or n is None):
            raise loc.fail(
                f"bone '{stem}' needs a side and a phalanx number",
                "write " + self._forms("!", stem, "phalanx"),
                field=field,
            )
        name = stem + (f"_{side}" if side else "") + (f"_{n}" if n else "")
        if name not in bones:
            raise loc.fail(
                f"unknown bone '{name}'", self._did_you_mean(name, list(bones)), field=field
            )
        return BoneRef(name)

    # -- expressions ---------------------------------------------------------------------

    def xyz(self, loc: _Loc, field: str, v: list[Any] | tuple[Any, ...]) -> Vec3:
        if len(v) != 3 or not all(_is_number(x) for x in v):
            raise loc.fail(f"expected 3 numbers [x, y, z], got {_got(v)}", field=field)
        if not all(math.isfinite(x) for x in v):
            raise loc.fail(f"expected finite numbers, got {_got(v)}", field=field)
        return (float(v[0]), float(v[1]), float(v[2]))

    def form(
        self, loc: _Loc, field: str, obj: Mapping[str, Any], forms: dict[str, tuple[str, ...]],
        desc: str,
    ) -> str:  # fmt: skip
        """The head key of an expression object, after checking its keys."""
        known = [k for f in forms.values() for k in f]
        for key in obj:
            if key not in known:
                raise loc.fail(
                    f"unknown key '{key}' in {desc.split(' (')[0]}",
                    f"expected {desc}" + suggest(str(key), list(dict.fromkeys(known))),
                    field=field,
                )
        heads = [k for k in obj if k in forms]
        if len(heads) != 1:
            what = (
                f"{_got(obj)} mixes the forms "
                + " and ".join(f"'{h}'" for h in heads)
                if heads
                else f"{_got(obj)} is incomplete"
            )
            raise loc.fail(what, f"expected {desc}", field=field)
        head = heads[0]
        for key in obj:
            if key not in forms[head]:
                raise loc.fail(
                    f"key '{key}' does not belong with '{head}'",
                    f"expected {desc}",
                    field=field,
                )
        for key in forms[head]:
            if key not in obj:
                raise loc.fail(
                    f"'{head}' needs '{key}'", f"expected {desc}", field=field
                )
        return head

    def items(self, loc: _Loc, field: str, v: Any, n: int | None, what: str) -> list[Any]:
        if not isinstance(v, (list, tuple)) or (n is not None and len(v) != n) or not v:
            count = f"{n} {what}s" if n is not None else f"a list of one or more {what}s"
            raise loc.fail(f"expected {count}, got {_got(v)}", field=field)
        return v

    def point(self, loc: _Loc, field: str, v: Any) -> PointExpr:
        if isinstance(v, str):
            if v.startswith(("@", "^")):
                return PSite(self.site_ref(loc, field, v))
            if v in NAMED_DIRECTIONS or _LAT_RE.match(v):
                raise loc.fail(
                    f"'{v}' is a direction, not a point",
                    'use [x, y, z] or {"translate": P, "by": V}',
                    field=field,
                )
        if isinstance(v, (list, tuple)):
            return PLiteral(self.xyz(loc, field, v))
        if isinstance(v, Mapping):
            head = self.form(loc, field, v, _POINT_FORMS, _POINT_DESC)
            if head == "translate":
                return PTranslate(
                    self.point(loc, f"{field}.translate", v["translate"]),
                    self.vector(loc, f"{field}.by", v["by"]),
                )
            p, q = self.items(loc, f"{field}.mid", v["mid"], 2, "point")
            return PMid(
                self.point(loc, f"{field}.mid[1]", p), self.point(loc, f"{field}.mid[2]", q)
            )
        raise loc.fail(f"expected {_POINT_DESC}, got {_got(v)}", field=field)

    def vector(self, loc: _Loc, field: str, v: Any) -> VectorExpr:
        if isinstance(v, str):
            if v in NAMED_DIRECTIONS:
                return VAxis(NAMED_DIRECTIONS[v], v)
            if m := _LAT_RE.match(v):
                if m.group(1) not in ("s", "w"):
                    raise loc.fail(
                        f"unknown side '{m.group(1)}' in '{v}'",
                        "write lat(s) or lat(w), or left / right",
                        field=field,
                    )
                word = _SIDE_WORD[resolve_side(m.group(1), self.strong)]
                return VAxis(NAMED_DIRECTIONS[word], word)
            if v.startswith(("@", "^")):
                raise loc.fail(
                    f"'{v}' is a point, not a vector",
                    'use {"from": P, "to": Q} for the vector between two points',
                    field=field,
                )
            names = list(NAMED_DIRECTIONS) + ["lat(s)", "lat(w)"]
            raise loc.fail(
                f"unknown direction '{v}'",
                f"valid directions are {', '.join(names)}" + suggest(v, names),
                field=field,
            )
        if isinstance(v, (list, tuple)):
            return VLiteral(self.xyz(loc, field, v))
        if isinstance(v, Mapping):
            head = self.form(loc, field, v, _VECTOR_FORMS, _VECTOR_DESC)
            sub = f"{field}.{head}"
            if head in ("dir", "nrm"):
                return VBoneAxis(self.bone(loc, sub, v[head]), Axis(head))
            if head == "opp":
                return VOpp(self.vector(loc, sub, v["opp"]))
            if head == "scale":
                return VScale(
                    self.vector(loc, sub, v["scale"]), self.number(loc, f"{field}.by", v["by"])
                )
            if head == "add":
                terms = self.items(loc, sub, v["add"], None, "vector")
                return VAdd(
                    tuple(self.vector(loc, f"{sub}[{i}]", t) for i, t in enumerate(terms, 1))
                )
            if head == "cross":
                a, b = self.items(loc, sub, v["cross"], 2, "vector")
                return VCross(self.vector(loc, f"{sub}[1]", a), self.vector(loc, f"{sub}[2]", b))
            if head == "from":
                return VFrom(
                    self.point(loc, sub, v["from"]), self.point(loc, f"{field}.to", v["to"])
                )
            inner = self.vector(loc, sub, v["unit"])
            self.nonzero(loc, sub, inner, v["unit"], "cannot normalise the zero vector")
            return VUnit(inner)
        raise loc.fail(f"expected {_VECTOR_DESC}, got {_got(v)}", field=field)

    def nonzero(self, loc: _Loc, field: str, expr: VectorExpr, written: Any, what: str) -> None:
        if depends_on_body(expr):
            return
        value = eval_vector(expr, _no_site, _no_bone)
        if float(np.linalg.norm(value)) < ZERO_NORM:
            raise loc.fail(
                f"{what} {_got(written)}", "give a vector of non-zero length", field=field
            )

    def direction(self, loc: _Loc, field: str, v: Any) -> VectorExpr:
        expr = self.vector(loc, field, v)
        self.nonzero(loc, field, expr, v, "zero direction")
        return expr
