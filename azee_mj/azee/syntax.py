"""Parse ``.azee`` text, in its corpus layout form or its inline form, into a small tree.

Grammar (design contract, section 1)::

    expr  := app | "^" ident | "." ident | number | text   # locus; atom .nb-0 ... .nb-9
    text  := '"' { any character but '"' and '\\', or '\\"' or '\\\\' } '"'   # on one line
    app   := ":" ident [ "(" [ arg {"," arg} ] ")" ]
    arg   := [ "'" ident ] expr
    ident := letter (any script) {letter | digit | "-" | "_"}

Parentheses and layout levels nest at most :data:`MAX_NESTING` deep each (a clean error
beyond, not a ``RecursionError``). ``#`` starts a comment. In the **layout form** each line is ``expr``, ``'label`` or
``'label expr``; an application's arguments are the following lines indented deeper than
it, and a label takes the next expression line, at least as deep as the label. Inside
parentheses layout is ignored. Positions are 1-based lines and columns (characters).
"""

from __future__ import annotations

import dataclasses
import re
import unicodedata

from azee_mj.azee.errors import ExpressionError


@dataclasses.dataclass(frozen=True)
class Atom:
    """A locus (``^Rssp``: kind ``locus``), a digit atom (``.nb-5``: ``atom``), a number
    (``num``) or a text (``"maison"``: ``text``); ``text`` is as written without its sigil
    (a text without its quotes and escapes), ``value`` the number for ``num``."""

    kind: str
    text: str
    line: int
    col: int
    value: float = 0.0


@dataclasses.dataclass(frozen=True)
class Arg:
    """One argument: its label (None when positional) and its expression; ``line``/``col``
    locate the label, or the expression when there is none."""

    label: str | None
    value: Node
    line: int
    col: int


@dataclasses.dataclass(frozen=True)
class App:
    """``:name`` applied to ``args``; ``parens`` when written with parentheses."""

    name: str
    args: tuple[Arg, ...]
    line: int
    col: int
    parens: bool = False


Node = App | Atom


@dataclasses.dataclass(frozen=True)
class _Tok:
    kind: str  # app locus atom num label ( ) ,
    text: str
    line: int
    col: int
    first: bool  # first token of its physical line


#: Deepest nesting of parentheses, and of layout levels, the parser accepts.
MAX_NESTING = 64

_NUM = re.compile(r"-?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?")
_SIGILS = {":": "app", "^": "locus", ".": "atom", "'": "label"}
_WHAT = {
    "app": "an application",
    "locus": "a locus",
    "atom": "an atom",
    "num": "a number",
    "text": "a text",
    "label": "a label",
    "(": "'('",
    ")": "')'",
    ",": "','",
}


def _ident_end(s: str, i: int) -> int:
    """End of an identifier starting at ``s[i]`` (``i`` itself when none starts there)."""
    if i >= len(s) or not s[i].isalpha():
        return i
    j = i + 1
    while j < len(s) and (s[j].isalnum() or s[j] in "-_"):
        j += 1
    return j


class _Parser:
    def __init__(self, text: str, file: str):
        self.file = file
        self.text = unicodedata.normalize("NFC", text)

    def err(self, problem: str, line: int, col: int) -> ExpressionError:
        return ExpressionError(problem, file=self.file, line=line, col=col, path="syntax")

    def too_deep(self, line: int, col: int) -> ExpressionError:
        return self.err(f"nesting deeper than {MAX_NESTING} levels", line, col)

    # -- tokens ---------------------------------------------------------------------------
    def tokens(self) -> list[_Tok]:
        out: list[_Tok] = []
        for ln, raw in enumerate(self.text.split("\n"), start=1):
            s = raw.rstrip("\r")
            i, first = 0, True
            while i < len(s):
                c = s[i]
                if c == "#":
                    break
                if c == "\t":
                    raise self.err("tab character; indent and separate with spaces", ln, i + 1)
                if c.isspace():
                    i += 1
                    continue
                col = i + 1
                if c in "(),":
                    out.append(_Tok(c, c, ln, col, first))
                    i += 1
                elif c in _SIGILS:
                    j = _ident_end(s, i + 1)
                    if j == i + 1:
                        raise self.err(
                            f"expected a name after {c!r}; a name starts with a letter", ln, col
                        )
                    out.append(_Tok(_SIGILS[c], s[i + 1 : j], ln, col, first))
                    i = j
                elif c == '"':
                    text, i = self.text_literal(s, i, ln)
                    out.append(_Tok("text", text, ln, col, first))
                    first = False
                    continue
                elif c == "?":
                    raise self.err("templates (?x) are not supported; write the value", ln, col)
                elif m := _NUM.match(s, i):
                    out.append(_Tok("num", m.group(), ln, col, first))
                    i = m.end()
                else:
                    raise self.err(
                        f"unexpected character {c!r}; an expression starts with "
                        ':name, ^locus, .atom, \'label, a number or a "text"',
                        ln,
                        col,
                    )
                first = False
        return out

    def text_literal(self, s: str, i: int, ln: int) -> tuple[str, int]:
        """The text literal opening at ``s[i]`` (unescaped) and the index after it."""
        out, j = [], i + 1
        while j < len(s):
            c = s[j]
            if c == '"':
                return "".join(out), j + 1
            if c == "\\":
                if j + 1 < len(s) and s[j + 1] in '"\\':
                    out.append(s[j + 1])
                    j += 2
                    continue
                raise self.err('bad escape in a text; write \\" or \\\\', ln, j + 1)
            out.append(c)
            j += 1
        raise self.err('unterminated text: a text ends with " on the same line', ln, i + 1)

    # -- logical lines ----------------------------------------------------------------------
    def lines(self, toks: list[_Tok]) -> list[list[_Tok]]:
        """Tokens grouped by layout lines: a new one starts at a line's first token outside
        parentheses."""
        out: list[list[_Tok]] = []
        opened: list[_Tok] = []
        for t in toks:
            if t.first and not opened:
                out.append([])
            out[-1].append(t)
            if t.kind == "(":
                opened.append(t)
                if len(opened) > MAX_NESTING:
                    raise self.too_deep(t.line, t.col)
            elif t.kind == ")":
                if not opened:
                    raise self.err("unbalanced parentheses: ')' without '('", t.line, t.col)
                opened.pop()
        if opened:
            t = opened[-1]
            raise self.err("unbalanced parentheses: '(' is never closed", t.line, t.col)
        return out

    # -- inline expressions -----------------------------------------------------------------
    def expr(self, toks: list[_Tok], i: int) -> tuple[Node, int]:
        if i >= len(toks):
            last = toks[-1]
            raise self.err("expected an expression", last.line, last.col + len(last.text) + 1)
        t = toks[i]
        if t.kind == "app":
            if i + 1 < len(toks) and toks[i + 1].kind == "(":
                args, j = self.arglist(toks, i + 2, toks[i + 1])
                return App(t.text, tuple(args), t.line, t.col, True), j
            return App(t.text, (), t.line, t.col), i + 1
        if t.kind == "locus":
            return Atom("locus", t.text, t.line, t.col), i + 1
        if t.kind == "atom":
            return Atom("atom", t.text, t.line, t.col), i + 1
        if t.kind == "num":
            return Atom("num", t.text, t.line, t.col, float(t.text)), i + 1
        if t.kind == "text":
            return Atom("text", t.text, t.line, t.col), i + 1
        raise self.err(f"expected an expression, got {_WHAT[t.kind]}", t.line, t.col)

    def arglist(self, toks: list[_Tok], i: int, opener: _Tok) -> tuple[list[Arg], int]:
        args: list[Arg] = []
        if i < len(toks) and toks[i].kind == ")":
            return args, i + 1
        while True:
            if i >= len(toks):
                raise self.err(
                    "unbalanced parentheses: '(' is never closed", opener.line, opener.col
                )
            t = toks[i]
            label = None
            if t.kind == "label":
                label, i = t.text, i + 1
                if i >= len(toks) or toks[i].kind in (",", ")"):
                    raise self.err(f"label '{label} without a value", t.line, t.col)
            value, i = self.expr(toks, i)
            args.append(Arg(label, value, t.line, t.col))
            if i < len(toks) and toks[i].kind == ",":
                i += 1
                continue
            if i < len(toks) and toks[i].kind == ")":
                return args, i + 1
            if i >= len(toks):
                raise self.err(
                    "unbalanced parentheses: '(' is never closed", opener.line, opener.col
                )
            u = toks[i]
            raise self.err(f"expected ',' or ')', got {_WHAT[u.kind]}", u.line, u.col)

    # -- layout -------------------------------------------------------------------------------
    def parse(self) -> Node:
        toks = self.tokens()
        if not toks:
            raise self.err("no expression; a file holds one expression", 1, 1)
        self.ls = []
        for group in self.lines(toks):
            head = group[0]
            label, k = (head, 1) if head.kind == "label" else (None, 0)
            node = None
            if k < len(group):
                node, j = self.expr(group, k)
                if j < len(group):
                    u = group[j]
                    raise self.err(
                        "a second expression on one line; put each argument on "
                        "its own line or inside parentheses",
                        u.line,
                        u.col,
                    )
            self.ls.append((head.col - 1, label, node, head))
        _, label, _, head = self.ls[0]
        if label is not None:
            raise self.err(f"label '{label.text} outside an application", head.line, head.col)
        node, nxt = self.value(0)
        if nxt < len(self.ls):
            h = self.ls[nxt][3]
            raise self.err(
                "a second expression; a file holds one expression (arguments "
                "are indented deeper than their application)",
                h.line,
                h.col,
            )
        return node

    def value(self, i: int, depth: int = 1) -> tuple[Node, int]:
        """The expression of layout line ``i`` (``depth`` layout levels deep) with its
        layout arguments; next line index."""
        indent, _, node, head = self.ls[i]
        if depth > MAX_NESTING:
            raise self.too_deep(head.line, head.col)
        end = i + 1
        while end < len(self.ls) and self.ls[end][0] > indent:
            end += 1
        if end == i + 1:
            return node, end
        h = self.ls[i + 1][3]
        if not isinstance(node, App):
            raise self.err(
                f"{_WHAT[node.kind]} takes no arguments; this line is indented deeper than it",
                h.line,
                h.col,
            )
        if node.parens:
            raise self.err(
                f"arguments of :{node.name} go in parentheses or in layout, never both",
                h.line,
                h.col,
            )
        args = self.layout_args(i + 1, end, depth + 1)
        return dataclasses.replace(node, args=tuple(args)), end

    def layout_args(self, i: int, end: int, depth: int) -> list[Arg]:
        col = self.ls[i][0]
        args: list[Arg] = []
        while i < end:
            indent, label, node, head = self.ls[i]
            if indent != col:
                raise self.err(
                    f"bad indent: this argument starts at column {indent + 1}, the "
                    f"one before at column {col + 1}",
                    head.line,
                    head.col,
                )
            if label is not None and node is None:
                if i + 1 >= end or self.ls[i + 1][0] < indent or self.ls[i + 1][2] is None:
                    raise self.err(
                        f"label '{label.text} without a value; put it on the next "
                        "line, at least as deep as the label",
                        head.line,
                        head.col,
                    )
                value, i = self.value(i + 1, depth)
            else:
                value, i = self.value(i, depth)
            args.append(Arg(label.text if label else None, value, head.line, head.col))
        return args


def parse(text: str, file: str = "<text>") -> Node:
    """Parse one expression; raise :class:`ExpressionError` (path ``syntax``) if invalid."""
    return _Parser(text, file).parse()
