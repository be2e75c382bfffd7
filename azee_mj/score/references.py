"""Site, locus and bone references: ``@STEM``, ``@STEM(side)``, ``@STEM(side,n)``, ``^locus``,
``!bone`` ... resolved against a :class:`~azee_mj.sites.SignerMap` with the score's strong
side.

Sites and bones follow the same rules (midline stems take no side, sided stems a side,
phalanx stems a side and a phalanx number), so one resolver reads both from a table.
"""

from __future__ import annotations

import dataclasses
import difflib
import re
from collections.abc import Mapping
from typing import Any

from azee_mj.score.records import BoneRef, SiteRef
from azee_mj.score.validation import Loc, got, listing
from azee_mj.sites import (
    DIGIT_STEMS,
    DIGITS,
    LATERAL_STEMS,
    MIDLINE_STEMS,
    PHALANX_STEMS,
    SignerMap,
    azee_bone_names,
    resolve_side,
    suggest,
)

VALID_SIDES = "valid sides are s, w, L, R"
_SITES_HINT = "(azee-mj sites lists all)"
_REF_RE = re.compile(r"^([A-Za-z][A-Za-z0-9_]*)(?:\(([^()]*)\))?$")


@dataclasses.dataclass(frozen=True)
class RefKind:
    """How one kind of reference is written and which stems take which arguments."""

    noun: str  #: "site" or "bone"
    sigil: str  #: "@" or "!"
    example: str  #: the forms shown when a reference is malformed
    midline: frozenset[str]  #: stems that take no side
    sided: frozenset[str]  #: stems that take a side
    phalanx: frozenset[str]  #: stems that take a side and a phalanx number


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


_LATERAL_SITES = frozenset(LATERAL_STEMS) | {f"{d}_{s}" for d in DIGITS for s in DIGIT_STEMS}

SITE = RefKind(
    "site",
    "@",
    "'@STEM', '@STEM(side)' or '@STEM(side,n)', e.g. '@FH', '@I_TIP(s)', '@I_KN(s,2)'",
    frozenset(MIDLINE_STEMS) - _LATERAL_SITES,
    _LATERAL_SITES,
    frozenset(f"{d}_{s}" for d in DIGITS for s in PHALANX_STEMS),
)
BONE = RefKind(
    "bone",
    "!",
    "'!bone', '!bone(side)' or '!bone(side,n)', e.g. '!head', '!f_arm(s)', '!index(s,2)'",
    *_bone_stems(),
)


class References:
    """Resolves references on ``signer_map`` with the strong side ``strong`` (``R``/``L``)."""

    def __init__(self, signer_map: SignerMap, strong: str = "R"):
        self.map = signer_map
        self.strong = strong

    def side(self, loc: Loc, field: str, side: str, written: str) -> str:
        """``s``/``w``/``L``/``R`` as ``L`` or ``R``."""
        try:
            return resolve_side(side, self.strong)
        except ValueError:
            in_ = f" in '{written}'" if written != side else ""
            raise loc.fail(f"unknown side '{side}'{in_}", VALID_SIDES, field=field) from None

    def _split(self, loc: Loc, field: str, text: str, kind: RefKind):
        """Split ``STEM`` / ``STEM(side)`` / ``STEM(side,n)``: (stem, side, n)."""
        m = _REF_RE.match(text[1:])
        if not m:
            raise loc.fail(
                f"malformed {kind.noun} reference '{text}'", f"write {kind.example}", field=field
            )
        stem, args = m.group(1), m.group(2)
        if args is None:
            return stem, None, None
        parts = [a.strip() for a in args.split(",")]
        if len(parts) > 2 or not parts[0]:
            raise loc.fail(
                f"malformed {kind.noun} reference '{text}'", f"write {kind.example}", field=field
            )
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

    def _resolve(
        self, loc: Loc, field: str, text: str, kind: RefKind, names: Mapping[str, Any]
    ) -> str:
        """The full name ``text`` stands for among ``names`` (model sites or bones)."""
        stem, side, n = self._split(loc, field, text, kind)
        what, sg = f"{kind.noun} '{stem}'", kind.sigil
        if side is None and stem in names:
            return stem
        if side is not None and stem in kind.midline:
            raise loc.fail(
                f"{what} is on the midline and takes no side", f"write '{sg}{stem}'", field=field
            )
        if stem in kind.sided:
            if side is None:
                forms = ", ".join(f"'{sg}{stem}({s})'" for s in "swR") + f" or '{sg}{stem}(L)'"
                raise loc.fail(f"{what} needs a side", "write " + forms, field=field)
            if n is not None:
                raise loc.fail(
                    f"{what} takes no phalanx number", f"write '{sg}{stem}(s)'", field=field
                )
        if stem in kind.phalanx and (side is None or n is None):
            raise loc.fail(
                f"{what} needs a side and a phalanx number",
                f"write e.g. '{sg}{stem}(s,1)' (1 proximal to 3 distal)",
                field=field,
            )
        name = stem + (f"_{side}" if side else "") + (f"_{n}" if n else "")
        if name not in names:
            # Quote and suggest as written: '@I_TPI(s)' -> did you mean '@I_TIP(s)'?
            stems = sorted(kind.midline | kind.sided | kind.phalanx)
            match = difflib.get_close_matches(stem, stems, n=1, cutoff=0.6)
            if match:
                args = "" if match[0] in kind.midline else text[1 + len(stem) :]
                valid = f"did you mean '{sg}{match[0]}{args}'? {_SITES_HINT}"
            else:
                valid = "azee-mj sites lists all valid names"
            raise loc.fail(f"unknown {kind.noun} '{text}'", valid, field=field)
        return name

    def site(self, loc: Loc, field: str, text: str) -> SiteRef:
        """A body site ``@...`` or a locus ``^...``."""
        if text.startswith("^"):
            name = text[1:]
            if name not in self.map.loci:
                shown = [f"^{n}" for n in self.map.loci]
                raise loc.fail(
                    f"unknown locus '{text}'",
                    f"valid loci are {listing(shown)}" + suggest(text, shown),
                    field=field,
                )
            return SiteRef(name, locus=True)
        return SiteRef(self._resolve(loc, field, text, SITE, self.map.sites))

    def body_site(self, loc: Loc, field: str, v: Any, user: str) -> SiteRef:
        """A body site (not a locus): what ``user`` (e.g. "a place") moves."""
        if not isinstance(v, str) or not v.startswith(("@", "^")):
            raise loc.fail(f"expected a body site such as '@I_TIP(s)', got {got(v)}", field=field)
        if v.startswith("^"):
            raise loc.fail(
                f"'{v}' is a signing-space locus, not a body site",
                f"{user} moves a body site ('@...')",
                field=field,
            )
        return self.site(loc, field, v)

    def bone(self, loc: Loc, field: str, v: Any) -> BoneRef:
        """A bone ``!...``."""
        if not isinstance(v, str) or not v.startswith("!"):
            raise loc.fail(f"expected a bone such as '!f_arm(s)', got {got(v)}", field=field)
        return BoneRef(self._resolve(loc, field, v, BONE, self.map.bones))
