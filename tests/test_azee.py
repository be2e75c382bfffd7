"""The .azee front end: worked examples of the contract, lexicon, forms, errors, CLI, and
realization of compiled scores on the real signer."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import mujoco
import numpy as np
import pytest

from azee_mj import arkit
from azee_mj.azee import RULES, ExpressionError, Lexicon, compile_file, compile_text, parse
from azee_mj.azee.nonmanual import EXPRESSIONS, GESTURES
from azee_mj.check import check_poses
from azee_mj.cli import main
from azee_mj.model import load_model
from azee_mj.schedule import contact_pairs, make_solver
from azee_mj.score import load_score
from azee_mj.sites import DEFAULT_MAP, FINGERS, HANDSHAPES
from azee_mj.timeline import realize

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples"
TOL = 1e-9
PROSE = ("x-faithful", "x-guessed")


def _example(name: str) -> dict:
    return json.loads((EXAMPLES / f"{name}.json").read_text(encoding="utf-8"))


def _no_x(score: dict) -> dict:
    return {k: v for k, v in score.items() if not k.startswith("x-")}


def _tree(block: dict, prefix: str = "") -> dict[str, tuple[str, float, float]]:
    """Dotted path -> (kind, start, end) for every block."""
    path = f"{prefix}.{block['name']}" if prefix else block["name"]
    out = {path: (block["kind"], block["start"], block["end"])}
    for c in block.get("children", ()):
        out.update(_tree(c, path))
    return out


def _assert_times(score: dict, expected: dict[str, tuple[str, float, float]]) -> None:
    tree = _tree(score["root"])
    for path, (kind, s, e) in expected.items():
        assert path in tree, (path, sorted(tree))
        k, s2, e2 = tree[path]
        assert k == kind and abs(s2 - s) <= TOL and abs(e2 - e) <= TOL, (path, tree[path])


def _walk(block: dict):
    yield block
    for c in block.get("children", ()):
        yield from _walk(c)


def _block(score: dict, path: str) -> dict:
    b = score["root"]
    for name in path.split(".")[1:]:
        b = next(c for c in b["children"] if c["name"] == name)
    return b


# ---------------------------------------------------------------------------------------
# Worked examples of the contract
# ---------------------------------------------------------------------------------------


def test_worked_example_a_info_about():
    s = compile_text(":info-about(:cinema, :bien)")
    _assert_times(
        s,
        {
            "INFO_ABOUT": ("sync", 0, 2.4),
            "INFO_ABOUT.TOPIC": ("sync", 0, 0.9),
            "INFO_ABOUT.TOPIC_HOLD": ("hold", 0.9, 1.2),
            "INFO_ABOUT.BROWS": ("cstr", 0, 1.2),
            "INFO_ABOUT.INFO": ("sync", 1.2, 2.4),
            "INFO_ABOUT.BLINK": ("cstr", 2.0, 2.2),
        },
    )
    assert [c["name"] for c in s["root"]["children"]] == [
        "TOPIC",
        "TOPIC_HOLD",
        "BROWS",
        "INFO",
        "BLINK",
    ]
    assert _block(s, "INFO_ABOUT.TOPIC_HOLD")["of"] == "TOPIC"
    assert _no_x(s) == _no_x(_example("info-about"))


def test_worked_example_b_nicht_sondern():
    s = compile_text(":nicht-sondern('nicht :arbre, 'sondern :armoire)")
    n = "NICHT_SONDERN"
    expected = {
        n: ("sync", 0, 3.3),
        f"{n}.NEGATED": ("sync", 0, 2.0),
        f"{n}.NEGATED.NICHT": ("sync", 0, 1.2),
        f"{n}.NEGATED.NICHT_HOLD": ("hold", 1.2, 2.0),
        f"{n}.NEGATED.HEADSHAKE": ("sync", 1.2, 2.0),
        f"{n}.NEGATED.HEADSHAKE.GAZE": ("cstr", 0, 0.8),
        f"{n}.NEGATED.FROWN": ("cstr", 1.2, 1.85),
        f"{n}.NEGATED.FROWN_RELAX": ("cstr", 1.95, 2.0),
        f"{n}.SONDERN": ("sync", 2.0, 3.3),
    }
    for k in range(4):
        expected[f"{n}.NEGATED.HEADSHAKE.TURN_{k}"] = ("cstr", 0.2 * k, 0.2 * k + 0.08)
    _assert_times(s, expected)
    shake = _block(s, f"{n}.NEGATED.HEADSHAKE")
    assert len(shake["children"]) == 5
    lat = [c["constraints"][0]["vector"]["add"][1]["scale"] for c in shake["children"][:4]]
    assert lat == ["lat(w)", "lat(s)", "lat(w)", "lat(s)"]
    assert _no_x(s) == _no_x(_example("nicht-sondern"))
    # the alias gives the same score
    assert compile_text(":not-but(:arbre, :armoire)")["root"] == s["root"]


def test_worked_example_c_side_by_side():
    s = compile_text(":side-by-side('left :cinema, 'right :arbre)")
    r = "SIDE_BY_SIDE"
    _assert_times(
        s,
        {
            r: ("sync", 0, 2.85),
            f"{r}.LEFT": ("sync", 0, 0.9),
            f"{r}.LEFT.SIG": ("sync", 0, 0.9),
            f"{r}.LEFT.GAZE": ("cstr", 0, 0.9),
            f"{r}.RIGHT": ("sync", 0.9, 2.85),
            f"{r}.RIGHT.SIG": ("sync", 0, 1.2),
            f"{r}.RIGHT.POINT": ("sync", 1.2, 1.95),
        },
    )
    assert _block(s, f"{r}.LEFT.GAZE")["constraints"] == [{"type": "look", "at": "^Lssp"}]
    screen = _block(s, f"{r}.LEFT.SIG.SCREEN")["constraints"][0]
    assert screen["at"]["translate"] == "^Lssp"
    assert (
        compile_text(":ix('loc ^Rssp)")["root"]["children"]
        == _block(s, f"{r}.RIGHT.POINT")["children"]
    )


def test_worked_example_about_ref():
    s = compile_text(":about-ref('sig :arbre, 'pt ^Rssp)")
    side = compile_text(":side-by-side('left :cinema, 'right :arbre)")
    _assert_times(
        s,
        {
            "ABOUT_REF": ("sync", 0, 1.95),
            "ABOUT_REF.REF": ("sync", 0, 1.95),
            "ABOUT_REF.LEAN": ("cstr", 0, 1.95),
        },
    )
    assert _block(s, "ABOUT_REF.REF")["children"] == _block(side, "SIDE_BY_SIDE.RIGHT")["children"]
    assert _block(s, "ABOUT_REF.LEAN")["constraints"] == [
        {
            "type": "orient",
            "bone": "!back_2",
            "axis": "dir",
            "rel": "along",
            "vector": {"add": ["up", {"scale": "right", "by": 0.15}]},
        }
    ]


@pytest.mark.parametrize("name", ["info-about", "nicht-sondern"])
def test_generated_examples_equal_their_expressions(name):
    compiled = compile_file(EXAMPLES / f"{name}.azee")
    committed = _example(name)
    assert {k: v for k, v in committed.items() if k not in PROSE} == compiled
    assert list(committed) == ["format", "version", "strong_side", "x-source", *PROSE, "root"]


# ---------------------------------------------------------------------------------------
# Lexicon
# ---------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "name, side", [("arbre", "R"), ("armoire", "R"), ("bien", "R"), ("penser", "L")]
)
def test_a_bundled_sign_alone_equals_its_example(name, side):
    assert _no_x(compile_text(f":{name}", strong_side=side)) == _no_x(_example(name))


def test_cinema_is_the_topic_of_info_about_and_ix_points_like_pointing():
    topic = _block(_example("info-about"), "INFO_ABOUT.TOPIC")
    assert compile_text(":cinema")["root"] == {**topic, "name": "CINEMA"}
    ix = compile_text(":ix('loc ^Rssp)")["root"]
    point = next(c for c in _example("pointing")["root"]["children"] if c["name"] == "IX_R")
    assert ix["end"] == point["end"] == 0.75
    place, aim, palm, look = ix["children"][1]["constraints"]
    # as IX_R: the index along the line from the sternum to the locus, the gaze at it
    assert [aim, look] == [point["constraints"][1], point["constraints"][3]]
    # but the fingertip 0.1 m past the locus on that line (half way from the chest, the
    # strong hand cannot point at its own side) and the palm as near down as the index allows
    assert place["at"] == {
        "translate": "^Rssp",
        "by": {"scale": {"unit": aim["vector"]}, "by": 0.1},
    }
    assert palm["vector"] == {"cross": [aim["vector"], {"cross": ["down", aim["vector"]]}]}
    assert ix["children"][0]["start"] == ix["children"][1]["start"] == 0.35


def test_digits_are_signs_with_a_locus():
    lex = Lexicon()
    for n in range(10):
        sign = lex.get(f"nb-{n}")
        assert sign.duration == pytest.approx(0.7)
        assert [(p.name, p.kind, p.default) for p in sign.params] == [("loc", "locus", "^ssp")]
    s = compile_text(":nb-7('loc ^Rssp)")
    shapes = [c["id"] for c in s["root"]["children"][0]["constraints"]]
    assert shapes == ["hs_5", "hs_v"]


def test_user_lexicon_adds_and_overrides_signs(tmp_path):
    wave = _example("bien")
    wave["x-params"] = {"h": {"kind": "num", "default": 0.05}}
    k2 = next(c for c in wave["root"]["children"] if c["name"] == "K2")
    k2["constraints"][0]["at"]["by"]["by"] = "$h"
    (tmp_path / "wave.json").write_text(json.dumps(wave))
    (tmp_path / "twice.azee").write_text(":seq(:wave('h 0.1), :wave)\n")
    s = compile_text(":twice", lexicon=[tmp_path])
    assert s["root"]["name"] == "TWICE" and s["root"]["end"] == pytest.approx(2.4)
    by = [_block(s, f"TWICE.ITEM_{k}.K2")["constraints"][0]["at"]["by"]["by"] for k in (0, 1)]
    assert by == [0.1, 0.05]
    load_score(s)


# ---------------------------------------------------------------------------------------
# Forms
# ---------------------------------------------------------------------------------------

LAYOUT = """\
# the cinema was good
:info-about
  'topic
    :cinema      # a label on its own line takes the next line
  'info :bien
"""
SAME_DEPTH = """\
:info-about
  'topic
  :cinema
  'info
  :bien
"""
NESTED = """\
:info-about
  'topic :cinema
  'info
    :nicht-sondern
      :bien
      :penser
      'neghold 0.4
"""


@pytest.mark.parametrize(
    "text",
    [
        ":info-about(:cinema, :bien)",
        ":info-about('topic :cinema, 'info :bien)",
        ":info-about(:cinema, 'info :bien)",
        LAYOUT,
        SAME_DEPTH,
        ":info-about\n  :cinema\n  :bien\n",
        ":info-about(\n  :cinema,\n    :bien)\n",
    ],
)
def test_layout_and_inline_forms_agree(text):
    s = compile_text(text)
    assert s == compile_text(":info-about(:cinema, :bien)")
    assert s["x-source"] == ":info-about('topic :cinema, 'info :bien)"


def test_x_source_round_trips():
    s = compile_text(NESTED)
    src = s["x-source"]
    assert src == (
        ":info-about('topic :cinema, 'info :nicht-sondern('nicht :bien, "
        "'sondern :penser, 'neghold 0.4))"
    )
    assert compile_text(src) == s
    inline = compile_text(":tens-units(.nb-5, .nb-2, 'gap 0.2)")
    assert inline["x-source"] == ":tens-units('tens .nb-5, 'units .nb-2, 'gap 0.2)"
    assert compile_text(inline["x-source"]) == inline


def test_compile_score_gives_a_score_record():
    from azee_mj.azee import compile_score

    score = compile_score(":tens-units(.nb-5, .nb-2)", strong_side="L")
    assert score.strong_side == "L" and score.duration == pytest.approx(1.55)
    assert score.block("TENS_UNITS.U.HAND").start == pytest.approx(1.15)


def test_unicode_names_parse():
    node = parse(":été('lieu ^ssp)")
    assert node.name == "été" and node.args[0].label == "lieu"


# ---------------------------------------------------------------------------------------
# Every rule and sign gives a score the loader accepts; every composition realizes
# ---------------------------------------------------------------------------------------

EVERY_RULE = [
    ":seq(:bien, :penser, 'gap 0.1)",
    ":info-about(:cinema, :bien, 'hold 0)",
    ":side-info(:bien, :arbre)",
    ":about-ref(:bien, ^Lssp)",
    ":about-ref(:penser, ^ssp)",
    ":instance-of(:armoire, :bien)",
    ":in-context(:arbre, :bien)",
    ":each-of(:nb-1, :nb-2, :nb-3)",
    ":side-by-side(:cinema, :arbre)",
    ":nicht-sondern(:bien, :penser, 'neghold 0.1)",
    ":tens-units(.nb-5, .nb-2)",
    ":decidedly(:armoire)",
    ":info-about(:cinema, :info-about(:bien, :penser))",
]


@pytest.mark.parametrize("text", EVERY_RULE)
def test_every_rule_gives_a_valid_score(text):
    s = compile_text(text)
    load_score(s)
    assert s["root"]["start"] == 0
    load_score(compile_text(text, strong_side="L"))


def test_every_rule_is_exercised_and_documented():
    used = {t.split("(")[0][1:] for t in [*EVERY_RULE, *NONMANUAL]}
    for r in RULES:
        assert r.source and r.summary and r.approximated
        assert r.name in used or not r.implemented
    assert (
        compile_text(":info-about(:cinema, :info-about(:bien, :penser))")["root"]["children"][-1][
            "name"
        ]
        == "INFO"
    )  # no blink when the info is an info-about


#: One application of every non-manual rule (their ARKit morphs are the face rig's).
NONMANUAL = [
    ":yes-no-question(:bien)",
    ":wh-question(:penser)",
    ":boundary(:arbre, 'pause 0.3)",
    *(f':mouth-gesture(:arbre, "{g}")' for g in GESTURES),
    ':mouthing(:arbre, "arbre", \'lang "fr")',
    *(f":{name}(:bien)" for name in EXPRESSIONS),
]


@pytest.mark.parametrize("text", NONMANUAL)
def test_nonmanual_rules_give_arkit_morphs_in_range(text):
    if "mouthing" in text:
        pytest.importorskip("phonemizer", reason="mouthing needs the [mouthing] extra")
    s = compile_text(text)
    face = [c for c in s["root"]["children"] if c["name"] != "SIG"]
    cons = [
        c for f in face for b in _walk(f) for c in b.get("constraints", ()) if c["type"] == "morph"
    ]
    assert cons
    for c in cons:
        assert c["id"] in arkit.ARKIT_SHAPES or c["id"] in arkit.PAIRS, c
        assert c["id"] in DEFAULT_MAP.morphs, c
        assert 0.0 <= c["weight"] <= 1.0
    assert s["root"]["end"] == pytest.approx(
        _block(s, f"{s['root']['name']}.SIG")["end"] + (0.3 if "boundary" in text else 0.0)
    )


@pytest.mark.parametrize("text", NONMANUAL)
def test_nonmanual_rules_load(text):
    if "mouthing" in text:
        pytest.importorskip("phonemizer", reason="mouthing needs the [mouthing] extra")
    load_score(compile_text(text))
    load_score(compile_text(text, strong_side="L"))


@pytest.mark.parametrize(
    "text",
    [
        *NONMANUAL[:3],
        ':mouth-gesture(:bien, "pah")',
        ':mouth-gesture(:armoire, "puff")',
        ':mouthing(:arbre, "arbre", \'lang "fr")',
        ":with-surprise(:cinema)",
        ":too-scared-to-look(:penser)",
        ":info-about(:cinema, :yes-no-question(:bien))",
    ],
)
def test_nonmanual_rules_realize_within_tolerance(text):
    if "mouthing" in text:
        pytest.importorskip("phonemizer", reason="mouthing needs the [mouthing] extra")
    r = realize(compile_text(text), fps=25.0, solver=make_solver())
    assert all(t.ok for t in r.traces), [t.describe() for t in r.traces if not t.ok]


@pytest.mark.parametrize("name", Lexicon().names())
def test_every_sign_gives_a_valid_score(name):
    load_score(compile_text(f":{name}"))


def _bench_expression() -> str:
    """The composed expression of ``bench/azee_text.py`` (10 rules, 15.3 s)."""
    text = (ROOT / "bench" / "azee_text.py").read_text(encoding="utf-8")
    return text.split('EXPRESSION = """\\\n', 1)[1].split('"""', 1)[0]


#: Every composition of the contract's worked examples and of docs/azee-text.md, every
#: rule of EVERY_RULE, the benchmark's expression and each of its items.
REALIZED = list(
    dict.fromkeys(
        [
            ":info-about(:cinema, :bien)",
            ":nicht-sondern(:arbre, :armoire)",
            ":side-by-side('left :cinema, 'right :arbre)",
            ":about-ref('sig :arbre, 'pt ^Rssp)",
            ":seq(:bien, :ix('loc ^Rssp))",
            ":instance-of(:armoire, :bien)",
            ":info-about(:cinema, :tens-units(.nb-5, .nb-2))",
            ":nicht-sondern(:bien, :penser)",
            ":about-ref(:cinema, ^Rssp)",
            ":tens-units(.nb-0, .nb-9)",
            ":side-by-side('left :cinema, 'right :bien)",
            ":side-by-side('left :nb-5, 'right :nb-2)",
            ":ix('loc ^Lssp)",
            *EVERY_RULE,
            ":info-about(:arbre, :tens-units(.nb-5, .nb-2))",
            ":in-context(:cinema, :decidedly(:penser))",
            ":nicht-sondern(:bien, :each-of(:nb-1, :nb-2))",
            ":instance-of(:armoire, :side-info(:bien, :arbre))",
            ":tens-units(.nb-3, .nb-4)",
            _bench_expression(),
        ]
    )
)


@pytest.mark.parametrize("text", REALIZED)
def test_compiled_scores_realize_within_tolerance(text, model):
    s = compile_text(text)
    r = realize(s, fps=25.0, solver=make_solver())
    bad = [
        f"{t.block}#{t.index} {t.kind} {t.worst:.4g} > {t.tol:.4g}" for t in r.traces if not t.ok
    ]
    assert not bad, bad
    report = check_poses(model, r.qpos, allowed=contact_pairs(s, r.time, score_start=r.score_start))
    assert not report.penetrations, report.penetrations[:3]


@pytest.mark.parametrize("side", ["R", "L"])
@pytest.mark.parametrize(
    "text",
    [
        ":info-about(:cinema, :bien, 'hold 0)",
        ":side-by-side('left :cinema, 'right :bien)",
        ":side-by-side('left :nb-5, 'right :nb-2)",
    ],
)
def test_a_hand_shape_or_gaze_change_with_no_gap_stays_under_25_rad_per_s(text, side, model):
    """An open hand held to the end of a sign, then a fist or a V at once (and a gaze from
    one locus to the other): the blend between them is followed, no joint snaps."""
    r = realize(compile_text(text, strong_side=side), fps=50.0, solver=make_solver())
    hinge = model.jnt_qposadr[model.jnt_type == mujoco.mjtJoint.mjJNT_HINGE]
    assert np.abs(np.diff(r.qpos[:, hinge], axis=0)).max() * r.fps < 25.0
    assert all(t.ok for t in r.traces), [t.describe() for t in r.traces if not t.ok]


# ---------------------------------------------------------------------------------------
# Errors: one message, exit 2, no output file
# ---------------------------------------------------------------------------------------

ERRORS = [
    (
        ":info-about(:cinema, :bein)",
        (
            "<-e>:1:22: :info-about'info:bein: unknown rule or sign "
            "':bein'; did you mean ':bien'? (azee-mj rules lists all)"
        ),
    ),
    (
        ":info-about('topic :cinema, 'inf :bien)",
        (
            "<-e>:1:29: :info-about: unknown argument "
            "'inf for :info-about; did you mean 'info? It takes 'topic score, 'info score, "
            "'hold num=0.3"
        ),
    ),
    (
        ":info-about('topic :cinema, 'topic :bien)",
        (
            "<-e>:1:29: :info-about: repeated argument "
            "'topic for :info-about; it takes 'topic score, 'info score, 'hold num=0.3"
        ),
    ),
    (
        ":info-about(:cinema)",
        (
            "<-e>:1:1: :info-about: missing argument 'info for :info-about; "
            "it takes 'topic score, 'info score, 'hold num=0.3"
        ),
    ),
    (
        ":info-about(:cinema, :bien, 3, 4)",
        (
            "<-e>:1:32: :info-about: too many arguments for "
            ":info-about (4 given); it takes 'topic score, 'info score, 'hold num=0.3"
        ),
    ),
    (
        ":info-about('topic :cinema, :bien)",
        (
            "<-e>:1:29: :info-about: a positional argument "
            "after a labelled one; positional arguments come first, in parameter order"
        ),
    ),
    (
        ":about-ref('sig :arbre, 'pt :arbre)",
        ("<-e>:1:29: :about-ref: 'pt: expected a locus (^ssp, ^Rssp, ^Lssp), got score :arbre"),
    ),
    (
        ":about-ref(:arbre, ^Xssp)",
        (
            "<-e>:1:20: :about-ref'pt: unknown locus '^Xssp'; did you "
            "mean '^ssp'? Valid loci are ^ssp, ^Rssp, ^Lssp"
        ),
    ),
    (
        ":info-about(:cinema, :tens-units('tens :bien, 'units .nb-2))",
        (
            "<-e>:1:40: "
            ":info-about'info:tens-units: 'tens: expected a digit (.nb-0 to .nb-9), got score :bien"
        ),
    ),
    (
        ":tens-units(.nb-5, .nb-12)",
        ("<-e>:1:20: :tens-units'units: unknown atom '.nb-12'; atoms are .nb-0 to .nb-9"),
    ),
    (
        ":nicht-sondern(:arbre, :bien, 'neghold 0)",
        ("<-e>:1:40: :nicht-sondern: 'neghold: expected a number > 0, got 0"),
    ),
    (":seq(:bien, 'gap -1)", "<-e>:1:18: :seq: 'gap: expected a number >= 0, got -1"),
    (
        ":each-of(:bien)",
        ("<-e>:1:10: :each-of: 'item: expected at least 2 items, got 1; it takes 'item score 2+"),
    ),
    (":bien('loc 3)", ("<-e>:1:12: :bien: 'loc: expected a locus (^ssp, ^Rssp, ^Lssp), got num 3")),
    (
        ":fingerspelling(:arbre)",
        (
            "<-e>:1:1: :fingerspelling: not implemented: azee_mj has no "
            "manual alphabet; write the word with signs of the lexicon"
        ),
    ),
    (
        ":azop(:arbre)",
        (
            "<-e>:1:1: :azop: low-level operators (:azop) are not supported; write "
            "a rule or a sign (azee-mj rules lists all)"
        ),
    ),
    (
        "^ssp",
        (
            "<-e>:1:1: ^ssp: the expression is a locus, not a score; a file holds one :rule "
            "or :sign application"
        ),
    ),
    ("?x", "<-e>:1:1: syntax: templates (?x) are not supported; write the value"),
    ("\t:bien", "<-e>:1:1: syntax: tab character; indent and separate with spaces"),
    (":seq(:bien,", "<-e>:1:5: syntax: unbalanced parentheses: '(' is never closed"),
    (":bien)", "<-e>:1:6: syntax: unbalanced parentheses: ')' without '('"),
    (
        ":bien :arbre",
        (
            "<-e>:1:7: syntax: a second expression on one line; put each argument "
            "on its own line or inside parentheses"
        ),
    ),
    (
        ":bien\n:arbre",
        (
            "<-e>:2:1: syntax: a second expression; a file holds one expression "
            "(arguments are indented deeper than their application)"
        ),
    ),
    (
        ":info-about\n  'topic\n",
        (
            "<-e>:2:3: syntax: label 'topic without a value; put it on "
            "the next line, at least as deep as the label"
        ),
    ),
    (
        ":info-about\n  'topic :cinema\n 'info :bien",
        (
            "<-e>:3:2: syntax: bad indent: this "
            "argument starts at column 2, the one before at column 3"
        ),
    ),
    (
        ":seq(:bien)\n  :arbre",
        ("<-e>:2:3: syntax: arguments of :seq go in parentheses or in layout, never both"),
    ),
    (
        "^ssp\n  :arbre",
        ("<-e>:2:3: syntax: a locus takes no arguments; this line is indented deeper than it"),
    ),
    ("", "<-e>:1:1: syntax: no expression; a file holds one expression"),
    (":seq(:bien, )", "<-e>:1:13: syntax: expected an expression, got ')'"),
    (":seq(:bien :arbre)", "<-e>:1:12: syntax: expected ',' or ')', got an application"),
    (":seq('item)", "<-e>:1:6: syntax: label 'item without a value"),
    (
        ":seq(:bien, $x)",
        (
            "<-e>:1:13: syntax: unexpected character '$'; an expression starts "
            'with :name, ^locus, .atom, \'label, a number or a "text"'
        ),
    ),
]


@pytest.mark.parametrize("text, message", ERRORS)
def test_error_exits_2_with_its_message_and_no_output(text, message, tmp_path, capsys):
    out = tmp_path / "out.json"
    assert main(["compile", "-e", text, "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err == f"azee-mj: error: {message}\n"
    assert len(message.splitlines()) <= 4
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_error_records_where(tmp_path):
    with pytest.raises(ExpressionError) as e:
        compile_text(":info-about\n  'topic :cinema\n  'info :tens-units(.nb-5, :bien)")
    assert (e.value.line, e.value.col, e.value.path) == (3, 28, ":info-about'info:tens-units")
    assert e.value.file == "<text>"


def test_person_aged_52_parses_then_fails_on_personne(tmp_path):
    text = (
        "# 'person aged 52' (Sharma's thesis)\n:info-about\n  'topic\n    :personne\n"
        "  'info\n    :tens-units\n      'tens .nb-5\n      'units .nb-2\n"
    )
    path = tmp_path / "age.azee"
    path.write_text(text)
    assert parse(text).name == "info-about"
    with pytest.raises(ExpressionError) as e:
        compile_file(path)
    assert str(e.value) == (
        f"{path}:4:5: :info-about'topic:personne: unknown rule or sign "
        "':personne' (azee-mj rules lists all)"
    )


def test_lexicon_errors(tmp_path):
    (tmp_path / "a.azee").write_text(":seq(:bien, :b)")
    (tmp_path / "b.azee").write_text(":info-about(:cinema, :a)")
    with pytest.raises(ExpressionError) as e:
        compile_text(":a", lexicon=[tmp_path])
    assert str(e.value).endswith(":info-about'info:a: lexicon cycle :a -> :b -> :a")
    bad = _example("bien")
    bad["root"]["children"][1]["constraints"][0]["site"] = "@T_TPI(s)"
    (tmp_path / "bad.json").write_text(json.dumps(bad))
    with pytest.raises(ExpressionError) as e:
        compile_text(":bad", lexicon=[tmp_path])
    assert str(e.value) == (
        "<text>:1:1: :bad: lexicon :bad: BAD.K1: constraint 1 (place): "
        "unknown site '@T_TPI(s)'; did you mean '@T_TIP(s)'? (azee-mj "
        "sites lists all)"
    )
    (tmp_path / "seq.json").write_text(json.dumps(_example("bien")))
    with pytest.raises(ExpressionError) as e:
        Lexicon([tmp_path])
    assert str(e.value) == (
        f"{tmp_path / 'seq.json'}: a sign may not be named like the rule :seq; rename the file"
    )


def test_file_errors(tmp_path, capsys):
    missing = tmp_path / "nope.azee"
    assert main(["compile", str(missing)]) == 2
    assert capsys.readouterr().err == (
        f"azee-mj: error: {missing}: cannot read the expression: No such file or directory\n"
    )
    assert main(["compile", "-e", ":bien", "--lexicon", str(missing)]) == 2
    assert capsys.readouterr().err == (
        f"azee-mj: error: {missing}: not a directory of signs (--lexicon)\n"
    )
    assert main(["compile"]) == 2
    assert (
        capsys.readouterr().err == "azee-mj: error: compile: give one EXPR.azee file or -e TEXT\n"
    )


def test_deep_nesting_is_an_error():
    text = ":decidedly(" * 70 + ":bien" + ")" * 70
    with pytest.raises(ExpressionError) as e:
        compile_text(text)
    assert e.value.problem == "nesting deeper than 64 levels"


# ---------------------------------------------------------------------------------------
# CLI
# ---------------------------------------------------------------------------------------


def test_cli_compile_file_and_stdout(tmp_path, capsys):
    out = tmp_path / "s.json"
    assert main(["compile", str(EXAMPLES / "info-about.azee"), "-o", str(out)]) == 0
    assert json.loads(out.read_text()) == compile_file(EXAMPLES / "info-about.azee")
    capsys.readouterr()
    assert main(["compile", "-e", ":penser", "--strong-side", "L"]) == 0
    assert _no_x(json.loads(capsys.readouterr().out)) == _no_x(_example("penser"))


def test_cli_rules_json(capsys):
    assert main(["rules", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    names = [r["name"] for r in out["rules"]]
    assert names[:2] == ["seq", "info-about"] and "fingerspelling" in names
    ns = next(r for r in out["rules"] if r["name"] == "nicht-sondern")
    assert ns["aliases"] == ["not-but"]
    assert ns["args"][2] == {"name": "neghold", "kind": "num", "default": 0.8, "list": False}
    assert {"name", "aliases", "args", "summary", "source"} <= set(ns)
    signs = {s["name"]: s for s in out["signs"]}
    assert {"arbre", "armoire", "bien", "penser", "cinema", "ix"} <= set(signs)
    assert {f"nb-{n}" for n in range(10)} <= set(signs)
    assert signs["ix"]["params"] == [
        {"name": "loc", "kind": "locus", "default": "^ssp", "list": False}
    ]
    assert main(["rules"]) == 0
    assert ":nicht-sondern('nicht score, 'sondern score, 'neghold num=0.8) (alias :not-but)" in (
        capsys.readouterr().out
    )


def test_cli_realize_and_check_take_azee(tmp_path, capsys):
    src = tmp_path / "num.azee"
    src.write_text(":tens-units(.nb-5, .nb-2)\n")
    out = tmp_path / "num.npz"
    assert main(["realize", str(src), "-o", str(out), "--fps", "25"]) == 0
    assert "6/6 constraints within tolerance" in capsys.readouterr().out
    assert main(["check", str(out), "--score", str(src)]) == 0
    bad = tmp_path / "bad.azee"
    bad.write_text(":tens-units(.nb-5, :bien)\n")
    assert main(["realize", str(bad), "-o", str(tmp_path / "bad.npz")]) == 2
    assert capsys.readouterr().err.startswith(f"azee-mj: error: {bad}:1:20: :tens-units: ")
    assert not (tmp_path / "bad.npz").exists()


def test_cli_user_lexicon(tmp_path, capsys):
    lex = tmp_path / "signs"
    lex.mkdir()
    (lex / "hello.azee").write_text(":seq(:bien, :nb-5)\n")
    assert main(["compile", "-e", ":hello", "--lexicon", str(lex)]) == 0
    assert json.loads(capsys.readouterr().out)["root"]["name"] == "HELLO"
    assert main(["rules", "--lexicon", str(lex)]) == 0
    assert ":hello expression" in capsys.readouterr().out


# ---------------------------------------------------------------------------------------
# Named handshapes
# ---------------------------------------------------------------------------------------

HAND_JOINTS = 4 + 4 * len(FINGERS)


def test_handshapes_are_catalogue_morphs(capsys):
    assert len(HANDSHAPES) >= 20
    assert main(["sites", "--json"]) == 0
    morphs = json.loads(capsys.readouterr().out)["morphs"]
    assert {f"hs_{n}" for n in HANDSHAPES} <= set(morphs)
    for n in (
        "flat",
        "bent",
        "a",
        "s",
        "index",
        "v",
        "w",
        "4",
        "5",
        "claw",
        "l",
        "y",
        "c",
        "o",
        "f",
        "pinch",
        "thumb",
        "i",
        "horns",
        "flat_o",
    ):
        assert n in HANDSHAPES


@pytest.mark.parametrize("side", ["R", "L"])
def test_handshapes_are_free_of_self_penetration(model, side):
    """Each handshape on a hand held in front of the body (forearm raised), checked on the
    real model's collision geometry, inside every joint range."""
    d = mujoco.MjData(model)
    base = model.qpos0.copy()
    for j, v in ((f"arm_{side}_flex", 0.5), (f"f_arm_{side}_flex", 1.6)):
        base[model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j)]] = v
    for name in HANDSHAPES:
        changes = DEFAULT_MAP.morphs[f"hs_{name}"].joint_changes(side)
        assert len(changes) == HAND_JOINTS
        q = base.copy()
        for j, v in changes.items():
            q[model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j)]] += v
        report = check_poses(model, q)
        assert report.clean, (name, report.penetrations, report.range_violations)
        d.qpos[:] = q
    assert np.isfinite(d.qpos).all()


def test_a_handshape_and_another_morph_add():
    s = copy.deepcopy(_example("bien"))
    s["root"]["children"][0]["constraints"] = [
        {"type": "morph", "id": "hs_flat", "weight": 1.0, "side": "s"},
        {"type": "morph", "id": "index_bend", "weight": 0.5, "side": "s"},
    ]
    r = realize(s, fps=10.0)
    model = load_model()
    q = r.qpos[round((r.score_start + 1.1) * r.fps)][  # in the score, before the rest
        model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "index_R_1_flex")]
    ]
    assert q == pytest.approx(0.5 * 1.45, abs=0.02)


@pytest.mark.extra("plot", "render")
def test_cli_render_and_report_take_azee(tmp_path, capsys):
    from azee_mj import render
    from azee_mj.errors import AzeeError

    src = tmp_path / "five.azee"
    src.write_text(":nb-5\n")
    rep = tmp_path / "five.html"
    assert main(["report", str(src), "-o", str(rep), "--fps", "10"]) == 0
    assert "NB_5.HAND" in rep.read_text()
    try:
        render.gl_backend()
    except AzeeError as e:
        pytest.skip(f"no OpenGL backend, nothing can be rendered: {e}")
    png = tmp_path / "five.png"
    assert (
        main(
            [
                "render",
                str(src),
                "-o",
                str(png),
                "--time",
                "0.5",
                "--size",
                "160x120",
                "--fps",
                "10",
            ]
        )
        == 0
    )
    assert png.stat().st_size > 0


def test_the_front_end_imports_nothing_from_solving():
    import subprocess
    import sys

    code = (
        "import sys, azee_mj.azee; azee_mj.azee.compile_text(':bien'); "
        "print(' '.join(sorted(m for m in sys.modules if m.startswith('azee_mj'))))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT
    ).stdout.split()
    solving_and_after = {
        "azee_mj.kinematics",
        "azee_mj.constraints",
        "azee_mj.ik",
        "azee_mj.schedule",
        "azee_mj.motion",
        "azee_mj.timeline",
        "azee_mj.rollout_io",
        "azee_mj.markers",
        "azee_mj.render",
        "azee_mj.viewer",
        "azee_mj.check",
        "azee_mj.report",
        "azee_mj.cli",
    }
    assert not solving_and_after & set(out), out
