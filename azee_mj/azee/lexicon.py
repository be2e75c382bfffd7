"""The lexicon: signs as score templates (``NAME.json``) or expressions (``NAME.azee``).

A template is an ``azee-score`` file whose ``x-params`` declares parameters, e.g.
``{"loc": {"kind": "locus", "default": "^ssp"}}``; the string ``"$loc"`` then stands for a
point (a locus) or a number anywhere in the blocks. Signs are looked up in each user
directory in order, then in the bundled ``azee_mj/azee/lexicon/``. A template's
``strong_side`` and ``x-`` keys are dropped when it is used.
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from azee_mj.azee.catalogue import Param
from azee_mj.azee.errors import ExpressionError
from azee_mj.azee.rules import BY_NAME
from azee_mj.files import read_text

BUNDLED = Path(__file__).parent / "lexicon"
PARAM_KINDS = ("locus", "num")


@dataclasses.dataclass(frozen=True)
class Sign:
    """One lexicon entry. ``template`` is the root block of a ``.json`` sign (None for an
    ``.azee`` sign, whose ``text`` is its expression)."""

    name: str
    path: Path
    params: tuple[Param, ...] = ()
    template: Mapping[str, Any] | None = None
    text: str | None = None
    summary: str = ""

    @property
    def duration(self) -> float | None:
        """Duration [s] of a template sign (None for an expression sign)."""
        if self.template is None:
            return None
        return float(self.template["end"]) - float(self.template["start"])

    def signature(self) -> str:
        return ", ".join(p.signature() for p in self.params)


def _fail(path: Path, problem: str) -> ExpressionError:
    return ExpressionError(problem, file=str(path), path="")


class Lexicon:
    """Signs by name: each of ``dirs`` first (in order), then the bundled lexicon."""

    def __init__(self, dirs: Iterable[str | Path] = ()):
        self.dirs = tuple(Path(d) for d in dirs)
        self._files: dict[str, Path] = {}
        for d in (*self.dirs, BUNDLED):
            if not os.path.isdir(d):
                raise ExpressionError("not a directory of signs (--lexicon)", file=str(d), path="")
            try:
                files = sorted(d.iterdir())
            except OSError as e:
                raise _fail(d, f"cannot read the directory: {e.strerror or e}") from None
            for p in files:
                if p.suffix not in (".json", ".azee") or p.stem in self._files:
                    continue
                if p.stem in BY_NAME:
                    raise _fail(
                        p, f"a sign may not be named like the rule :{p.stem}; rename the file"
                    )
                self._files[p.stem] = p
        self._cache: dict[str, Sign] = {}

    def names(self) -> list[str]:
        return sorted(self._files)

    def __contains__(self, name: str) -> bool:
        return name in self._files

    def get(self, name: str) -> Sign:
        """The sign ``name`` (KeyError if none), read and checked on first use."""
        if name not in self._cache:
            self._cache[name] = read_sign(name, self._files[name])
        return self._cache[name]


def read_sign(name: str, path: Path) -> Sign:
    """Read one sign file; its declared parameters are checked, its blocks are checked by
    the score loader when it is used."""
    try:
        text = read_text(path)
    except OSError as e:
        raise _fail(path, f"lexicon :{name}: cannot read the sign: {e.strerror or e}") from None
    except UnicodeDecodeError as e:
        raise _fail(path, f"lexicon :{name}: not a UTF-8 text file: {e.reason}") from None
    if path.suffix == ".azee":
        return Sign(name, path, text=text)
    try:
        data = json.loads(text)
    except json.JSONDecodeError as e:
        raise _fail(
            path, f"lexicon :{name}: line {e.lineno} column {e.colno}: invalid JSON: {e.msg}"
        ) from None
    if not isinstance(data, dict) or not isinstance(data.get("root"), dict):
        raise _fail(path, f"lexicon :{name}: expected an azee-score object with a 'root' block")
    root = data["root"]
    if not all(isinstance(root.get(k), (int, float)) for k in ("start", "end")):
        raise _fail(path, f"lexicon :{name}: the root block needs numeric 'start' and 'end'")
    raw = data.get("x-params", {})
    if not isinstance(raw, dict):
        raise _fail(
            path,
            f"lexicon :{name}: 'x-params' must be an object of name -> "
            '{"kind": ..., "default": ...}',
        )
    params = []
    for p, spec in raw.items():
        kind = spec.get("kind") if isinstance(spec, dict) else None
        if kind not in PARAM_KINDS:
            raise _fail(
                path,
                f"lexicon :{name}: parameter '{p}: kind must be one of "
                f"{', '.join(PARAM_KINDS)}, got {kind!r}",
            )
        params.append(Param(p, kind, spec.get("default")))
    summary = data.get("x-summary") or data.get("x-source", "")
    return Sign(name, path, tuple(params), root, summary=str(summary))


def fill(template: Any, values: Mapping[str, Any], declared: Iterable[str]) -> Any:
    """A copy of ``template`` with each string ``"$p"`` replaced by ``values[p]``; raise
    KeyError(p) for an undeclared ``$p``."""
    declared = set(declared)
    if isinstance(template, dict):
        return {k: fill(v, values, declared) for k, v in template.items()}
    if isinstance(template, list):
        return [fill(v, values, declared) for v in template]
    if isinstance(template, str) and template.startswith("$"):
        if template[1:] not in declared:
            raise KeyError(template[1:])
        return values[template[1:]]
    return template
