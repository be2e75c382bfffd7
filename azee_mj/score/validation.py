"""The checks of the score loader and the shape of its messages.

A message is one line, ``<dotted block path>: <where in the block>: <what is wrong>; <what is
valid>`` (see :mod:`azee_mj.score`). :class:`Loc` says where; the functions here check one
JSON value each and raise :class:`~azee_mj.errors.ScoreError` through ``Loc.fail``.
"""

from __future__ import annotations

import dataclasses
import enum
import json
import math
from collections.abc import Mapping
from types import MappingProxyType
from typing import Any

import numpy as np

from azee_mj.errors import ScoreError, shorten, tidy
from azee_mj.score.expressions import depends_on_body, eval_vector
from azee_mj.score.records import (
    TIME_SLACK,
    ZERO_NORM,
    Block,
    BlockKind,
    VectorExpr,
)
from azee_mj.sites import suggest

#: Lists of valid names longer than this are abbreviated in messages.
MAX_LISTED = 8
#: Largest magnitude of any number in a score (times, metres, weights, counts).
MAX_NUMBER = 1e6
#: Deepest nesting of JSON objects and arrays in a score (about 48 nested blocks).
MAX_DEPTH = 100


@dataclasses.dataclass(frozen=True)
class Loc:
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
        path = ".".join(shorten(p) for p in self.path.split(".")) if self.path else "score"
        parts = [path, self.where]
        if field and show_field and field not in self.unnamed:
            parts.append(f"field '{field}'")
        parts.append(what)
        message = ": ".join(p for p in parts if p)
        if valid:
            message += "; " + valid
        return ScoreError(tidy(message), path=self.path, field=field)


def listing(names: Any, quote: bool = False) -> str:
    """``a, b, c`` or, beyond 8 names, ``a, ..., h, ..., and N more``."""
    names = [f"'{n}'" if quote else str(n) for n in names]
    if len(names) <= MAX_LISTED:
        return ", ".join(names)
    return ", ".join(names[:MAX_LISTED]) + f", ..., and {len(names) - MAX_LISTED} more"


def got(value: Any) -> str:
    """A value as the user wrote it (JSON), shortened."""
    if isinstance(value, int) and value.bit_length() > 64:
        return f"an integer of about {int(value.bit_length() * 0.30103) + 1} digits"
    try:
        text = json.dumps(value, ensure_ascii=False)
    except (TypeError, ValueError, RecursionError):
        text = f"a {type(value).__name__}"
    return text if len(text) <= 60 else text[:57] + "..."


def num(x: float) -> str:
    """A number in a message."""
    return f"{x:.10g}"


def is_number(v: Any) -> bool:
    """A JSON number (not a boolean)."""
    return isinstance(v, (int, float)) and not isinstance(v, bool)


#: The annotations of a block that has none (read-only, shared).
NO_ANNOTATIONS: Mapping[str, Any] = MappingProxyType({})


def freeze(v: Any) -> Any:
    """An immutable copy of a JSON value (mappings become read-only, lists tuples)."""
    if isinstance(v, Mapping):
        return MappingProxyType({k: freeze(x) for k, x in v.items()})
    if isinstance(v, (list, tuple)):
        return tuple(freeze(x) for x in v)
    return v


def check_keys(
    loc: Loc,
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
    kept = {k: v for k, v in obj.items() if isinstance(k, str) and k.startswith("x-")}
    return freeze(kept) if kept else NO_ANNOTATIONS  # most blocks have none: one shared


def number(loc: Loc, field: str, v: Any) -> float:
    """A finite JSON number."""
    if not is_number(v):
        raise loc.fail(f"expected a number, got {got(v)}", field=field)
    if isinstance(v, float) and not math.isfinite(v):
        raise loc.fail(f"expected a finite number, got {got(v)}", field=field)
    if abs(v) > MAX_NUMBER:
        raise loc.fail(
            f"{got(v)} is out of range",
            f"numbers in a score lie within -{MAX_NUMBER:g} to {MAX_NUMBER:g}",
            field=field,
        )
    return float(v)


def positive(loc: Loc, field: str, v: Any) -> float:
    """A finite number > 0."""
    x = number(loc, field, v)
    if x <= 0:
        raise loc.fail(f"must be positive, got {got(v)}", field=field)
    return x


def string(loc: Loc, field: str, v: Any) -> str:
    """A JSON string."""
    if not isinstance(v, str):
        raise loc.fail(f"expected a string, got {got(v)}", field=field)
    return v


def one_of(loc: Loc, field: str, v: Any, cls: type[enum.Enum], noun: str, plural: str) -> Any:
    """The member of enum ``cls`` whose value is the string ``v``."""
    s = string(loc, field, v)
    values = [m.value for m in cls]
    if s not in values:
        raise loc.fail(
            f"unknown {noun} '{s}'",
            f"valid {plural} are {', '.join(values)}" + suggest(s, values),
            field=field,
        )
    return cls(s)


def xyz(loc: Loc, field: str, v: list[Any] | tuple[Any, ...]) -> tuple[float, float, float]:
    """Three finite numbers."""
    if len(v) != 3 or not all(is_number(x) for x in v):
        raise loc.fail(f"expected 3 numbers [x, y, z], got {got(v)}", field=field)
    if not all(isinstance(x, int) or math.isfinite(x) for x in v):
        raise loc.fail(f"expected finite numbers, got {got(v)}", field=field)
    if any(abs(x) > MAX_NUMBER for x in v):
        raise loc.fail(
            f"{got(v)} is out of range",
            f"numbers in a score lie within -{MAX_NUMBER:g} to {MAX_NUMBER:g}",
            field=field,
        )
    return (float(v[0]), float(v[1]), float(v[2]))


def nonzero(loc: Loc, field: str, expr: VectorExpr, written: Any, what: str) -> None:
    """Reject a constant vector of (near) zero length; one that reads the posture is checked
    when it is evaluated."""
    if depends_on_body(expr):
        return
    if float(np.linalg.norm(eval_vector(expr, _no_posture, _no_posture))) < ZERO_NORM:
        raise loc.fail(f"{what} {got(written)}", "give a vector of non-zero length", field=field)


def _no_posture(*_: Any) -> np.ndarray:
    raise TypeError("a constant expression reads no site and no bone")


def check_depth(data: Any, limit: int = MAX_DEPTH) -> None:
    """Reject JSON nested deeper than ``limit`` objects and arrays (checked without
    recursion, before anything recursive reads it)."""
    stack = [(data, 1)]
    while stack:
        v, depth = stack.pop()
        if isinstance(v, Mapping):
            children = v.values()
        elif isinstance(v, (list, tuple)):
            children = v
        else:
            continue
        if depth > limit:
            raise Loc("").fail(
                f"the score is nested deeper than {limit} levels of objects and arrays",
                f"the deepest nesting allowed is {limit}",
            )
        stack.extend((c, depth + 1) for c in children)


def check_holds(parent: str, blocks: tuple[Block, ...], parent_start: float) -> None:
    """Check the holds among sibling ``blocks`` of the block at path ``parent`` (which
    starts at ``parent_start`` [s]): each names another sibling, one that ends by the time
    the hold starts."""
    by_name = {b.name: b for b in blocks}
    for b in blocks:
        if b.kind is not BlockKind.HOLD:
            continue
        of = (b.hold_of or "")[len(parent) + 1 :]
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
                f"'{of}' ends at {num(held.end - parent_start)} s, after this hold starts"
                f" at {num(b.start - parent_start)} s",
                "a hold keeps the posture reached at the end of the block it holds, "
                "so it starts at or after that end",
                field="of",
            )
