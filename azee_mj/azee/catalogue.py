"""Parameters, values and the block vocabulary shared by rules and signs.

A value is a :class:`ScoreVal` (a ``:`` application: a block to be named by its parent) or
a :class:`Lit` (a locus ``^ssp``, a digit ``.nb-5`` or a number). Times are seconds.
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Callable, Mapping
from typing import Any

#: Value kinds and how an error message describes what is expected.
KINDS = {
    "score": "a score (a :rule or :sign application)",
    "locus": "a locus (^ssp, ^Rssp, ^Lssp)",
    "digit": "a digit (.nb-0 to .nb-9)",
    "num": "a number",
    "text": 'a text in double quotes ("maison")',
}
LOCI = ("ssp", "Rssp", "Lssp")
DIGITS = tuple(f"nb-{n}" for n in range(10))


@dataclasses.dataclass(frozen=True)
class Param:
    """A named, typed argument. ``default`` None means required; ``list`` parameters take
    the remaining positional arguments and at least ``min_items``; a number must be at
    least ``minimum`` (strictly more when ``strict``)."""

    name: str
    kind: str
    default: Any = None
    list: bool = False
    min_items: int = 1
    minimum: float | None = None
    strict: bool = False

    def signature(self) -> str:
        """``'hold num=0.3``, ``'item score+``, ``'item score 2+``."""
        s = f"'{self.name} {self.kind}"
        if self.list:
            s += "+" if self.min_items <= 1 else f" {self.min_items}+"
        elif self.default is not None:
            s += f"={quote(self.default) if self.kind == 'text' else fmt_value(self.default)}"
        return s

    def to_json(self) -> dict:
        return {"name": self.name, "kind": self.kind, "default": self.default, "list": self.list}


def fmt_value(v: Any) -> str:
    """A literal as written in ``.azee`` text (numbers shortest, loci with ``^``)."""
    if isinstance(v, bool):
        raise TypeError(v)
    if isinstance(v, (int, float)):
        return repr(float(v)).removesuffix(".0") if float(v).is_integer() else repr(float(v))
    return str(v)


def quote(text: str) -> str:
    """A text as written in ``.azee`` text: in double quotes, ``"`` and ``\\`` escaped."""
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


@dataclasses.dataclass(frozen=True)
class Lit:
    """A locus (``value`` ``"^Rssp"``), a digit (``value`` 5, ``text`` ``.nb-5``), a
    number or a text (``value`` the string, ``text`` it quoted)."""

    kind: str
    value: Any
    text: str


@dataclasses.dataclass(frozen=True)
class ScoreVal:
    """A score value: a block of ``duration`` [s], named by whoever places it.

    ``head`` is its canonical text, ``origin`` the rule or sign it comes from, ``sign`` and
    ``given`` the sign and its explicit parameters when it is a sign application (so that a
    rule can fill an unfilled ``loc``).
    """

    head: str
    origin: str
    duration: float
    body: Mapping[str, Any]  # the block without name / start / end
    sign: Any = None
    given: Mapping[str, Lit] = dataclasses.field(default_factory=dict)

    def block(self, name: str, start: float) -> dict:
        """This value as a block named ``name`` over ``[start, start + duration]``."""
        out = {
            "name": name,
            "kind": self.body["kind"],
            "start": start,
            "end": start + self.duration,
        }
        out.update({k: copy.deepcopy(v) for k, v in self.body.items() if k != "kind"})
        return out


def block_name(label: str) -> str:
    """The block name of an argument label or rule name: upper case, ``-`` as ``_``."""
    return label.upper().replace("-", "_")


class Timeline:
    """Lays out a rule's children on its own time line [s] (parent-relative)."""

    def __init__(self) -> None:
        self.children: list[dict] = []
        self.t = 0.0

    def put(self, name: str, val: ScoreVal, at: float | None = None) -> tuple[float, float]:
        """Place ``val`` as ``name`` at ``at`` (default: the current end); returns its
        interval and moves the current end after it."""
        start = self.t if at is None else at
        self.children.append(val.block(name, start))
        self.t = start + val.duration
        return start, self.t

    def hold(self, of: str, d: float) -> tuple[float, float]:
        """``OF_HOLD``-style hold of sibling ``of`` for ``d`` seconds (nothing when 0)."""
        start = self.t
        if d > 0:
            self.children.append(
                {"name": f"{of}_HOLD", "kind": "hold", "start": start, "end": start + d, "of": of}
            )
            self.t = start + d
        return start, self.t

    def cstr(self, name: str, start: float, end: float, constraints: list[dict]) -> None:
        self.children.append(
            {"name": name, "kind": "cstr", "start": start, "end": end, "constraints": constraints}
        )

    def sync(self, name: str, start: float, end: float, children: list[dict]) -> None:
        self.children.append(
            {"name": name, "kind": "sync", "start": start, "end": end, "children": children}
        )

    def value(self, head: str, origin: str) -> ScoreVal:
        """The laid-out children as one ``sync`` value from 0 to the last end."""
        end = max((c["end"] for c in self.children), default=0.0)
        return ScoreVal(head, origin, end, {"kind": "sync", "children": self.children})


# Constraint builders (JSON dicts of the score format).


def scaled(axis: str | dict, k: float) -> dict:
    return {"scale": axis, "by": k}


def along(base: str, *terms: tuple[str, float]) -> dict:
    """``base + sum(k axis)`` as a vector expression."""
    return {"add": [base, *(scaled(a, k) for a, k in terms)]}


def head_along(vector: Any) -> dict:
    """ "head v": the head's NRM (its face direction) along ``v``."""
    return {"type": "orient", "bone": "!head", "axis": "nrm", "rel": "along", "vector": vector}


def lean_along(vector: Any) -> dict:
    """ "lean v": the upper back's DIR along ``v``."""
    return {"type": "orient", "bone": "!back_2", "axis": "dir", "rel": "along", "vector": vector}


def morph(mid: str, weight: float) -> dict:
    return {"type": "morph", "id": mid, "weight": weight}


def look(at: Any) -> dict:
    return {"type": "look", "at": at}


BuildFn = Callable[..., ScoreVal]
