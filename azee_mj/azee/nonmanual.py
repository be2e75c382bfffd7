"""Non-manual rules: questions, a blink at a boundary, mouth gestures, mouthing and the
facial expressions of the *40 brèves* corpus, each as ARKit blend shapes over a sign.

Every rule here takes a score ``'sig`` and lays face blocks over it: the shapes come on with
the sign, hold, and go back to rest by its end (a ``RELAX`` key with every shape the rule
used at weight 0 over the sign's last :data:`RELAX_S` seconds; the face blends to it in the
:data:`RELEASE_S` before). Weights are ARKit weights in [0, 1] (:mod:`azee_mj.arkit`); a
Left/Right pair with equal weights is written as its base name (both sides).

Sources: [BSC80] Baker-Shenk & Cokely 1980, *American Sign Language: a teacher's resource
text on grammar and culture*; [L80] Liddell 1980, *American Sign Language Syntax*; [W94]
Wilbur 1994, "Eyeblinks and ASL phrase structure", *Sign Language Studies* 84; [W01] Woll
2001, "The sign that dares to speak its name: echo phonology in BSL"; [C08] Crasborn et al.
2008, "Frequency distribution and spreading behavior of different types of mouth actions in
three sign languages", *Sign Language & Linguistics* 11; [T6] Sharma's PhD thesis (2024),
ch. 6 "Facial Expressions": its 22 synthesized rules of the *40 brèves* corpus, shown as
corpus stills (table "Synthesized Expressions") with the linguist's notes (table
"Limitations for the synthesized blendshapes") and, for ``big-threatening``, the action
units (figure "Manual adjustment"). The thesis gives no weights: the ARKit weights below are
ours, read from those stills and notes.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

from azee_mj import arkit, mouthing
from azee_mj.azee.catalogue import Param, ScoreVal, Timeline, along, head_along

#: The last seconds of a sign during which the face is back at rest [s].
RELAX_S = 0.05
#: The blend from the expression to rest, before :data:`RELAX_S` [s].
RELEASE_S = 0.1


class RuleProblem(Exception):
    """A bad argument value found while building a rule: ``label`` is the argument,
    ``problem`` the message (the evaluator adds where)."""

    def __init__(self, label: str, problem: str):
        super().__init__(problem)
        self.label = label
        self.problem = problem


def _both(**w: float) -> dict[str, float]:
    """``mouthPress=0.5`` -> ``{"mouthPressLeft": 0.5, "mouthPressRight": 0.5}``; an
    unpaired name (``jawOpen``) is kept as it is."""
    out = {}
    for name, v in w.items():
        if name in arkit.PAIRS:
            out.update({name + suffix: v for suffix in arkit.SIDE_SUFFIX.values()})
        else:
            out[name] = v
    return out


def face_blocks(
    tl: Timeline, name: str, start: float, end: float, weights: Mapping[str, float]
) -> None:
    """``name`` over [start, end - release] with ``weights`` and ``name``_RELAX (the same
    shapes at 0) over the last :data:`RELAX_S` seconds; the whole span when it is too short
    to release (then the shapes hold and a later block or rule returns them)."""
    if end - start > 2 * (RELAX_S + RELEASE_S):
        tl.cstr(name, start, end - RELAX_S - RELEASE_S, arkit.constraints(weights))
        tl.cstr(f"{name}_RELAX", end - RELAX_S, end, arkit.constraints(dict.fromkeys(weights, 0.0)))
    else:
        tl.cstr(name, start, end, arkit.constraints(weights))


# -- questions and boundaries -------------------------------------------------------------

#: Yes/no question: brows raised, eyes widened [BSC80]; weights guessed.
YES_NO_FACE = _both(browOuterUp=0.7, eyeWide=0.3) | {"browInnerUp": 0.8}
#: Wh-question: brows lowered and drawn together, eyes narrowed [BSC80]; weights guessed.
WH_FACE = _both(browDown=0.7, eyeSquint=0.3)
#: The head's forward tilt of a yes/no question (chin toward the addressee) and of a
#: wh-question: head fwd + k down.
YES_NO_TILT, WH_TILT = 0.15, 0.1


def _face_rule(face: Mapping[str, float], tilt: tuple[str, float] | None, origin: str):
    """A rule laying ``face`` over its sign (:func:`face_blocks`) and, with a ``tilt``
    ``(axis, k)``, the head toward fwd + k axis: the questions and the corpus expressions."""

    def build(ctx, a: dict, head: str) -> ScoreVal:
        tl = Timeline()
        s, e = tl.put("SIG", a["sig"])
        face_blocks(tl, "FACE", s, e, face)
        if tilt is not None:
            tl.cstr("HEAD", s, e, [head_along(along("fwd", tilt))])
        return tl.value(head, origin)

    return build


def _boundary(ctx, a: dict, head: str) -> ScoreVal:
    tl = Timeline()
    _, e = tl.put("SIG", a["sig"])
    tl.hold("SIG", a["pause"])
    tl.cstr("BLINK", e, e + BLINK_S, arkit.constraints(_both(eyeBlink=1.0)))
    tl.cstr("BLINK_OPEN", e + BLINK_S + 0.1, e + a["pause"], arkit.constraints(_both(eyeBlink=0.0)))
    return tl.value(head, "boundary")


#: The closed eyes of a boundary blink [s] (a blink takes 0.1 to 0.4 s; guessed).
BLINK_S = 0.08


# -- mouth gestures -----------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Gesture:
    """A mouth gesture: ``phases`` of (start, end) as fractions of the gesture's span and
    the ARKit weights held over each; ``what`` it looks like and ``source``."""

    phases: tuple[tuple[float, float, Mapping[str, float]], ...]
    what: str
    source: str


_G = "weights guessed"
#: Named mouth gestures (weights guessed; the shape's meaning from the source named).
GESTURES: dict[str, Gesture] = {
    "mm": Gesture(
        ((0, 1, _both(mouthPress=0.3) | {"mouthPucker": 0.2, "mouthShrugLower": 0.3}),),
        "lips pressed together and pushed out ('normally, with ease')",
        f"ASL [L80; BSC80]; {_G}",
    ),
    "th": Gesture(
        ((0, 1, _both(mouthLowerDown=0.15) | {"tongueOut": 0.4, "jawOpen": 0.12}),),
        "tongue tip between slightly parted lips ('carelessly')",
        f"ASL [L80; BSC80]; {_G}",
    ),
    "cha": Gesture(
        (
            (0, 0.45, _both(mouthPress=0.3) | {"mouthFunnel": 0.3}),
            (0.55, 1, _both(mouthLowerDown=0.3) | {"jawOpen": 0.6}),
        ),
        "tense closed lips that drop open ('large')",
        f"ASL [BSC80]; {_G}",
    ),
    "pah": Gesture(
        (
            (0, 0.55, _both(mouthPress=0.6) | {"cheekPuff": 0.2}),
            (0.65, 1, {"jawOpen": 0.4, "mouthFunnel": 0.2}),
        ),
        "closed lips that pop open ('at last', 'success')",
        f"BSL echo phonology [W01]; {_G}",
    ),
    "puff": Gesture(
        ((0, 1, _both(mouthPress=0.2) | {"cheekPuff": 1.0, "mouthClose": 0.2}),),
        "puffed cheeks ('big', 'a lot')",
        f"[C08]; {_G}",
    ),
    "suck": Gesture(
        ((0, 1, {"mouthPucker": 0.5, "mouthFunnel": 0.3, "jawOpen": 0.1}),),
        "sucked-in cheeks ('thin'): ARKit has no cheek suck, so pursed, funnelled lips",
        f"[C08]; {_G}",
    ),
    "pursed": Gesture(
        ((0, 1, {"mouthPucker": 0.8}),),
        "pursed lips ('small', 'precise')",
        f"[C08]; {_G}",
    ),
    "o": Gesture(
        ((0, 1, {"mouthFunnel": 0.7, "jawOpen": 0.3}),),
        "rounded open lips, an 'o' (surprise, 'wow')",
        f"[C08]; {_G}",
    ),
    "teeth": Gesture(
        ((0, 1, _both(mouthUpperUp=0.6, mouthLowerDown=0.5, mouthStretch=0.4)),),
        "bared clenched teeth ('tense', 'close call')",
        f"[C08]; {_G}",
    ),
    "tongue": Gesture(
        ((0, 1, {"tongueOut": 0.9, "jawOpen": 0.3}),),
        "tongue out",
        f"[C08]; {_G}",
    ),
    "sh": Gesture(
        ((0, 1, {"mouthFunnel": 0.6, "mouthPucker": 0.2, "jawOpen": 0.05}),),
        "rounded, protruded lips of 'sh' ('quietly')",
        f"guessed; {_G}",
    ),
    "ee": Gesture(
        ((0, 1, _both(mouthStretch=0.5, mouthSmile=0.3) | {"jawOpen": 0.05}),),
        "stretched lips, teeth nearly closed ('intense')",
        f"guessed; {_G}",
    ),
    "rolled": Gesture(
        ((0, 1, {"mouthRollLower": 0.7, "mouthRollUpper": 0.7}),),
        "lips rolled in ('nothing')",
        f"[T6] nothing-sticks-out's 'tucked lips'; {_G}",
    ),
}


def _mouth_gesture(ctx, a: dict, head: str) -> ScoreVal:
    shape = a["shape"].value
    g = GESTURES.get(shape)
    if g is None:
        from azee_mj.sites import suggest

        raise RuleProblem(
            "shape",
            f"unknown mouth gesture {shape!r}{suggest(shape, list(GESTURES))} Shapes: "
            + ", ".join(GESTURES),
        )
    tl = Timeline()
    s, e = tl.put("SIG", a["sig"])
    relax = e - s > 2 * (RELAX_S + RELEASE_S)  # else the shape holds (see face_blocks)
    span = e - s - (RELAX_S + RELEASE_S if relax else 0.0)
    used: dict[str, float] = {}
    for k, (f0, f1, w) in enumerate(g.phases):
        tl.cstr(f"MOUTH_{k}", s + f0 * span, s + f1 * span, arkit.constraints(w))
        used.update(dict.fromkeys(w, 0.0))
    if relax:
        tl.cstr("MOUTH_RELAX", e - RELAX_S, e, arkit.constraints(used))
    return tl.value(head, "mouth-gesture")


# -- mouthing -----------------------------------------------------------------------------


def _mouthing(ctx, a: dict, head: str) -> ScoreVal:
    tl = Timeline()
    s, e = tl.put("SIG", a["sig"])
    try:
        keys = mouthing.keys(a["word"].value, a["lang"].value, e - s)
    except mouthing.MouthingError as err:
        raise RuleProblem(err.field, err.problem) from None
    h = mouthing.KEY_HALF_S
    for k, key in enumerate(keys):
        tl.cstr(f"VISEME_{k}", s + key.time - h, s + key.time + h, arkit.constraints(key.weights))
    return tl.value(head, "mouthing")


# -- the 40 brèves expressions --------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Expression:
    """A facial-expression rule of the corpus: its ARKit ``face``, an optional head
    orientation ``tilt`` (``(axis, k)``: head fwd + k axis), and what the source says."""

    face: Mapping[str, float]
    seen: str
    tilt: tuple[str, float] | None = None


#: The 22 rules of [T6] (``decidedly``, the 23rd, is its own rule), as their corpus stills
#: show them; "note" quotes the thesis's limitations table.
EXPRESSIONS: dict[str, Expression] = {
    "almost-reaching": Expression(
        _both(mouthSmile=0.3, mouthStretch=0.2, mouthLowerDown=0.1) | {"browInnerUp": 0.3},
        "slight smile, lips apart; note: 'mouth modeling unconvincing'",
    ),
    "big-threatening": Expression(
        _both(
            browDown=0.5,
            cheekSquint=0.5,
            eyeSquint=0.4,
            mouthUpperUp=0.6,
            mouthSmile=0.6,
            mouthLowerDown=0.3,
        )
        | {"jawOpen": 0.15},
        "AU4 brow lowerer, AU6 cheek raiser, AU7 lid tightener, AU10 upper lip raiser, AU12 lip "
        "corner puller, AU25 lips part (the thesis's detected AUs); teeth bared",
    ),
    "closer-look": Expression(
        _both(browDown=0.8, eyeSquint=0.7, mouthPress=0.4) | {"mouthPucker": 0.3},
        "brows lowered, eyes narrowed, lips pressed and pushed forward",
    ),
    "continuously": Expression(
        _both(mouthPress=0.4) | {"cheekPuff": 0.4, "mouthPucker": 0.3},
        "lips pressed and pushed out; note: '\"Pffff\" air and cheek puff, neutral eyebrows'",
    ),
    "do-you-realise": Expression(
        _both(browDown=0.4, eyeSquint=0.5) | {"mouthPucker": 0.3, "mouthRight": 0.3},
        "brows lowered, eyes narrowed, lips pursed to one side",
        ("lat(s)", 0.1),
    ),
    "impressive-grandiose": Expression(
        _both(browOuterUp=0.8, eyeWide=0.6)
        | {"browInnerUp": 0.8, "mouthFunnel": 0.6, "jawOpen": 0.25},
        "brows raised, eyes wide, lips rounded open ('o')",
    ),
    "inter-subjectivity": Expression(
        _both(mouthPress=0.3, mouthSmile=0.2),
        "lips pressed in a slight closed smile",
    ),
    "it-is-a-shame": Expression(
        _both(mouthFrown=0.6, mouthPress=0.3) | {"mouthShrugLower": 0.6, "browInnerUp": 0.4},
        "corners down, chin raised, lips pressed; note: 'mouth expression not quite real'",
    ),
    "most-probably": Expression(
        _both(browOuterUp=0.5, eyeSquint=0.2)
        | {"browInnerUp": 0.5, "mouthLowerDownLeft": 0.4, "jawOpen": 0.15},
        "head tilted, brows raised, lower lip down on one side; note: 'less visible teeth "
        "preferred'",
        ("lat(w)", 0.15),
    ),
    "much-almost-too-much": Expression(
        _both(browDown=0.8, noseSneer=0.5, eyeSquint=0.6, cheekSquint=0.4, mouthPress=0.3),
        "brows lowered, nose wrinkled, eyes narrowed; note: 'frowning eyebrows and lack of "
        "eye wrinkles'",
    ),
    "nothing-sticks-out": Expression(
        _both(eyeWide=0.3) | {"mouthRollLower": 0.7, "mouthRollUpper": 0.7, "browInnerUp": 0.4},
        "lips tucked in, eyes open; note: 'tucked lips difficult to model'",
    ),
    "peacefully": Expression(
        _both(mouthSmile=0.3, eyeSquint=0.3, eyeBlink=0.2),
        "slight closed smile, relaxed half-lowered lids",
    ),
    "something-sticks-out": Expression(
        _both(browDown=0.3, eyeSquint=0.4, mouthPress=0.3) | {"mouthPucker": 0.4},
        "lips pushed forward, eyes narrowed, head tilted; note: 'interpreted as confusion'",
        ("lat(s)", 0.1),
    ),
    "takes-a-while": Expression(
        _both(mouthStretch=0.5, mouthFrown=0.4, eyeSquint=0.4, mouthPress=0.3)
        | {"browInnerUp": 0.5},
        "corners stretched down, lips pressed, eyes narrowed, inner brows up",
    ),
    "too-scared-to-look": Expression(
        _both(eyeBlink=0.8, mouthFrown=0.3, mouthPress=0.4) | {"mouthShrugLower": 0.4},
        "eyes nearly shut, head turned away and back, lips pressed",
        ("lat(w)", 0.25),
    ),
    "trouble-disturbance": Expression(
        _both(browDown=0.8, noseSneer=0.4, eyeSquint=0.5, mouthPress=0.4)
        | {"mouthShrugUpper": 0.3, "mouthShrugLower": 0.4},
        "brows lowered, nose wrinkled, lips pressed upward; note: 'mouth \"rising\"'",
    ),
    "uneasy-awkward": Expression(
        {"tongueOut": 0.5, "jawOpen": 0.15, "mouthFunnel": 0.4, "browInnerUp": 0.3},
        "tongue tip out of rounded, slightly open lips",
    ),
    "with-chaos": Expression(
        _both(browOuterUp=0.3) | {"cheekPuff": 0.7, "mouthLeft": 0.4, "eyeSquintLeft": 0.4},
        "one cheek blown (ARKit puffs both: the mouth pulled to that side); note: 'single "
        "cheek blow/puff and alternating eye blinks'",
    ),
    "with-no-precision": Expression(
        _both(eyeBlink=0.4) | {"mouthShrugLower": 0.7, "mouthRollLower": 0.4, "mouthPucker": 0.3},
        "head back, upper lip over the lower pushed toward the nose, lids lowered; note: "
        "'upper lip over lower and mouth near nose'",
        ("up", 0.2),
    ),
    "with-surprise": Expression(
        _both(browOuterUp=0.9, eyeWide=0.8) | {"browInnerUp": 0.9, "mouthPucker": 0.4},
        "brows raised, eyes wide, lips pursed small; note: 'cannot lower lower eyelid fully'",
    ),
    "with-uncertainty": Expression(
        _both(mouthFrown=0.5, mouthPress=0.3) | {"browInnerUp": 0.6, "mouthLeft": 0.3},
        "inner brows up, corners down, lips pushed to one side, head tilted",
        ("lat(s)", 0.12),
    ),
    "with-worry": Expression(
        _both(browDown=0.3, eyeSquint=0.3, mouthStretch=0.5, mouthFrown=0.3)
        | {"browInnerUp": 0.8, "jawOpen": 0.1},
        "inner brows raised and knit, lips stretched apart; note: 'lack of wrinkles around "
        "nose/forehead'",
    ),
}


def rules(Rule) -> tuple:
    """The non-manual rules as ``Rule`` records (the class is passed in to keep imports one
    way)."""
    sig = Param("sig", "score")
    out = [
        Rule(
            "yes-no-question",
            (sig,),
            "SIG with FACE (brows raised: browInnerUp 0.8, browOuterUp 0.7; eyeWide 0.3) "
            f"and HEAD (head fwd+{YES_NO_TILT} down: forward tilt) over it",
            "ASL [BSC80]",
            "LSF assumed alike; weights and tilt guessed",
            _face_rule(YES_NO_FACE, ("down", YES_NO_TILT), "yes-no-question"),
            aliases=("yn-q",),
        ),
        Rule(
            "wh-question",
            (sig,),
            f"SIG with FACE (browDown 0.7, eyeSquint 0.3) and HEAD (head fwd+{WH_TILT} down)",
            "ASL [BSC80]",
            "LSF assumed alike; weights and tilt guessed",
            _face_rule(WH_FACE, ("down", WH_TILT), "wh-question"),
            aliases=("wh-q",),
        ),
        Rule(
            "boundary",
            (sig, Param("pause", "num", 0.3, minimum=0.2)),
            f"SIG, SIG_HOLD over 'pause, BLINK (eyeBlink 1) over its first {BLINK_S} s, "
            "BLINK_OPEN (eyeBlink 0) to its end",
            "blinks at intonational phrase boundaries [W94]",
            "blink length and pause guessed",
            _boundary,
        ),
        Rule(
            "mouth-gesture",
            (sig, Param("shape", "text")),
            "SIG with MOUTH_k (the shape's phases) over it and MOUTH_RELAX at its end; shapes: "
            + ", ".join(GESTURES),
            "per shape in docs/mouthing.md ([L80], [BSC80], [W01], [C08])",
            "every ARKit weight guessed",
            _mouth_gesture,
        ),
        Rule(
            "mouthing",
            (sig, Param("word", "text"), Param("lang", "text", "fr")),
            "SIG with VISEME_k keys of 'word spoken in 'lang (espeak-ng phonemes, "
            "OVRLipSync visemes, coarticulated) fitted into it",
            "visemes: Meta OVRLipSync; coarticulation: Cohen & Massaro 1993",
            "viseme weights, dominances and the speech rate guessed (docs/mouthing.md)",
            _mouthing,
        ),
    ]
    for name, x in EXPRESSIONS.items():
        shapes = ", ".join(f"{k} {v:g}" for k, v in sorted(x.face.items()))
        tilt = f"; HEAD (head fwd+{x.tilt[1]:g} {x.tilt[0]})" if x.tilt else ""
        out.append(
            Rule(
                name,
                (sig,),
                f"SIG with FACE over it: {x.seen}{tilt}",
                "[T6] (corpus still and notes)",
                f"ARKit weights ours from the still: {shapes}",
                _face_rule(x.face, x.tilt, name),
            )
        )
    return tuple(out)
