"""The expression grammar of a score: points and vectors, read from JSON into records.

A point is a site or locus (``"@SITE"``, ``"^locus"``), ``[x, y, z]`` [m], or one of the
forms ``{"translate": P, "by": V}`` and ``{"mid": [P, Q]}``; a vector is a named direction
(``fwd`` ... ``down``, ``lat(s)``, ``lat(w)``), ``[x, y, z]``, or one of the forms listed in
:data:`VECTOR_DESC`. :class:`ExpressionReader` reads them, naming the field (e.g.
``at.translate``) in every message.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from typing import Any

from azee_mj.score.records import (
    NAMED_DIRECTIONS,
    Axis,
    PLiteral,
    PMid,
    PointExpr,
    PSite,
    PTranslate,
    VAdd,
    VAxis,
    VBoneAxis,
    VCross,
    VectorExpr,
    VFrom,
    VLiteral,
    VOpp,
    VScale,
    VUnit,
)
from azee_mj.score.references import References
from azee_mj.score.validation import Loc, got, nonzero, number, xyz
from azee_mj.sites import resolve_side, suggest

_LAT_RE = re.compile(r"^lat\(\s*([^()]*?)\s*\)$")
_SIDE_WORD = {"R": "right", "L": "left"}

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
#: What a point may be, as messages say it.
POINT_DESC = 'a point ("@SITE", "^locus", [x, y, z], {"translate": P, "by": V} or {"mid": [P, Q]})'
#: What a vector may be, as messages say it.
VECTOR_DESC = (
    "a vector (fwd, back, left, right, up, down, lat(s), lat(w), [x, y, z], or one of "
    '{"dir"|"nrm": BONE}, {"opp": V}, {"scale": V, "by": k}, {"add": [V, ...]}, '
    '{"cross": [V1, V2]}, {"from": P, "to": Q}, {"unit": V})'
)


def form(
    loc: Loc, field: str, obj: Mapping[str, Any], forms: dict[str, tuple[str, ...]], desc: str
) -> str:
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
            f"{got(obj)} mixes the forms " + " and ".join(f"'{h}'" for h in heads)
            if heads
            else f"{got(obj)} is incomplete"
        )
        raise loc.fail(what, f"expected {desc}", field=field)
    head = heads[0]
    for key in obj:
        if key not in forms[head]:
            raise loc.fail(
                f"key '{key}' does not belong with '{head}'", f"expected {desc}", field=field
            )
    for key in forms[head]:
        if key not in obj:
            raise loc.fail(f"'{head}' needs '{key}'", f"expected {desc}", field=field)
    return head


def items(loc: Loc, field: str, v: Any, n: int | None, what: str) -> list[Any]:
    """The operands of a form: exactly ``n`` of them, or one or more if ``n`` is None."""
    if not isinstance(v, (list, tuple)) or (n is not None and len(v) != n) or not v:
        count = f"{n} {what}s" if n is not None else f"a list of one or more {what}s"
        raise loc.fail(f"expected {count}, got {got(v)}", field=field)
    return v


class ExpressionReader:
    """Reads point and vector expressions, resolving site, locus and bone names through
    ``refs`` (whose strong side turns ``lat(s)`` / ``lat(w)`` into left or right)."""

    def __init__(self, refs: References):
        self.refs = refs

    def point(self, loc: Loc, field: str, v: Any) -> PointExpr:
        """A point expression [m]."""
        if isinstance(v, str):
            if v.startswith(("@", "^")):
                return PSite(self.refs.site(loc, field, v))
            if v in NAMED_DIRECTIONS or _LAT_RE.match(v):
                raise loc.fail(
                    f"'{v}' is a direction, not a point",
                    'use [x, y, z] or {"translate": P, "by": V}',
                    field=field,
                )
        if isinstance(v, (list, tuple)):
            return PLiteral(xyz(loc, field, v))
        if isinstance(v, Mapping):
            head = form(loc, field, v, _POINT_FORMS, POINT_DESC)
            if head == "translate":
                return PTranslate(
                    self.point(loc, f"{field}.translate", v["translate"]),
                    self.vector(loc, f"{field}.by", v["by"]),
                )
            p, q = items(loc, f"{field}.mid", v["mid"], 2, "point")
            return PMid(
                self.point(loc, f"{field}.mid[1]", p), self.point(loc, f"{field}.mid[2]", q)
            )
        raise loc.fail(f"expected {POINT_DESC}, got {got(v)}", field=field)

    def vector(self, loc: Loc, field: str, v: Any) -> VectorExpr:
        """A vector expression (any length, zero included)."""
        if isinstance(v, str):
            return self.named(loc, field, v)
        if isinstance(v, (list, tuple)):
            return VLiteral(xyz(loc, field, v))
        if isinstance(v, Mapping):
            return self.compound(loc, field, v)
        raise loc.fail(f"expected {VECTOR_DESC}, got {got(v)}", field=field)

    def direction(self, loc: Loc, field: str, v: Any) -> VectorExpr:
        """A vector expression that is not constantly zero."""
        expr = self.vector(loc, field, v)
        nonzero(loc, field, expr, v, "zero direction")
        return expr

    def named(self, loc: Loc, field: str, v: str) -> VAxis:
        """A named direction: ``fwd`` ... ``down``, ``lat(s)`` or ``lat(w)``."""
        if v in NAMED_DIRECTIONS:
            return VAxis(NAMED_DIRECTIONS[v], v)
        if m := _LAT_RE.match(v):
            if m.group(1) not in ("s", "w"):
                raise loc.fail(
                    f"unknown side '{m.group(1)}' in '{v}'",
                    "write lat(s) or lat(w), or left / right",
                    field=field,
                )
            word = _SIDE_WORD[resolve_side(m.group(1), self.refs.strong)]
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

    def compound(self, loc: Loc, field: str, v: Mapping[str, Any]) -> VectorExpr:
        """A vector form: ``{"dir": BONE}``, ``{"opp": V}``, ``{"add": [V, ...]}``, ..."""
        head = form(loc, field, v, _VECTOR_FORMS, VECTOR_DESC)
        sub = f"{field}.{head}"
        if head in ("dir", "nrm"):
            return VBoneAxis(self.refs.bone(loc, sub, v[head]), Axis(head))
        if head == "opp":
            return VOpp(self.vector(loc, sub, v["opp"]))
        if head == "scale":
            return VScale(self.vector(loc, sub, v["scale"]), number(loc, f"{field}.by", v["by"]))
        if head == "add":
            terms = items(loc, sub, v["add"], None, "vector")
            return VAdd(tuple(self.vector(loc, f"{sub}[{i}]", t) for i, t in enumerate(terms, 1)))
        if head == "cross":
            a, b = items(loc, sub, v["cross"], 2, "vector")
            return VCross(self.vector(loc, f"{sub}[1]", a), self.vector(loc, f"{sub}[2]", b))
        if head == "from":
            return VFrom(self.point(loc, sub, v["from"]), self.point(loc, f"{field}.to", v["to"]))
        inner = self.vector(loc, sub, v["unit"])
        nonzero(loc, sub, inner, v["unit"], "cannot normalise the zero vector")
        return VUnit(inner)
