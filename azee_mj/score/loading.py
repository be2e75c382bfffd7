"""Reading a score: JSON in, validated :class:`~azee_mj.score.records.Score` out.

:func:`load_score` reads a JSON file or an already-parsed object, checks everything (the
checks and message shapes are in :mod:`azee_mj.score.validation`, references are resolved by
:mod:`azee_mj.score.references`) and returns the records.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from azee_mj.errors import ScoreError, shorten
from azee_mj.files import read_text
from azee_mj.score.constraint_reader import ConstraintReader
from azee_mj.score.records import (
    FORMAT,
    TIME_SLACK,
    VERSION,
    Block,
    BlockKind,
    Score,
)
from azee_mj.score.references import References
from azee_mj.score.validation import (
    MAX_DEPTH,
    MAX_NUMBER,
    Loc,
    check_depth,
    check_holds,
    check_keys,
    got,
    is_number,
    num,
    number,
    string,
)
from azee_mj.sites import DEFAULT_MAP, SignerMap, suggest
from azee_mj.timing import MAX_DURATION, child_span, root_span


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
        text = read_text(path)
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


_TOP_KEYS = ("format", "version", "strong_side", "root")
_TOP_REQUIRED = ("format", "version", "root")
_BLOCK_COMMON = ("name", "kind", "start", "end")
_BLOCK_KEYS = {
    BlockKind.SYNC: _BLOCK_COMMON + ("children",),
    BlockKind.CSTR: _BLOCK_COMMON + ("constraints",),
    BlockKind.HOLD: _BLOCK_COMMON + ("of",),
    BlockKind.TRANSPATH: _BLOCK_COMMON + ("site", "path"),
}


@dataclasses.dataclass(frozen=True)
class _Parent:
    """The block whose children are being read: its path, absolute start and end [s] and
    written duration [s] (None above the root)."""

    path: str
    start: float
    end: float | None
    duration: float | None


_ROOT = _Parent("", 0.0, None, None)


class _Loader:
    """Reads the block structure of a score and its times; what each block does is read by
    a :class:`~azee_mj.score.constraint_reader.ConstraintReader`."""

    def __init__(self, signer_map: SignerMap):
        self.refs = References(signer_map)
        self.contents = ConstraintReader(self.refs)

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
        root = self.block(data["root"], Loc("", "root block"), _ROOT)
        if root.kind is BlockKind.HOLD:
            raise Loc(root.path).fail(
                f"no sibling block named '{data['root']['of']}'",
                "the root block has no siblings to hold",
                field="of",
            )
        return Score(strong_side=strong, root=root, annotations=annotations)

    # -- blocks --------------------------------------------------------------------------

    def block(self, obj: Any, pre: Loc, parent: _Parent) -> Block:
        """Parse one block. ``pre`` locates it before its name is known."""
        name = self.block_name(pre, obj)
        path = f"{parent.path}.{name}" if parent.path else name
        loc = Loc(path)
        kind = self.block_kind(loc, obj)
        annotations = check_keys(loc, obj, _BLOCK_KEYS[kind], (), f"a {kind.value} block")
        start = number(loc, "start", obj["start"])
        end = number(loc, "end", obj["end"])
        abs_start, abs_end = self.span(loc, obj, start, end, parent)
        fields: dict[str, Any] = {}
        if kind is BlockKind.SYNC:
            here = _Parent(path, abs_start, abs_end, end - start)
            fields["children"] = self.children(loc, obj["children"], here)
        elif kind is BlockKind.CSTR:
            fields["constraints"] = self.contents.constraints(loc, obj["constraints"])
        elif kind is BlockKind.HOLD:
            of = string(loc, "of", obj["of"])
            fields["hold_of"] = f"{parent.path}.{of}" if parent.path else of
        else:
            fields["transpath_site"] = self.refs.body_site(loc, "site", obj["site"], "a transpath")
            fields["route"] = self.contents.route(loc, obj["path"])
        return Block(
            name=name,
            path=path,
            kind=kind,
            start=abs_start,
            end=abs_end,
            annotations=annotations,
            **fields,
        )

    def block_name(self, pre: Loc, obj: Any) -> str:
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
        return name

    def block_kind(self, loc: Loc, obj: Mapping[str, Any]) -> BlockKind:
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
        return BlockKind(kind_s)

    def span(
        self, loc: Loc, obj: Mapping[str, Any], start: float, end: float, parent: _Parent
    ) -> tuple[float, float]:
        """The block's absolute ``(start, end)`` [s], made once here on the microsecond grid
        (see :mod:`azee_mj.timing`), after checking it lies within its parent."""
        if not start < end:
            raise loc.fail(
                f"end {got(obj['end'])} is not after start {got(obj['start'])}",
                "a block needs start < end",
                field="end",
            )
        if parent.duration is None:
            abs_start, abs_end = root_span(start, end)
            if abs_end > MAX_DURATION:
                raise loc.fail(
                    f"the score lasts {num(end - start)} s",
                    f"the longest score is {MAX_DURATION:g} s (1 hour)",
                    field="end",
                )
        else:
            inside = (
                "a child's times are relative to its parent's start and lie within "
                f"[0, {num(parent.duration)}]"
            )
            if start < -TIME_SLACK:
                raise loc.fail(
                    f"{got(obj['start'])} is before the start of its parent {parent.path}",
                    inside,
                    field="start",
                )
            if end > parent.duration + TIME_SLACK:
                raise loc.fail(
                    f"{got(obj['end'])} is after the end of its parent {parent.path}",
                    inside,
                    field="end",
                )
            abs_start, abs_end = child_span(start, end, parent.start, parent.end)
        if abs_end <= abs_start:
            raise loc.fail(
                f"lasts {num(end - start)} s",
                "a block lasts at least 1e-06 s (times are resolved to the microsecond)",
                field="end",
            )
        return abs_start, abs_end

    def children(self, loc: Loc, items: Any, parent: _Parent) -> tuple[Block, ...]:
        if not isinstance(items, (list, tuple)):
            raise loc.fail(f"expected a list of blocks, got {got(items)}", field="children")
        blocks: list[Block] = []
        seen: dict[str, int] = {}
        for i, item in enumerate(items, 1):
            child = self.block(item, Loc(loc.path, f"child {i}"), parent)
            if child.name in seen:
                raise Loc(loc.path, f"child {i}").fail(
                    f"duplicate name '{child.name}' (child {seen[child.name]} has it too)",
                    "sibling names must be unique",
                    field="name",
                )
            seen[child.name] = i
            blocks.append(child)
        check_holds(loc.path, tuple(blocks), parent.start)
        return tuple(blocks)
