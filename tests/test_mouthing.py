"""Mouthing (azee_mj/mouthing.py) and the non-manual rules: visemes against espeak-ng's
phonemes, timing, coarticulation, human speed, errors, and realization on the signer."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest
from scores import cstr, envelope, sync

from azee_mj import arkit, mouthing
from azee_mj import face as face_mod
from azee_mj.azee import ExpressionError, compile_file, compile_text, parse
from azee_mj.azee.catalogue import quote
from azee_mj.azee.nonmanual import EXPRESSIONS, GESTURES
from azee_mj.cli import main
from azee_mj.export import arkit as face
from azee_mj.schedule import make_solver
from azee_mj.score import load_score
from azee_mj.sites import DEFAULT_MAP
from azee_mj.timeline import realize


def _has_phonemizer() -> bool:
    try:
        mouthing.phonemes("a", "fr")
    except mouthing.MouthingUnavailableError:
        return False
    return True


HAS_PHONEMIZER = _has_phonemizer()
needs_phonemizer = pytest.mark.skipif(
    not HAS_PHONEMIZER, reason="mouthing needs the [mouthing] extra and espeak-ng"
)

#: Three words per language: the phones of their standard pronunciation (as espeak-ng
#: gives them) and, by hand from the OVRLipSync viseme classes, their visemes.
WORDS = [
    ("fr", "bonjour", "b ɔ̃ ʒ u ʁ", "PP oh CH ou kk"),
    ("fr", "maison", "m ɛ z ɔ̃", "PP E SS oh"),
    ("fr", "fou", "f u", "FF ou"),
    ("de", "Haus", "h aʊ s", "kk aa ou SS"),
    ("de", "schön", "ʃ øː n", "CH oh nn"),
    ("de", "Buch", "b uː x", "PP ou kk"),
    ("en", "think", "θ ɪ ŋ k", "TH ih kk kk"),
    ("en", "church", "tʃ ɜː tʃ", "CH E CH"),
    ("en", "yes", "j ɛ s", "ih E SS"),
]


# -- pure ---------------------------------------------------------------------------------


def assert_arkit_weights(weights, where: str) -> None:
    """Every name an ARKit shape of the catalogue, every weight in [0, 1]."""
    for name, w in weights.items():
        assert name in arkit.ARKIT_SHAPES and name in DEFAULT_MAP.morphs, (where, name)
        assert 0.0 <= w <= 1.0, (where, name, w)


def test_every_viseme_has_weights_in_range_and_a_dominance():
    assert set(mouthing.VISEMES) == set(mouthing.VISEME_WEIGHTS) == set(mouthing.DOMINANCE)
    assert len(mouthing.VISEMES) == 15
    for v, w in mouthing.VISEME_WEIGHTS.items():
        assert_arkit_weights(w, v)
    assert set(mouthing.IPA_VISEMES.values()) <= set(mouthing.VISEMES)


def test_length_stress_and_nasal_marks_do_not_change_the_viseme():
    assert mouthing.visemes(["ɔ̃", "øː", "ˈa", "ç"]) == ("oh", "oh", "aa", "kk")
    assert mouthing.visemes(["aʊ", "tʃ"]) == ("aa", "ou", "CH")  # diphthong: two; affricate: one
    assert mouthing.visemes(["mʲ", "dʰ", "t̪"]) == ("PP", "DD", "DD")  # secondary articulations


def test_a_phone_without_a_viseme_is_named():
    with pytest.raises(mouthing.MouthingError) as e:
        mouthing.visemes(["a", "ʘ"])
    assert str(e.value) == "the phone 'ʘ' ('ʘ', U+0298) has no viseme in the OVRLipSync table"


@pytest.mark.parametrize("duration", [0.2, 0.35, 0.6, 1.2, 3.0])
def test_visemes_fit_their_block_at_human_speed(duration):
    seq = ("PP", "aa", "PP", "aa", "SS", "E", "kk", "ou", "nn", "ih", "FF", "oh")
    keys = mouthing.plan(seq, duration)
    t = np.array([k.time for k in keys])
    h = mouthing.KEY_HALF_S
    assert t[0] - h >= 0 and t[-1] + h <= duration + 1e-9
    # Human speed: keys at least 1/14 s apart, so that a close-open cycle takes >= 1/7 s
    # (adults repeat a syllable at most ~7 times a second, Fletcher 1972).
    assert np.diff(t).min() >= mouthing.MIN_PHONE_S - 1e-9
    shapes = sorted({n for k in keys for n in k.weights})
    w = np.array([[k.weights.get(n, 0.0) for n in shapes] for k in keys])
    assert w.min() >= 0 and w.max() <= 1
    # a minimum-jerk blend peaks at 1.875 x its mean rate: at most 26.25 weight units a second
    assert (1.875 * np.abs(np.diff(w, axis=0)) / np.diff(t)[:, None]).max() <= 1.875 * 14 + 1e-6
    assert keys[-1].viseme == "sil" and not any(keys[-1].weights.values())
    assert keys[0].viseme == "PP"  # a shortened word keeps its first viseme
    if duration >= 1.2:  # at speech rate nothing is dropped
        assert tuple(k.viseme for k in keys[:-1]) == seq
        assert np.diff(t[:-1]) == pytest.approx(mouthing.PHONE_S)
    else:
        assert len(keys) - 1 < len(seq)


def test_coarticulation_keeps_lip_closure_and_blends_the_rest():
    keys = mouthing.plan(("aa", "PP", "aa"), 1.0)
    closed = keys[1].weights
    for n, v in mouthing.VISEME_WEIGHTS["PP"].items():
        assert closed[n] == pytest.approx(v)  # the lips meet whatever the vowels
    alone = mouthing.VISEME_WEIGHTS["aa"]["jawOpen"]
    assert 0 < keys[0].weights["jawOpen"] < alone  # the vowel anticipates the closure
    assert keys[0].weights["mouthPressLeft"] > 0


def test_a_block_too_short_is_refused():
    with pytest.raises(mouthing.MouthingError) as e:
        mouthing.plan(("PP", "aa"), 0.1)
    assert str(e.value) == "the block lasts 0.1 s; mouthing needs at least 0.163 s"


# -- espeak-ng ------------------------------------------------------------------------------


@needs_phonemizer
@pytest.mark.parametrize(("lang", "word", "phones", "visemes"), WORDS)
def test_visemes_of_three_words_per_language_follow_the_phonemizer(lang, word, phones, visemes):
    got = mouthing.phonemes(word, lang)
    assert " ".join(got) == phones
    assert mouthing.visemes(got) == tuple(visemes.split())
    keys = mouthing.keys(word, lang, 2.0)
    assert tuple(k.viseme for k in keys[:-1]) == tuple(v for v in visemes.split() if v != "sil")


@needs_phonemizer
@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            ':mouthing(:bien, "bien", \'lang "xx")',
            (
                "<-e>:1:1: :mouthing'lang: language 'xx' is not one espeak-ng speaks; use fr "
                "(fr-fr), de (de), en (en-us), en-gb (en-gb), it (it), es (es) or any of the "
                "130 espeak-ng voices (espeak-ng --voices)"
            ),
        ),
        (
            ':mouthing(:bien, "!?")',
            "<-e>:1:1: :mouthing'word: espeak-ng (fr-fr) finds no phonemes in '!?'",
        ),
        (
            ':mouthing(:bien, "")',
            '<-e>:1:1: :mouthing\'word: the word is empty; write the word to mouth, e.g. "maison"',
        ),
        (
            ':seq(:bien, :mouthing(:bien, "?"))',
            "<-e>:1:13: :seq'item:mouthing'word: espeak-ng (fr-fr) finds no phonemes in '?'",
        ),
    ],
)
def test_mouthing_errors_exit_2_with_the_block_path(text, message, tmp_path, capsys):
    out = tmp_path / "o.json"
    assert main(["compile", "-e", text, "-o", str(out)]) == 2
    assert capsys.readouterr().err == f"azee-mj: error: {message}\n"
    assert not out.exists()


def test_missing_phonemizer_is_one_message():
    code = (
        "import sys; sys.modules['phonemizer'] = None\n"
        "from azee_mj.cli import main\n"
        "sys.exit(main(['compile', '-e', ':mouthing(:bien, \"bien\")']))\n"
    )
    p = subprocess.run([sys.executable, "-c", code], check=False, capture_output=True, text=True)
    assert p.returncode == 2
    assert p.stderr == (
        "azee-mj: error: <-e>:1:1: :mouthing: mouthing needs the package 'phonemizer': pip "
        "install 'azee_mj[mouthing]' and install espeak-ng (apt-get install espeak-ng)\n"
    )


def test_unknown_mouth_gesture_and_text_syntax_errors():
    with pytest.raises(ExpressionError) as e:
        compile_text(':mouth-gesture(:bien, "pha")', file="<-e>")
    assert str(e.value) == (
        "<-e>:1:1: :mouth-gesture'shape: unknown mouth gesture 'pha'; did you mean 'pah'? "
        "Shapes: " + ", ".join(GESTURES)
    )
    with pytest.raises(ExpressionError) as e:
        compile_text(':mouth-gesture(:bien, "pah)', file="<-e>")
    assert str(e.value) == (
        '<-e>:1:23: syntax: unterminated text: a text ends with " on the same line'
    )
    with pytest.raises(ExpressionError) as e:
        compile_text(":mouth-gesture(:bien, 3)", file="<-e>")
    assert str(e.value) == (
        '<-e>:1:23: :mouth-gesture: \'shape: expected a text in double quotes ("maison"), got num 3'
    )


def test_texts_round_trip_through_x_source():
    s = compile_text(':mouth-gesture(:bien, "o")')
    assert s["x-source"] == ":mouth-gesture('sig :bien, 'shape \"o\")"
    assert compile_text(s["x-source"])["root"] == s["root"]
    node = parse(':x("say \\"ah\\" \\\\ # no comment")')
    assert node.args[0].value.text == 'say "ah" \\ # no comment'
    assert quote(node.args[0].value.text) == '"say \\"ah\\" \\\\ # no comment"'


@needs_phonemizer
def test_mouthing_keys_lie_inside_the_sign():
    s = compile_text(':mouthing(:arbre, "arbre", \'lang "fr")')
    sig = next(c for c in s["root"]["children"] if c["name"] == "SIG")
    keys = [c for c in s["root"]["children"] if c["name"].startswith("VISEME_")]
    assert len(keys) == len(mouthing.visemes(mouthing.phonemes("arbre", "fr"))) + 1
    assert all(sig["start"] <= k["start"] < k["end"] <= sig["end"] for k in keys)


@pytest.mark.parametrize("name", list(GESTURES))
def test_mouth_gestures_are_timed_arkit_sets(name):
    g = GESTURES[name]
    assert g.what and g.source
    for f0, f1, w in g.phases:
        assert 0 <= f0 < f1 <= 1
        assert_arkit_weights(w, name)
    assert len(GESTURES) >= 10


def test_the_corpus_expressions_are_valid_arkit_sets():
    assert len(EXPRESSIONS) == 22
    for name, x in EXPRESSIONS.items():
        assert_arkit_weights(x.face, name)


# -- on the signer ----------------------------------------------------------------------------


SENTENCE = (
    ':seq(:mouthing(:arbre, "arbre"), :wh-question(:penser), '
    ':mouth-gesture(:bien, "pah"), :with-surprise(:cinema), :boundary(:armoire))'
)


@needs_phonemizer
def test_a_mouthed_sentence_realizes_within_human_speed(model):
    r = realize(compile_text(SENTENCE), fps=50.0)
    assert all(t.ok for t in r.traces), [t.describe() for t in r.traces if not t.ok]
    jaw = model.jnt_qposadr[model.joint("jaw_open").id]
    assert np.ptp(r.qpos[:, jaw]) > 0.05  # the jaw moved with the words
    w = face.weights(model, r.qpos)
    mouth = [
        arkit.ARKIT_SHAPES.index(n) for n in arkit.ARKIT_SHAPES if n.startswith(("jaw", "mouth"))
    ]
    rate = np.abs(np.diff(w[:, mouth], axis=0)).max() * r.fps
    assert 0 < rate <= 1.875 * 14 + 1e-6, rate  # the limit of the planned keys (Fletcher 1972)


def _face_score(mid: str, weight: float) -> dict:
    return envelope(
        sync("S", 1, cstr("FACE", 0, 1, {"type": "morph", "id": mid, "weight": weight}))
    )


def test_an_arkit_weight_out_of_range_or_an_unknown_shape_is_one_message():
    from azee_mj.errors import ScoreError

    load_score(_face_score("jawOpen", 1.0))
    with pytest.raises(ScoreError) as e:
        load_score(_face_score("jawOpen", 1.5))
    assert str(e.value) == (
        "S.FACE: constraint 1 (morph): field 'weight': weight 1.5 is out of range; ARKit "
        "shapes take 0 to 1"
    )
    with pytest.raises(ScoreError) as e:
        load_score(_face_score("mouthSmile", -0.2))
    assert "weight -0.2 is out of range" in str(e.value)
    with pytest.raises(ScoreError) as e:
        load_score(_face_score("jawOpn", 0.5))
    assert str(e.value).startswith("S.FACE: constraint 1 (morph): field 'id': unknown morph")
    assert str(e.value).endswith("did you mean 'jawOpen'?")


@needs_phonemizer
def test_the_documented_example_closes_the_lips_and_blinks(model):
    """docs/examples/mouthing.azee (face-question.gif): the lips meet at every "m" and "b"
    (a lip closure's key is its own shapes alone), open wider for "a" than for "o", and
    the eyes close at the boundary, as the rig's apertures measure them."""
    path = Path(__file__).resolve().parent.parent / "docs" / "examples" / "mouthing.azee"
    s = compile_file(path)
    names = {b["name"] for b in _walk(s["root"])}
    assert {"FACE", "HEAD", "BLINK", "VISEME_0"} <= names
    score = load_score(s)
    r = realize(score, fps=50.0, solver=make_solver())
    assert all(t.ok for t in r.traces), [t.describe() for t in r.traces if not t.ok]
    d = mujoco.MjData(model)

    def apertures(t: float) -> tuple[float, float]:
        d.qpos[:] = r.qpos[round((r.score_start + t) * r.fps)]  # score time -> rollout
        mujoco.mj_kinematics(model, d)
        return face_mod.lip_aperture(model, d), face_mod.eyelid_aperture(model, d, "R")

    keys = {}
    for b in score.blocks():
        ids = {c.id: c.weight for c in getattr(b, "constraints", ()) if hasattr(c, "id")}
        if b.name.startswith("VISEME_") and ids.get("mouthPress") == 0.5:
            keys.setdefault("PP", []).append(b.start)
        if b.name.startswith("VISEME_") and "mouthFunnel" in ids and not keys.get("oh"):
            keys["oh"] = [b.start]  # the first rounded key: "au"
        if b.name.startswith("VISEME_") and ids.get("mouthLowerDown", 0.0) > 0.1:
            keys["aa"] = [b.start]  # the open "a" of cinéma
        if b.name == "BLINK":
            keys["BLINK"] = [b.start + 0.04]
    assert len(keys["PP"]) == 2  # the "m" of cinéma, the "b" of bien
    assert all(apertures(t)[0] == 0.0 for t in keys["PP"])
    assert apertures(keys["BLINK"][0])[1] == 0.0
    assert apertures(keys["aa"][0])[0] > apertures(keys["oh"][0])[0] + 0.001


def _walk(block: dict):
    yield block
    for c in block.get("children", ()):
        yield from _walk(c)


@pytest.mark.parametrize(
    ("mid", "weight", "problem"),
    [
        ("jawOpen", 1.5, "field 'weight': weight 1.5 is out of range; ARKit shapes take 0 to 1"),
        ("eyeBlink", -0.2, "field 'weight': weight -0.2 is out of range; ARKit shapes take 0 to 1"),
        ("jawOpn", 0.5, "field 'id': unknown morph 'jawOpn'"),
    ],
)
def test_a_bad_face_morph_in_a_score_exits_2_with_the_block_path(
    mid, weight, problem, tmp_path, capsys
):
    src, out = tmp_path / "face.json", tmp_path / "face.npz"
    src.write_text(json.dumps(_face_score(mid, weight)))
    assert main(["realize", str(src), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"azee-mj: error: S.FACE: constraint 1 (morph): {problem}"), err
    if mid == "jawOpn":
        assert err.endswith("did you mean 'jawOpen'?\n"), err
    else:
        assert err == f"azee-mj: error: S.FACE: constraint 1 (morph): {problem}\n"
    assert not out.exists()
