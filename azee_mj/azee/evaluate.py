"""Evaluate a parsed expression into an ``azee-score`` v1 dict.

``:name`` resolves to a rule first, then to a sign. Arguments are bound by label or
position, checked for kind, and each rule lays its arguments out on its own time line.
Error paths are the chain of rules and labels from the root
(``:info-about'info:tens-units'tens``).
"""

from __future__ import annotations

import difflib
import json
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from azee_mj.azee.catalogue import (
    DIGITS,
    KINDS,
    LOCI,
    Lit,
    Param,
    ScoreVal,
    Timeline,
    block_name,
    fmt_value,
    look,
    quote,
)
from azee_mj.azee.errors import ExpressionError
from azee_mj.azee.lexicon import Lexicon, Sign, fill
from azee_mj.azee.nonmanual import RuleProblem
from azee_mj.azee.rules import BY_NAME, RULES
from azee_mj.azee.syntax import MAX_NESTING, App, Arg, Atom, Node, parse
from azee_mj.errors import ScoreError
from azee_mj.files import read_text
from azee_mj.score import load_score

#: Deepest nesting of rules and signs evaluated (the parser's limit, signs included).
MAX_DEPTH = MAX_NESTING
#: Decimals output times are rounded to [s].
TIME_DECIMALS = 9
_ATOM_KIND = {"locus": "locus", "atom": "digit", "num": "num", "text": "text"}


def _close(name: str, valid) -> str | None:
    """The closest valid name, for a did-you-mean (None when nothing is close)."""
    m = difflib.get_close_matches(name, list(valid), n=1, cutoff=0.6)
    return m[0] if m else None


def _kind_of(node: Node) -> str:
    return "score" if isinstance(node, App) else _ATOM_KIND[node.kind]


def _describe(node: Node) -> str:
    if isinstance(node, App):
        return f"score :{node.name}"
    if node.kind == "text":
        return f"text {quote(node.text)}"
    sigil = {"locus": "^", "atom": ".", "num": ""}[node.kind]
    return f"{_kind_of(node)} {sigil}{node.text}"


def _err(file: str, problem: str, line: int, col: int, path: str) -> ExpressionError:
    return ExpressionError(problem, file=file, line=line, col=col, path=path)


def _atom(node: Atom, path: str, file: str) -> Lit:
    """The value of a locus, digit, number or text atom; ``path`` and ``file`` for errors."""
    if node.kind == "locus":
        if node.text not in LOCI:
            m = _close(node.text, LOCI)
            hint = f"; did you mean '^{m}'? Valid" if m else "; valid"
            raise _err(
                file,
                f"unknown locus '^{node.text}'{hint} loci are ^ssp, ^Rssp, ^Lssp",
                node.line,
                node.col,
                path or "syntax",
            )
        return Lit("locus", f"^{node.text}", f"^{node.text}")
    if node.kind == "atom":
        if node.text not in DIGITS:
            raise _err(
                file,
                f"unknown atom '.{node.text}'; atoms are .nb-0 to .nb-9",
                node.line,
                node.col,
                path or "syntax",
            )
        return Lit("digit", int(node.text[3:]), f".{node.text}")
    if node.kind == "text":
        return Lit("text", node.text, quote(node.text))
    return Lit("num", node.value, fmt_value(node.value))


def _default(p: Param, keep_lits: bool) -> Any:
    """A parameter's default: a float, or a :class:`Lit` (``keep_lits``, or not a number)."""
    if p.kind == "num":
        return Lit("num", float(p.default), fmt_value(p.default)) if keep_lits else float(p.default)
    if p.kind == "text":
        return Lit("text", p.default, quote(p.default))
    return Lit(p.kind, p.default, fmt_value(p.default))


class _Evaluator:
    def __init__(self, lexicon: Lexicon, strong_side: str, file: str):
        self.lex = lexicon
        self.strong = strong_side
        self.file = file
        self.signs: list[str] = []  # expression signs being evaluated (cycle check)
        self.depth = 0
        self.where: tuple[int, int, str] = (0, 0, "")  # the application being built
        self.templates: dict[tuple, ScoreVal] = {}

    def err(self, problem: str, line: int, col: int, path: str) -> ExpressionError:
        return ExpressionError(problem, file=self.file, line=line, col=col, path=path)

    # -- values -------------------------------------------------------------------------
    def value(self, node: Node, path: str) -> Lit | ScoreVal:
        if isinstance(node, Atom):
            return _atom(node, path, self.file)
        here = f"{path}:{node.name}"
        if node.name.startswith("azop"):
            raise self.err(
                f"low-level operators (:{node.name}) are not supported; write a "
                "rule or a sign (azee-mj rules lists all)",
                node.line,
                node.col,
                here,
            )
        self.depth += 1
        try:
            if self.depth > MAX_DEPTH:
                raise self.err(f"nesting deeper than {MAX_DEPTH} levels", node.line, node.col, here)
            rule = BY_NAME.get(node.name)
            if rule is not None:
                here = f"{path}:{rule.name}"
                if not rule.implemented:
                    raise self.err(
                        "not implemented: azee_mj has no manual alphabet; write "
                        "the word with signs of the lexicon",
                        node.line,
                        node.col,
                        here,
                    )
                args, head, _ = self.bind(node, rule.params, f":{rule.name}", here)
                saved, self.where = self.where, (node.line, node.col, here)
                try:
                    return rule.build(self, args, head)
                except RuleProblem as p:
                    at = f"{here}'{p.label}" if p.label else here
                    raise self.err(p.problem, node.line, node.col, at) from None
                finally:
                    self.where = saved
            if node.name in self.lex:
                sign = self.lex.get(node.name)
                saved, self.where = self.where, (node.line, node.col, here)
                try:
                    given, head, explicit = self.bind(
                        node, sign.params, f":{sign.name}", here, keep_lits=True
                    )
                    return self.apply_sign(sign, given, head, explicit)
                finally:
                    self.where = saved
            m = _close(node.name, [*BY_NAME, *self.lex.names()])
            hint = f"; did you mean ':{m}'?" if m else ""
            raise self.err(
                f"unknown rule or sign ':{node.name}'{hint} (azee-mj rules lists all)",
                node.line,
                node.col,
                here,
            )
        finally:
            self.depth -= 1

    # -- arguments ------------------------------------------------------------------------
    def bind(
        self, node: App, params: tuple[Param, ...], callee: str, here: str, keep_lits: bool = False
    ) -> tuple[dict[str, Any], str, set[str]]:
        """Bind ``node``'s arguments to ``params``; returns (name -> value, canonical text,
        the names given explicitly).
        List parameters get lists; numbers are floats (or :class:`Lit` with ``keep_lits``),
        loci and digits :class:`Lit`, scores :class:`ScoreVal`."""
        sig = ", ".join(p.signature() for p in params) or "no arguments"
        takes = f"it takes {sig}" if params else "it takes no arguments"
        assigned = self._assign(node, params, callee, here, sig, takes)
        out: dict[str, Any] = {}
        parts: list[str] = []
        for p in params:
            given = assigned.get(p.name)
            if not given:
                if p.default is None:
                    raise self.err(
                        f"missing argument '{p.name} for {callee}; {takes}",
                        node.line,
                        node.col,
                        here,
                    )
                out[p.name] = _default(p, keep_lits)
                continue
            out[p.name] = self._bind_param(p, given, here, takes, keep_lits, parts)
        head = f"{callee}({', '.join(parts)})" if parts else callee
        return out, head, set(assigned)

    def _assign(
        self, node: App, params: tuple[Param, ...], callee: str, here: str, sig: str, takes: str
    ) -> dict[str, list[Arg]]:
        """Match ``node``'s arguments, positional then labelled, to parameter names."""
        by_name = {p.name: p for p in params}
        assigned: dict[str, list[Arg]] = {}
        seen_label = False
        positional = iter(params)
        current: Param | None = None
        for a in node.args:
            if a.label is None:
                if seen_label:
                    raise self.err(
                        "a positional argument after a labelled one; positional "
                        "arguments come first, in parameter order",
                        a.line,
                        a.col,
                        here,
                    )
                if current is None or not current.list:
                    current = next(positional, None)
                if current is None:
                    n = len(node.args)
                    raise self.err(
                        f"too many arguments for {callee} ({n} given); {takes}", a.line, a.col, here
                    )
                assigned.setdefault(current.name, []).append(a)
                continue
            seen_label = True
            p = by_name.get(a.label)
            if p is None:
                m = _close(a.label, list(by_name))
                tail = f"; did you mean '{m}? It takes {sig}" if m else f"; {takes}"
                raise self.err(
                    f"unknown argument '{a.label} for {callee}{tail}", a.line, a.col, here
                )
            if p.name in assigned and not p.list:
                raise self.err(
                    f"repeated argument '{p.name} for {callee}; {takes}", a.line, a.col, here
                )
            assigned.setdefault(p.name, []).append(a)
        return assigned

    def _bind_param(
        self, p: Param, given: list[Arg], here: str, takes: str, keep_lits: bool, parts: list[str]
    ) -> Any:
        """Check and evaluate the arguments given to ``p``; appends their canonical text
        to ``parts``."""
        if p.list and len(given) < p.min_items:
            a = given[-1]
            raise self.err(
                f"'{p.name}: expected at least {p.min_items} items, got {len(given)}; {takes}",
                a.line,
                a.col,
                here,
            )
        vals = []
        for a in given:
            kind = _kind_of(a.value)
            if kind != p.kind:
                raise self.err(
                    f"'{p.name}: expected {KINDS[p.kind]}, got {_describe(a.value)}",
                    a.value.line,
                    a.value.col,
                    here,
                )
            v = self.value(a.value, f"{here}'{p.name}")
            if p.kind == "num":
                self.check_num(p, v, a.value, here)
            vals.append(v)
            parts.append(f"'{p.name} {v.head if isinstance(v, ScoreVal) else v.text}")
        if p.kind == "num" and not keep_lits:
            vals = [v.value for v in vals]
        return vals if p.list else vals[0]

    def check_num(self, p: Param, v: Lit, node: Node, here: str) -> None:
        if p.minimum is None:
            return
        if v.value < p.minimum or (p.strict and v.value == p.minimum):
            op = ">" if p.strict else ">="
            raise self.err(
                f"'{p.name}: expected a number {op} {fmt_value(p.minimum)}, got {v.text}",
                node.line,
                node.col,
                here,
            )

    # -- signs ------------------------------------------------------------------------------
    def apply_sign(
        self, sign: Sign, given: Mapping[str, Lit], head: str, explicit: Iterable[str] = ()
    ) -> ScoreVal:
        """The sign with every parameter in ``given``; ``explicit`` names those the
        expression filled (a rule may fill the others)."""
        line, col, here = self.where
        if sign.template is None:
            return self.expression_sign(sign, head)
        explicit = {k: given[k] for k in explicit}
        values = {p.name: given[p.name].value for p in sign.params}
        key = (sign.name, tuple(sorted((k, str(v)) for k, v in values.items())))
        if key not in self.templates:
            try:
                root = fill(sign.template, values, (p.name for p in sign.params))
            except KeyError as e:
                declared = ", ".join(f"'{p.name}" for p in sign.params) or "none"
                raise self.err(
                    f'lexicon :{sign.name}: "${e.args[0]}" is not a declared '
                    f"parameter; declared: {declared}",
                    line,
                    col,
                    here,
                ) from None
            try:
                load_score(
                    {
                        "format": "azee-score",
                        "version": 1,
                        "strong_side": self.strong,
                        "root": {**root, "name": block_name(sign.name)},
                    }
                )
            except ScoreError as e:
                raise self.err(f"lexicon :{sign.name}: {e}", line, col, here) from None
            body = {k: v for k, v in root.items() if k not in ("name", "start", "end")}
            duration = float(root["end"]) - float(root["start"])
            self.templates[key] = ScoreVal("", sign.name, duration, body)
        t = self.templates[key]
        return ScoreVal(head, sign.name, t.duration, t.body, sign, explicit)

    def expression_sign(self, sign: Sign, head: str) -> ScoreVal:
        line, col, here = self.where
        if sign.name in self.signs:
            chain = " -> ".join(
                f":{s}" for s in [*self.signs[self.signs.index(sign.name) :], sign.name]
            )
            raise self.err(f"lexicon cycle {chain}", line, col, here)
        self.signs.append(sign.name)
        saved_file, self.file = self.file, str(sign.path)
        try:
            node = parse(sign.text or "", str(sign.path))
            val = self.value(node, "")
        finally:
            self.file = saved_file
            self.signs.pop()
        if not isinstance(val, ScoreVal):
            raise self.err(
                f"lexicon :{sign.name}: the expression is a {val.kind}, not a score",
                line,
                col,
                here,
            )
        return ScoreVal(head, val.origin, val.duration, val.body, sign, {})

    # -- for rules ----------------------------------------------------------------------------
    def sign_value(self, name: str, params: Mapping[str, Lit]) -> ScoreVal:
        """The sign ``name`` with ``params`` (the others at their defaults)."""
        line, col, here = self.where
        if name not in self.lex:
            raise self.err(
                f"this rule needs the sign :{name}, which the lexicon lacks", line, col, here
            )
        sign = self.lex.get(name)
        given = {}
        for p in sign.params:
            if p.name in params:
                given[p.name] = params[p.name]
            elif p.default is None:
                raise self.err(f"this rule needs :{name} to default its '{p.name}", line, col, here)
            else:
                given[p.name] = _default(p, True)
        parts = [f"'{k} {v.text}" for k, v in params.items()]
        head = f":{name}({', '.join(parts)})" if parts else f":{name}"
        return self.apply_sign(sign, given, head, params)

    def localise(self, val: ScoreVal, locus: Lit) -> ScoreVal:
        """``SIG`` = the value with its unfilled ``loc`` set to ``locus`` and a ``GAZE`` at
        it, or, when it has none, ``SIG`` then ``POINT`` = ``:ix('loc locus)``."""
        tl = Timeline()
        sign: Sign | None = val.sign
        has_loc = sign is not None and any(
            p.name == "loc" and p.kind == "locus" for p in sign.params
        )
        if has_loc and "loc" not in val.given:
            given = {p.name: val.given.get(p.name) or _default(p, True) for p in sign.params}
            given["loc"] = locus
            s, e = tl.put("SIG", self.apply_sign(sign, given, val.head, val.given))
            tl.cstr("GAZE", s, e, [look(locus.value)])
        else:
            tl.put("SIG", val)
            tl.put("POINT", self.sign_value("ix", {"loc": locus}))
        return tl.value("", "localise")


def dump_score(score: dict) -> str:
    """A score dict as the JSON text ``azee-mj compile`` writes (one-space indent, UTF-8)."""
    return json.dumps(score, indent=1, ensure_ascii=False) + "\n"


def _round_times(block: dict) -> dict:
    block["start"] = round(float(block["start"]), TIME_DECIMALS)
    block["end"] = round(float(block["end"]), TIME_DECIMALS)
    for c in block.get("children", ()):
        _round_times(c)
    return block


def compile_node(
    node: Node, *, strong_side: str = "R", lexicon: Lexicon | None = None, file: str = "<text>"
) -> dict:
    """The score dict of a parsed expression (see :func:`compile_text`)."""
    if strong_side not in ("R", "L"):
        raise ExpressionError(
            f"strong side must be R or L, got {strong_side!r}", file=file, path=""
        )
    ev = _Evaluator(lexicon or Lexicon(), strong_side, file)
    val = ev.value(node, "")
    if not isinstance(val, ScoreVal):
        raise ExpressionError(
            f"the expression is a {val.kind}, not a score; a file holds one "
            ":rule or :sign application",
            file=file,
            line=node.line,
            col=node.col,
            path=val.text,
        )
    name = node.name
    rule = BY_NAME.get(name)
    root = _round_times(val.block(block_name(rule.name if rule else name), 0.0))
    return {
        "format": "azee-score",
        "version": 1,
        "strong_side": strong_side,
        "x-source": val.head,
        "root": root,
    }


def compile_text(
    text: str,
    strong_side: str = "R",
    lexicon: Iterable[str | Path] | Lexicon = (),
    *,
    file: str = "<text>",
) -> dict:
    """Compile one ``.azee`` expression to an ``azee-score`` v1 dict.

    Args:
      text: the expression, layout or inline form.
      strong_side: ``"R"`` or ``"L"``, written as the score's ``strong_side``.
      lexicon: user sign directories (searched in order before the bundled lexicon), or a
        :class:`Lexicon`.
      file: the name errors give for ``text``.

    Raises:
      ExpressionError: with ``.path``, ``.line``, ``.col`` (one message, see the module).
    """
    lex = lexicon if isinstance(lexicon, Lexicon) else Lexicon(lexicon)
    return compile_node(parse(text, file), strong_side=strong_side, lexicon=lex, file=file)


def compile_score(
    text: str,
    strong_side: str = "R",
    lexicon: Iterable[str | Path] | Lexicon = (),
    *,
    file: str = "<text>",
):
    """:func:`compile_text`, loaded as a :class:`azee_mj.score.Score` record."""
    return load_score(compile_text(text, strong_side, lexicon, file=file))


def compile_file(
    path: str | Path, strong_side: str = "R", lexicon: Iterable[str | Path] | Lexicon = ()
) -> dict:
    """Compile the ``.azee`` file at ``path`` (see :func:`compile_text`)."""
    path = Path(path)
    try:
        text = read_text(path)
    except OSError as e:
        raise ExpressionError(
            f"cannot read the expression: {e.strerror or e}", file=str(path), path=""
        ) from None
    except UnicodeDecodeError as e:
        raise ExpressionError(
            f"not a UTF-8 text file: {e.reason}", file=str(path), path=""
        ) from None
    return compile_text(text, strong_side, lexicon, file=str(path))


def rules_catalogue(lexicon: Lexicon | None = None) -> dict:
    """Rules and signs as ``azee-mj rules --json`` prints them."""
    lex = lexicon or Lexicon()
    signs = []
    for n in lex.names():
        s = lex.get(n)
        signs.append(
            {
                "name": n,
                "params": [p.to_json() for p in s.params],
                "duration": s.duration,
                "summary": s.summary,
                "file": s.path.name
                if s.path.parent == Path(__file__).parent / "lexicon"
                else str(s.path),
            }
        )
    return {"rules": [r.to_json() for r in RULES], "signs": signs}
