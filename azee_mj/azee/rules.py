"""The rule catalogue: each rule's parameters, sources and approximations as data, and a
small function that lays its arguments out on its time line.

A rule returns one ``sync`` block from 0 to its children's last end; times are
parent-relative seconds. Rules only offset, hold and overlay: they never change an
argument's articulation except through a sign's declared parameters (``loc``).

Sources: [N18] Nunnari, Filhol & Heloir 2018; [SF22] Sharma & Filhol 2022; [SF23] Sharma &
Filhol, SCA 2023; [G23] Sharma, GRAPP 2023; [T] Sharma's PhD thesis.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any, Protocol

from azee_mj.azee import nonmanual
from azee_mj.azee.catalogue import (
    Lit,
    Param,
    ScoreVal,
    Timeline,
    along,
    head_along,
    lean_along,
    look,
    morph,
)

#: The point the "deep gaze" of a negation looks at (1.5 m ahead at eye level) [m].
NEG_GAZE_AT = [1.5, 0.0, 0.69]
#: The negation's frown over the manual hold.
FROWN = morph("brows_frown", 0.6)
#: Lean direction toward each locus (signer frame).
LOCUS_SIDE = {"^Rssp": "right", "^Lssp": "left", "^ssp": "fwd"}


class Context(Protocol):
    """What a rule may ask of the evaluator."""

    def sign_value(self, name: str, params: Mapping[str, Lit]) -> ScoreVal: ...

    def localise(self, val: ScoreVal, locus: Lit) -> ScoreVal: ...


@dataclasses.dataclass(frozen=True)
class Rule:
    """One rule: ``build(ctx, args, head)`` maps bound arguments to a score value."""

    name: str
    params: tuple[Param, ...]
    summary: str
    source: str
    approximated: str
    build: Any = dataclasses.field(repr=False, compare=False)
    aliases: tuple[str, ...] = ()
    implemented: bool = True

    def signature(self) -> str:
        return ", ".join(p.signature() for p in self.params)

    def to_json(self) -> dict:
        """The rule as ``azee-mj rules --json`` lists it."""
        return {
            "name": self.name,
            "aliases": list(self.aliases),
            "args": [p.to_json() for p in self.params],
            "summary": self.summary,
            "source": self.source,
            "approximated": self.approximated,
            "implemented": self.implemented,
        }


def _seq(ctx: Context, a: dict, head: str) -> ScoreVal:
    tl = Timeline()
    for k, item in enumerate(a["item"]):
        tl.put(f"ITEM_{k}", item, at=None if k == 0 else tl.t + a["gap"])
    return tl.value(head, "seq")


def _info_about(ctx: Context, a: dict, head: str) -> ScoreVal:
    tl = Timeline()
    tl.put("TOPIC", a["topic"])
    _, held = tl.hold("TOPIC", a["hold"])
    tl.cstr("BROWS", 0.0, held, [morph("brows_raise", 0.8)])
    info = a["info"]
    tl.put("INFO", info)
    if info.duration >= 0.4 and info.origin != "info-about":
        tl.cstr("BLINK", tl.t - 0.4, tl.t - 0.2, [morph("blink", 1.0)])
    return tl.value(head, "info-about")


def _side_info(ctx: Context, a: dict, head: str) -> ScoreVal:
    tl = Timeline()
    tl.put("FOCUS", a["focus"])
    tl.hold("FOCUS", 0.2)
    s, e = tl.put("INFO", a["info"])
    tl.cstr("CHIN", s, e, [head_along(along("fwd", ("up", 0.2)))])
    tl.cstr("LIFT", s, e, [morph("spine_extended", 0.5)])
    return tl.value(head, "side-info")


def _about_ref(ctx: Context, a: dict, head: str) -> ScoreVal:
    tl = Timeline()
    pt = a["pt"]
    s, e = tl.put("REF", ctx.localise(a["sig"], pt))
    tl.cstr("LEAN", s, e, [lean_along(along("up", (LOCUS_SIDE[pt.value], a["lean"])))])
    return tl.value(head, "about-ref")


def _instance_of(ctx: Context, a: dict, head: str) -> ScoreVal:
    tl = Timeline()
    tl.put("CAT", a["cat"])
    _, held = tl.hold("CAT", 0.2)
    tl.cstr("BACK", 0.0, held, [lean_along(along("up", ("back", 0.1)))])
    tl.cstr("CHIN", 0.0, held, [head_along(along("fwd", ("up", 0.1)))])
    tl.put("ELT", a["elt"])
    return tl.value(head, "instance-of")


def _in_context(ctx: Context, a: dict, head: str) -> ScoreVal:
    tl = Timeline()
    tl.put("CTX", a["ctx"])
    _, held = tl.hold("CTX", 0.2)
    tl.cstr("LEAN", 0.0, held, [lean_along(along("up", ("fwd", 0.1)))])
    tl.put("MAIN", a["main"])
    return tl.value(head, "in-context")


def _each_of(ctx: Context, a: dict, head: str) -> ScoreVal:
    tl = Timeline()
    for k, item in enumerate(a["item"]):
        tl.put(f"ITEM_{k}", item)
        s, e = tl.hold(f"ITEM_{k}", 0.15)
        tl.cstr(f"NOD_{k}", s, e, [head_along(along("fwd", ("down", 0.2)))])
    return tl.value(head, "each-of")


def _side_by_side(ctx: Context, a: dict, head: str) -> ScoreVal:
    tl = Timeline()
    tl.put("LEFT", ctx.localise(a["left"], Lit("locus", "^Lssp", "^Lssp")))
    tl.put("RIGHT", ctx.localise(a["right"], Lit("locus", "^Rssp", "^Rssp")))
    return tl.value(head, "side-by-side")


def _nicht_sondern(ctx: Context, a: dict, head: str) -> ScoreVal:
    d = a["neghold"]
    neg = Timeline()
    _, e = neg.put("NICHT", a["nicht"])
    neg.hold("NICHT", d)
    shake = Timeline()
    for k in range(math.floor(d / 0.2 + 1e-9)):
        side = "lat(w)" if k % 2 == 0 else "lat(s)"
        shake.cstr(f"TURN_{k}", 0.2 * k, 0.2 * k + 0.08, [head_along(along("fwd", (side, 0.22)))])
    shake.cstr("GAZE", 0.0, d, [look(list(NEG_GAZE_AT))])
    neg.put("HEADSHAKE", shake.value("", "headshake"), at=e)
    if d > 2 * (nonmanual.RELAX_S + nonmanual.RELEASE_S):
        neg.cstr("FROWN", e, e + d - nonmanual.RELAX_S - nonmanual.RELEASE_S, [FROWN])
        neg.cstr("FROWN_RELAX", e + d - nonmanual.RELAX_S, e + d, [morph("brows_frown", 0.0)])
    else:
        neg.cstr("FROWN", e, e + d, [FROWN])
    tl = Timeline()
    tl.put("NEGATED", neg.value("", "negated"))
    tl.put("SONDERN", a["sondern"])
    return tl.value(head, "nicht-sondern")


def _tens_units(ctx: Context, a: dict, head: str) -> ScoreVal:
    tl = Timeline()
    tl.put("D", ctx.sign_value(f"nb-{a['tens'].value}", {}))
    tl.put("U", ctx.sign_value(f"nb-{a['units'].value}", {}), at=tl.t + a["gap"])
    return tl.value(head, "tens-units")


def _decidedly(ctx: Context, a: dict, head: str) -> ScoreVal:
    tl = Timeline()
    s, e = tl.put("SIG", a["sig"])
    tl.cstr("FACE", s, e, [morph("brows_frown", 0.5), morph("mouth_down", 0.4)])
    tl.cstr("NOD", max(s, e - 0.25), e, [head_along(along("fwd", ("down", 0.25)))])
    return tl.value(head, "decidedly")


def _score(name: str) -> Param:
    return Param(name, "score")


_GE0 = {"minimum": 0.0}
RULES: tuple[Rule, ...] = (
    Rule(
        "seq",
        (Param("item", "score", list=True), Param("gap", "num", 0.0, **_GE0)),
        "the items in sequence, each starting 'gap seconds after the previous one ends",
        "ours",
        "nothing: it only offsets its items",
        _seq,
    ),
    Rule(
        "info-about",
        (_score("topic"), _score("info"), Param("hold", "num", 0.3, **_GE0)),
        "TOPIC, TOPIC_HOLD, INFO in sequence; BROWS (brows_raise 0.8) over the first two; "
        "BLINK over [end-0.4, end-0.2] unless INFO is shorter than 0.4 s or an info-about",
        "sequence and blink [N18 sec. 5.2]; blocks [SF23; T ch. 4]",
        "brow weight guessed; the thesis's final HOLD2 is dropped (the last posture holds anyway)",
        _info_about,
    ),
    Rule(
        "side-info",
        (_score("focus"), _score("info")),
        "FOCUS, FOCUS_HOLD 0.2 s, INFO; over INFO, CHIN (head fwd+0.2 up) and LIFT "
        "(spine_extended 0.5)",
        "template [T ch. 5]",
        "block names, hold, head and spine amounts guessed",
        _side_info,
    ),
    Rule(
        "about-ref",
        (_score("sig"), Param("pt", "locus"), Param("lean", "num", 0.15)),
        "REF = the sign localised at 'pt (its loc set and a look at it, or a pointing "
        "after it); LEAN (back toward the point) over it",
        "body and head toward the point [T ch. 5]; gaze and lean [G23]",
        "pointing guessed; G23's chin-up dropped (it fights the look)",
        _about_ref,
    ),
    Rule(
        "instance-of",
        (_score("cat"), _score("elt")),
        "CAT, CAT_HOLD 0.2 s, ELT; over the first two BACK (lean up+0.1 back) and CHIN "
        "(head fwd+0.1 up)",
        "template [T ch. 5]; names [G23]",
        "order and amounts guessed",
        _instance_of,
    ),
    Rule(
        "in-context",
        (_score("ctx"), _score("main")),
        "CTX, CTX_HOLD 0.2 s, MAIN; LEAN (up+0.1 fwd) over the first two",
        "[T ch. 5]: 'body preparing to sign'",
        "hold and lean amount guessed",
        _in_context,
    ),
    Rule(
        "each-of",
        (Param("item", "score", list=True, min_items=2),),
        "each ITEM_k then ITEM_k_HOLD 0.15 s with NOD_k (head fwd+0.2 down)",
        "ours",
        "all of it guessed",
        _each_of,
    ),
    Rule(
        "side-by-side",
        (_score("left"), _score("right")),
        "LEFT = left localised at ^Lssp, then RIGHT = right localised at ^Rssp",
        "ours",
        "all of it guessed",
        _side_by_side,
    ),
    Rule(
        "nicht-sondern",
        (
            _score("nicht"),
            _score("sondern"),
            Param("neghold", "num", 0.8, minimum=0.0, strict=True),
        ),
        "NEGATED (NICHT, NICHT_HOLD and a HEADSHAKE over the hold: head turns every 0.2 s "
        "and a deep gaze; FROWN (brows_frown 0.6) over the hold, FROWN_RELAX at its end), "
        "then SONDERN",
        "[N18 sec. 3.1]: 'headshake and deep gaze over a manual hold of X'; [SF22 fig. 1, 5]; "
        "the frown of negation [BSC80]",
        "the headshake as alternating head orientations (0.22 lateral) rather than a trill; "
        "the gaze point, the timings and the frown's weight guessed",
        _nicht_sondern,
        aliases=("not-but",),
    ),
    Rule(
        "tens-units",
        (Param("tens", "digit"), Param("units", "digit"), Param("gap", "num", 0.15, **_GE0)),
        "D = :nb-<tens>, then U = :nb-<units> after 'gap seconds",
        "order from the 'person aged 52' timeline [T]",
        "digit handshapes and the gap guessed",
        _tens_units,
    ),
    Rule(
        "decidedly",
        (_score("sig"),),
        "SIG with FACE (brows_frown 0.5, mouth_down 0.4) over it and NOD (head fwd+0.25 "
        "down) over its last 0.25 s",
        "listed in [T annex]",
        "face and nod guessed",
        _decidedly,
    ),
    Rule(
        "fingerspelling",
        (Param("word", "score"),),
        "not implemented: azee_mj has no manual alphabet",
        "[T annex]",
        "not implemented",
        None,
        implemented=False,
    ),
)

RULES += nonmanual.rules(Rule)

#: Rule name or alias -> rule.
BY_NAME: dict[str, Rule] = {n: r for r in RULES for n in (r.name, *r.aliases)}
