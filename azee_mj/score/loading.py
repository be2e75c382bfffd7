"""Reading a score: JSON in, validated :class:`~azee_mj.score.records.Score` out.

:func:`load_score` reads a JSON file or an already-parsed object, checks everything (the
checks and message shapes are in :mod:`azee_mj.score.validation`, references are resolved by
:mod:`azee_mj.score.references`) and returns the records.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from azee_mj.errors import ScoreError, shorten
from azee_mj.score.records import (
    CONSTRAINT_TYPES,
    DEFAULT_TOL,
    DEFAULT_TOL_DEG,
    FORMAT,
    NAMED_DIRECTIONS,
    TIME_SLACK,
    VERSION,
    Arc,
    Axis,
    Block,
    BlockKind,
    Circle,
    Constraint,
    Look,
    MorphC,
    Orient,
    Place,
    PLiteral,
    PMid,
    PointExpr,
    PSite,
    PTranslate,
    Rel,
    Route,
    Score,
    Straight,
    Trill,
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
from azee_mj.score.validation import (
    MAX_DEPTH,
    MAX_NUMBER,
    Loc,
    check_depth,
    check_keys,
    got,
    is_number,
    listing,
    nonzero,
    num,
    number,
    one_of,
    positive,
    string,
    xyz,
)
from azee_mj.sites import DEFAULT_MAP, SignerMap, resolve_side, suggest
from azee_mj.timing import MAX_DURATION, exact_time


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

    def parse_int(s: str) -> int:
        if len(s) > 16:  # beyond MAX_NUMBER; int() of thousands of digits is refused anyway
            raise _BigNumber(s)
        return int(s)

    try:
        return json.loads(
            text, object_pairs_hook=pairs, parse_constant=bad_constant, parse_int=parse_int
        )
    except RecursionError:
        raise ScoreError(
            f"{path}: invalid score: nested deeper than {MAX_DEPTH} levels of objects and arrays"
        ) from None
    except _BigNumber as e:
        raise ScoreError(
            f"{path}: invalid score: the integer {shorten(e.args[0], 20)} has "
            f"{len(e.args[0].lstrip('-'))} digits; numbers in a score lie within "
            f"-{MAX_NUMBER:g} to {MAX_NUMBER:g}"
        ) from None
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


class _BigNumber(Exception):
    pass


_LAT_RE = re.compile(r"^lat\(\s*([^()]*?)\s*\)$")
_SIDE_WORD = {"R": "right", "L": "left"}

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
_POINT_DESC = 'a point ("@SITE", "^locus", [x, y, z], {"translate": P, "by": V} or {"mid": [P, Q]})'
_VECTOR_DESC = (
    "a vector (fwd, back, left, right, up, down, lat(s), lat(w), [x, y, z], or one of "
    '{"dir"|"nrm": BONE}, {"opp": V}, {"scale": V, "by": k}, {"add": [V, ...]}, '
    '{"cross": [V1, V2]}, {"from": P, "to": Q}, {"unit": V})'
)


class _Loader:
    def __init__(self, signer_map: SignerMap):
        self.map = signer_map
        self.refs = References(signer_map)

    # -- top level -----------------------------------------------------------------------

    def score(self, data: Any) -> Score:
        loc = Loc("")
        if not isinstance(data, Mapping):
            raise loc.fail(f"expected a JSON object at the top level, got {got(data)}")
        check_depth(data)
        annotations = check_keys(loc, data, _TOP_REQUIRED, ("strong_side",), "", _TOP_KEYS)
        fmt = data["format"]
        if fmt != FORMAT:
            raise loc.fail(f'expected "{FORMAT}", got {got(fmt)}', field="format")
        version = data["version"]
        if not is_number(version):
            raise loc.fail(f"expected a number, got {got(version)}", field="version")
        if version != VERSION:
            raise loc.fail(
                f"unsupported version {got(version)}",
                f"this reader reads version {VERSION}",
                field="version",
            )
        strong = data.get("strong_side", "R")
        if strong not in ("R", "L"):
            raise loc.fail(f'expected "R" or "L", got {got(strong)}', field="strong_side")
        self.refs.strong = strong
        root = self.block(data["root"], Loc("", "root block"), "", 0.0, None)
        if root.kind is BlockKind.HOLD:
            raise Loc(root.path).fail(
                f"no sibling block named '{data['root']['of']}'",
                "the root block has no siblings to hold",
                field="of",
            )
        return Score(strong_side=strong, root=root, annotations=annotations)

    # -- blocks --------------------------------------------------------------------------

    def block(
        self,
        obj: Any,
        pre: Loc,
        parent_path: str,
        parent_abs: float,
        parent_dur: float | None,
        parent_abs_end: float | None = None,
    ) -> Block:
        """Parse one block. ``pre`` locates it before its name is known; ``parent_dur`` is
        None for the root."""
        if not isinstance(obj, Mapping):
            raise pre.fail(f"expected a block (a JSON object), got {got(obj)}")
        if "name" not in obj:
            raise pre.fail(
                "missing field 'name'",
                "a block needs name, kind, start, end",
                field="name",
                show_field=False,
            )
        name = string(pre, "name", obj["name"])
        if not name:
            raise pre.fail("a block name cannot be empty", field="name")
        if "." in name:
            raise pre.fail(
                f"block name '{name}' contains '.'",
                "block paths join names with '.', so use another character",
                field="name",
            )
        path = f"{parent_path}.{name}" if parent_path else name
        loc = Loc(path)
        if "kind" not in obj:
            raise loc.fail(
                "missing field 'kind'",
                "a block needs name, kind, start, end",
                field="kind",
                show_field=False,
            )
        kind_s = string(loc, "kind", obj["kind"])
        kinds = [k.value for k in BlockKind]
        if kind_s not in kinds:
            raise loc.fail(
                f"unknown block kind '{kind_s}'",
                f"valid kinds are {', '.join(kinds)}" + suggest(kind_s, kinds),
                field="kind",
            )
        kind = BlockKind(kind_s)
        annotations = check_keys(loc, obj, _BLOCK_KEYS[kind], (), f"a {kind_s} block")
        start = number(loc, "start", obj["start"])
        end = number(loc, "end", obj["end"])
        if not start < end:
            raise loc.fail(
                f"end {got(obj['end'])} is not after start {got(obj['start'])}",
                "a block needs start < end",
                field="end",
            )
        if parent_dur is None:
            abs_start, abs_end = 0.0, exact_time(end - start)
            if abs_end > MAX_DURATION:
                raise loc.fail(
                    f"the score lasts {num(end - start)} s",
                    f"the longest score is {MAX_DURATION:g} s (1 hour)",
                    field="end",
                )
        else:
            inside = (
                "a child's times are relative to its parent's start and lie within "
                f"[0, {num(parent_dur)}]"
            )
            if start < -TIME_SLACK:
                raise loc.fail(
                    f"{got(obj['start'])} is before the start of its parent {parent_path}",
                    inside,
                    field="start",
                )
            if end > parent_dur + TIME_SLACK:
                raise loc.fail(
                    f"{got(obj['end'])} is after the end of its parent {parent_path}",
                    inside,
                    field="end",
                )
            # Absolute times are made here, once, on the microsecond grid (azee_mj.timing),
            # and kept inside the parent's.
            lo, hi = parent_abs, parent_abs_end if parent_abs_end is not None else math.inf
            abs_start = min(max(exact_time(parent_abs + start), lo), hi)
            abs_end = min(max(exact_time(parent_abs + end), lo), hi)
        if abs_end <= abs_start:
            raise loc.fail(
                f"lasts {num(end - start)} s",
                "a block lasts at least 1e-06 s (times are resolved to the microsecond)",
                field="end",
            )
        fields: dict[str, Any] = {}
        if kind is BlockKind.SYNC:
            fields["children"] = self.children(
                loc, obj["children"], abs_start, end - start, abs_end
            )
        elif kind is BlockKind.CSTR:
            fields["constraints"] = self.constraints(loc, obj["constraints"])
        elif kind is BlockKind.HOLD:
            of = string(loc, "of", obj["of"])
            fields["hold_of"] = f"{parent_path}.{of}" if parent_path else of
        else:
            fields["transpath_site"] = self.refs.body_site(loc, "site", obj["site"], "a transpath")
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

    def children(
        self, loc: Loc, items: Any, abs_start: float, dur: float, abs_end: float
    ) -> tuple[Block, ...]:
        if not isinstance(items, (list, tuple)):
            raise loc.fail(f"expected a list of blocks, got {got(items)}", field="children")
        blocks: list[Block] = []
        seen: dict[str, int] = {}
        for i, item in enumerate(items, 1):
            child = self.block(item, Loc(loc.path, f"child {i}"), loc.path, abs_start, dur, abs_end)
            if child.name in seen:
                raise Loc(loc.path, f"child {i}").fail(
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
            hloc = Loc(b.path)
            others = [n for n in by_name if n != b.name]
            if of == b.name:
                raise hloc.fail(
                    f"'{of}' is this hold itself",
                    f"a hold names a sibling block: {listing(others)}"
                    if others
                    else "a hold names a sibling block, and this block has none",
                    field="of",
                )
            if of not in by_name:
                raise hloc.fail(
                    f"no sibling block named '{of}'",
                    (f"siblings are {listing(others)}" + suggest(of, others))
                    if others
                    else "this block has no siblings",
                    field="of",
                )
            held = by_name[of]
            if held.end > b.start + TIME_SLACK:
                raise hloc.fail(
                    f"'{of}' ends at {num(held.end - abs_start)} s, after this hold starts"
                    f" at {num(b.start - abs_start)} s",
                    "a hold keeps the posture reached at the end of the block it holds, "
                    "so it starts at or after that end",
                    field="of",
                )
        return tuple(blocks)

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
                at=self.point(loc, "at", obj["at"]),
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
                vector=self.direction(loc, "vector", obj["vector"]),
                tol=math.radians(tol_deg),
                **common,
            )
        if ctype == "morph":
            return self.morph(loc, obj, common)
        if ctype == "look":
            return Look(at=self.point(loc, "at", obj["at"]), **common)
        return self.trill(loc, obj, common)

    def morph(self, loc: Loc, obj: Mapping[str, Any], common: dict[str, Any]) -> MorphC:
        mid = string(loc, "id", obj["id"])
        ids = list(self.map.morphs)
        if mid not in self.map.morphs:
            raise loc.fail(
                f"unknown morph '{mid}'",
                f"valid ids are {listing(ids)}" + suggest(mid, ids),
                field="id",
            )
        weight = number(loc, "weight", obj["weight"])
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
            vector=self.direction(loc, "vector", obj["vector"]),
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
            return Arc(bulge=self.direction(loc, "path.bulge", obj["bulge"]))
        center = self.point(loc, "path.center", obj["center"])
        turns = positive(loc, "path.turns", obj["turns"]) if "turns" in obj else 1.0
        normal = self.direction(loc, "path.normal", obj["normal"]) if "normal" in obj else None
        return Circle(center=center, turns=turns, normal=normal)

    # -- expressions ---------------------------------------------------------------------

    def form(
        self,
        loc: Loc,
        field: str,
        obj: Mapping[str, Any],
        forms: dict[str, tuple[str, ...]],
        desc: str,
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
                    f"key '{key}' does not belong with '{head}'",
                    f"expected {desc}",
                    field=field,
                )
        for key in forms[head]:
            if key not in obj:
                raise loc.fail(f"'{head}' needs '{key}'", f"expected {desc}", field=field)
        return head

    def items(self, loc: Loc, field: str, v: Any, n: int | None, what: str) -> list[Any]:
        if not isinstance(v, (list, tuple)) or (n is not None and len(v) != n) or not v:
            count = f"{n} {what}s" if n is not None else f"a list of one or more {what}s"
            raise loc.fail(f"expected {count}, got {got(v)}", field=field)
        return v

    def point(self, loc: Loc, field: str, v: Any) -> PointExpr:
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
        raise loc.fail(f"expected {_POINT_DESC}, got {got(v)}", field=field)

    def vector(self, loc: Loc, field: str, v: Any) -> VectorExpr:
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
        if isinstance(v, (list, tuple)):
            return VLiteral(xyz(loc, field, v))
        if isinstance(v, Mapping):
            head = self.form(loc, field, v, _VECTOR_FORMS, _VECTOR_DESC)
            sub = f"{field}.{head}"
            if head in ("dir", "nrm"):
                return VBoneAxis(self.refs.bone(loc, sub, v[head]), Axis(head))
            if head == "opp":
                return VOpp(self.vector(loc, sub, v["opp"]))
            if head == "scale":
                return VScale(
                    self.vector(loc, sub, v["scale"]), number(loc, f"{field}.by", v["by"])
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
            nonzero(loc, sub, inner, v["unit"], "cannot normalise the zero vector")
            return VUnit(inner)
        raise loc.fail(f"expected {_VECTOR_DESC}, got {got(v)}", field=field)

    def direction(self, loc: Loc, field: str, v: Any) -> VectorExpr:
        expr = self.vector(loc, field, v)
        nonzero(loc, field, expr, v, "zero direction")
        return expr
