"""What a block does, read from JSON: the constraints of a ``cstr`` block and the route of a
``transpath`` block, each as a record of :mod:`azee_mj.score.records`; the points and vectors
inside them are read by :class:`~azee_mj.score.grammar.ExpressionReader`."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from azee_mj import arkit
from azee_mj.score.grammar import ExpressionReader
from azee_mj.score.records import (
    CONSTRAINT_TYPES,
    DEFAULT_TOL,
    DEFAULT_TOL_DEG,
    Arc,
    Axis,
    Circle,
    Constraint,
    Look,
    MorphC,
    Orient,
    Place,
    Rel,
    Route,
    Straight,
    Trill,
)
from azee_mj.score.references import References
from azee_mj.score.validation import Loc, check_keys, got, listing, number, one_of, positive, string
from azee_mj.sites import suggest

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


class ConstraintReader:
    """Reads constraints and transpath routes, resolving names through ``refs`` (the
    vocabulary of one signer and the score's strong side)."""

    def __init__(self, refs: References):
        self.refs = refs
        self.map = refs.map
        self.expr = ExpressionReader(refs)

    # -- constraints ---------------------------------------------------------------------

    def constraints(self, loc: Loc, items: Any) -> tuple[Constraint, ...]:
        if not isinstance(items, (list, tuple)):
            raise loc.fail(f"expected a list of constraints, got {got(items)}", field="constraints")
        return tuple(self.constraint(loc.path, i, item) for i, item in enumerate(items, 1))

    def constraint(self, path: str, index: int, obj: Any) -> Constraint:
        pre = Loc(path, f"constraint {index}")
        if not isinstance(obj, Mapping):
            raise pre.fail(f"expected a constraint (a JSON object), got {got(obj)}")
        types = ", ".join(CONSTRAINT_TYPES)
        if "type" not in obj:
            raise pre.fail(
                "missing field 'type'", f"valid types are {types}", field="type", show_field=False
            )
        ctype = string(pre, "type", obj["type"])
        if ctype not in CONSTRAINT_TYPES:
            raise pre.fail(
                f"unknown constraint type '{ctype}'",
                f"valid types are {types}" + suggest(ctype, CONSTRAINT_TYPES),
                field="type",
            )
        loc = Loc(path, f"constraint {index} ({ctype})", frozenset({"site", "bone"}))
        required, optional = _CONSTRAINT_KEYS[ctype]
        ann = check_keys(loc, obj, required, optional, f"{_ARTICLE[ctype]} constraint")
        common = {"index": index, "annotations": ann}
        if ctype == "place":
            return Place(
                site=self.refs.body_site(loc, "site", obj["site"], "a place"),
                at=self.expr.point(loc, "at", obj["at"]),
                tol=positive(loc, "tol", obj["tol"]) if "tol" in obj else DEFAULT_TOL,
                **common,
            )
        if ctype == "orient":
            tol_deg = (
                positive(loc, "tol_deg", obj["tol_deg"]) if "tol_deg" in obj else DEFAULT_TOL_DEG
            )
            return Orient(
                bone=self.refs.bone(loc, "bone", obj["bone"]),
                axis=one_of(loc, "axis", obj["axis"], Axis, "axis", "axes"),
                rel=one_of(loc, "rel", obj["rel"], Rel, "relation", "relations"),
                vector=self.expr.direction(loc, "vector", obj["vector"]),
                tol=math.radians(tol_deg),
                **common,
            )
        if ctype == "morph":
            return self.morph(loc, obj, common)
        if ctype == "look":
            return Look(at=self.expr.point(loc, "at", obj["at"]), **common)
        return self.trill(loc, obj, common)

    def morph(self, loc: Loc, obj: Mapping[str, Any], common: dict[str, Any]) -> MorphC:
        mid = string(loc, "id", obj["id"])
        if mid not in self.map.morphs:
            ids = list(self.map.morphs)
            raise loc.fail(
                f"unknown morph '{mid}'",
                f"valid ids are {listing(ids)}" + suggest(mid, ids),
                field="id",
            )
        weight = number(loc, "weight", obj["weight"])
        if arkit.is_shape(mid) and not 0.0 <= weight <= 1.0:
            raise loc.fail(
                f"weight {weight:g} is out of range", "ARKit shapes take 0 to 1", field="weight"
            )
        side = None
        if "side" in obj:
            written = string(loc, "side", obj["side"])
            side = self.refs.side(loc, "side", written, written)
            if not self.map.morphs[mid].sided:
                raise loc.fail(f"morph '{mid}' has no sides", "remove 'side'", field="side")
        return MorphC(id=mid, weight=weight, side=side, **common)

    def trill(self, loc: Loc, obj: Mapping[str, Any], common: dict[str, Any]) -> Trill:
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
            site = self.refs.body_site(loc, "site", obj["site"], "a trill")
            amp_key, wrong_key = "amplitude", "amplitude_deg"
        else:
            bone = self.refs.bone(loc, "bone", obj["bone"])
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
                f"missing field '{amp_key}'",
                f"a {mover} trill needs its amplitude in {unit}",
                field=amp_key,
                show_field=False,
            )
        amplitude = positive(loc, amp_key, obj[amp_key])
        if bone is not None:
            amplitude = math.radians(amplitude)
        return Trill(
            site=site,
            bone=bone,
            vector=self.expr.direction(loc, "vector", obj["vector"]),
            amplitude=amplitude,
            frequency=positive(loc, "frequency", obj["frequency"]),
            **common,
        )

    # -- transpath routes ----------------------------------------------------------------

    def route(self, loc: Loc, obj: Any) -> Route:
        shapes = list(_SHAPE_KEYS)
        if not isinstance(obj, Mapping):
            raise loc.fail(
                f"expected a path (a JSON object with 'shape'), got {got(obj)}", field="path"
            )
        ploc = Loc(loc.path, "field 'path'")
        if "shape" not in obj:
            raise ploc.fail(
                "missing field 'shape'",
                f"valid shapes are {', '.join(shapes)}",
                field="path.shape",
                show_field=False,
            )
        shape = string(loc, "path.shape", obj["shape"])
        if shape not in _SHAPE_KEYS:
            raise loc.fail(
                f"unknown shape '{shape}'",
                f"valid shapes are {', '.join(shapes)}" + suggest(shape, shapes),
                field="path.shape",
            )
        required, optional = _SHAPE_KEYS[shape]
        check_keys(ploc, obj, required, optional, f"{_ARTICLE[shape]} path", prefix="path.")
        if shape == "straight":
            return Straight()
        if shape == "arc":
            return Arc(bulge=self.expr.direction(loc, "path.bulge", obj["bulge"]))
        center = self.expr.point(loc, "path.center", obj["center"])
        turns = positive(loc, "path.turns", obj["turns"]) if "turns" in obj else 1.0
        normal = self.expr.direction(loc, "path.normal", obj["normal"]) if "normal" in obj else None
        return Circle(center=center, turns=turns, normal=normal)
