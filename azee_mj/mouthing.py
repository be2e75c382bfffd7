"""Mouthing: a spoken word as timed ARKit mouth shapes (visemes), fitted into a block.

1. **Phonemes.** The word goes through the ``phonemizer`` package's espeak-ng backend
   (``pip install azee_mj[mouthing]`` and the ``espeak-ng`` program), which gives IPA
   phones for about a hundred languages; this is the module's only impure step.
2. **Visemes.** Each phone maps onto one of the 15 visemes of Meta's OVRLipSync
   (:data:`VISEMES`: ``sil PP FF TH DD kk CH SS nn RR aa E ih oh ou``). OVRLipSync gives each
   viseme English example phonemes; the IPA symbols of French and German it has no example
   for (front rounded vowels, nasal vowels, uvular r, ``ç x``) are placed by where they are
   articulated (ours, :data:`IPA_VISEMES`). A diphthong is two visemes.
3. **Weights.** Each viseme is a set of ARKit weights (:data:`VISEME_WEIGHTS`, guessed).
4. **Timing and coarticulation.** Phones last :data:`PHONE_S` (speech rate, 12.5 phones a
   second); a key sits at each phone's centre, and its weights are blended with its
   neighbours' by Cohen and Massaro's dominance functions (1993): each viseme dominates
   ``alpha exp(-theta |t - centre|)`` around its centre, bilabials and labiodentals
   strongly (and their keys keep their own shapes: the lips must meet), tongue-only
   consonants weakly (they take the shape of the vowels around them). The word starts with its block; when it is longer than the
   block its phones are shortened down to :data:`MIN_PHONE_S`, and below that the weakest
   visemes are dropped (a reduced mouthing, as signers do) until it fits. A last key
   returns the mouth to rest.

Human speed: two keys are at least :data:`MIN_PHONE_S` apart, so that a full close-open
cycle of the lips or jaw takes at least 2 x 1/14 s = 1/7 s: adults repeat a syllable at
most about 7 times a second (the diadochokinetic rate; Fletcher 1972, "Time-by-count
measurement of diadochokinetic syllable rate", JSHR 15).

Times in seconds.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import unicodedata
from collections.abc import Mapping

from azee_mj.errors import AzeeError

#: Speech rate: one phone every 80 ms [s].
PHONE_S = 0.08
#: Shortest phone when a word is squeezed into a short block [s] (see the module).
MIN_PHONE_S = 1.0 / 14.0
#: Half the duration of each key's cstr block [s].
KEY_HALF_S = 0.01
#: Dominance decay rate [1/s]: a viseme's dominance halves every 40 ms from its centre.
THETA = math.log(2.0) / 0.04
#: Visemes whose key keeps its own shapes whatever the neighbours (the lips must meet).
CLOSURES = ("PP", "FF")
#: Longest text a mouthing may say [characters, after Unicode NFC and stripping]: a word or
#: a short phrase (German's longest dictionary compounds have about 60 letters). A longer
#: one is refused before the phonemizer sees it (it would mostly be dropped to fit its
#: block anyway: at most 14 visemes a second).
MAX_WORD = 100
#: Hint given when the phonemizer is missing.
INSTALL_HINT = "pip install 'azee_mj[mouthing]' and install espeak-ng (apt-get install espeak-ng)"

#: Short language names -> espeak-ng voices (any espeak-ng voice name is also accepted).
LANGUAGES = {"fr": "fr-fr", "de": "de", "en": "en-us", "en-gb": "en-gb", "it": "it", "es": "es"}

#: OVRLipSync's 15 visemes and its example phonemes (Meta, "Viseme Reference").
VISEMES = {
    "sil": "silence",
    "PP": "p b m",
    "FF": "f v",
    "TH": "th (think, that)",
    "DD": "t d",
    "kk": "k g",
    "CH": "ch j sh (chair, join, she)",
    "SS": "s z",
    "nn": "n l",
    "RR": "r",
    "aa": "a (car)",
    "E": "e (bed)",
    "ih": "i (tip)",
    "oh": "o (toe)",
    "ou": "u (book)",
}

#: IPA phone (stress, length and nasalisation marks removed) -> viseme.
IPA_VISEMES: dict[str, str] = {
    **dict.fromkeys(["p", "b", "m", "ɱ", "β", "ɸ", "ʙ"], "PP"),
    **dict.fromkeys(["f", "v", "pf", "ʋ"], "FF"),
    **dict.fromkeys(["θ", "ð"], "TH"),
    **dict.fromkeys(["t", "d", "ɾ", "ɗ", "ʈ", "ɖ"], "DD"),
    **dict.fromkeys(
        ["k", "g", "ɡ", "ŋ", "x", "ç", "h", "ɦ", "ʁ", "ʀ", "χ", "ɣ", "ɰ", "q", "ħ", "ʕ"], "kk"
    ),
    **dict.fromkeys(["ʃ", "ʒ", "tʃ", "dʒ", "ɕ", "ʑ", "c", "ɟ", "ʂ", "ʐ"], "CH"),
    **dict.fromkeys(["s", "z", "ts", "dz"], "SS"),
    **dict.fromkeys(["n", "l", "ɲ", "ɫ", "ʎ", "ɬ", "ɮ", "ɳ", "ɭ"], "nn"),
    **dict.fromkeys(["ɹ", "r", "ɻ", "ɚ", "ɝ", "ɽ"], "RR"),
    **dict.fromkeys(["a", "ɑ", "ɐ", "æ", "ʌ", "ɒ"], "aa"),
    **dict.fromkeys(["e", "ɛ", "ə", "ɜ", "œ", "ɘ", "ᵻ"], "E"),
    **dict.fromkeys(["i", "ɪ", "j", "ɨ", "ʝ"], "ih"),
    **dict.fromkeys(["o", "ɔ", "ø", "ɵ", "ɤ", "ɞ"], "oh"),
    **dict.fromkeys(["u", "ʊ", "w", "ɥ", "y", "ʏ", "ɯ"], "ou"),
    **dict.fromkeys(["ʔ"], "sil"),
}

#: Viseme -> ARKit weights (guessed: the lips and jaw as each viseme's example phonemes
#: are said; left and right alike).
VISEME_WEIGHTS: dict[str, dict[str, float]] = {
    "sil": {},
    "PP": {"mouthClose": 0.2, "mouthPressLeft": 0.5, "mouthPressRight": 0.5},
    "FF": {
        "mouthRollLower": 0.5,
        "mouthUpperUpLeft": 0.2,
        "mouthUpperUpRight": 0.2,
        "jawOpen": 0.08,
    },
    "TH": {"tongueOut": 0.3, "jawOpen": 0.15},
    "DD": {"jawOpen": 0.2, "mouthStretchLeft": 0.1, "mouthStretchRight": 0.1},
    "kk": {"jawOpen": 0.25, "mouthStretchLeft": 0.15, "mouthStretchRight": 0.15},
    "CH": {"mouthFunnel": 0.6, "jawOpen": 0.15},
    "SS": {
        "mouthStretchLeft": 0.3,
        "mouthStretchRight": 0.3,
        "jawOpen": 0.08,
        "mouthSmileLeft": 0.1,
        "mouthSmileRight": 0.1,
    },
    "nn": {"jawOpen": 0.15, "mouthStretchLeft": 0.1, "mouthStretchRight": 0.1},
    "RR": {"mouthFunnel": 0.3, "mouthPucker": 0.3, "jawOpen": 0.1},
    "aa": {"jawOpen": 0.75, "mouthLowerDownLeft": 0.2, "mouthLowerDownRight": 0.2},
    "E": {
        "jawOpen": 0.35,
        "mouthStretchLeft": 0.3,
        "mouthStretchRight": 0.3,
        "mouthSmileLeft": 0.1,
        "mouthSmileRight": 0.1,
    },
    "ih": {
        "jawOpen": 0.2,
        "mouthSmileLeft": 0.3,
        "mouthSmileRight": 0.3,
        "mouthStretchLeft": 0.2,
        "mouthStretchRight": 0.2,
    },
    "oh": {"jawOpen": 0.4, "mouthFunnel": 0.5},
    "ou": {"mouthPucker": 0.7, "mouthFunnel": 0.2, "jawOpen": 0.1},
}

#: Dominance of each viseme over its neighbours (Cohen & Massaro's alpha; guessed).
DOMINANCE = {
    "sil": 0.3,
    "PP": 1.0,
    "FF": 1.0,
    "TH": 0.8,
    "CH": 0.8,
    "ou": 0.8,
    "oh": 0.7,
    "aa": 0.6,
    "E": 0.6,
    "ih": 0.6,
    "RR": 0.5,
    "SS": 0.5,
    "DD": 0.3,
    "kk": 0.3,
    "nn": 0.3,
}

#: Marks dropped before the table: length, stress, nasalisation, syllabic, non-syllabic,
#: tie bars, and secondary articulations and phonation (palatalised, aspirated, labialised,
#: velarised, pharyngealised, ejective, dental, voiceless, voiced, rhotic, lowered, raised,
#: retracted, advanced, centralised), which do not change the viseme.
_DROP = "ːˑˈˌ̩̯̃͡‿ʲʰʷˠˤʼ̪̥̬˞̞̝̠̟̈"


class MouthingError(AzeeError):
    """A word that cannot be mouthed: a language the phonemizer lacks, a word it cannot
    phonemize, a phone without a viseme, or a block too short. ``problem`` is the message
    without its location, ``field`` what is wrong (``word``, ``lang`` or ``""``)."""

    def __init__(self, problem: str, field: str = "word"):
        super().__init__(problem)
        self.problem = problem
        self.field = field


class MouthingUnavailableError(MouthingError):
    """The optional ``phonemizer`` package or the espeak-ng program is missing."""


@dataclasses.dataclass(frozen=True)
class Key:
    """One viseme key: at ``time`` [s, from the block's start], the ``viseme`` of the phone
    said there and the blended ARKit ``weights`` of the mouth."""

    time: float
    viseme: str
    weights: Mapping[str, float]


def voice(lang: str) -> str:
    """The espeak-ng voice of ``lang`` (``fr``, ``de``, ``en`` or any espeak-ng voice)."""
    return LANGUAGES.get(lang, lang)


@functools.cache
def _backend(v: str):
    try:
        from phonemizer.backend import EspeakBackend
    except ImportError:
        raise MouthingUnavailableError(
            f"mouthing needs the package 'phonemizer': {INSTALL_HINT}", ""
        ) from None
    try:
        if not EspeakBackend.is_available():
            raise MouthingUnavailableError(f"mouthing needs espeak-ng: {INSTALL_HINT}", "")
        voices = EspeakBackend.supported_languages()
    except RuntimeError:
        raise MouthingUnavailableError(f"mouthing needs espeak-ng: {INSTALL_HINT}", "") from None
    if v not in voices:
        short = ", ".join(f"{k} ({w})" for k, w in LANGUAGES.items() if w in voices)
        raise MouthingError(
            f"language {v!r} is not one espeak-ng speaks; use {short} or any of the "
            f"{len(voices)} espeak-ng voices (espeak-ng --voices)",
            "lang",
        )
    return EspeakBackend(
        v, preserve_punctuation=False, with_stress=False, language_switch="remove-flags"
    )


def phonemes(word: str, lang: str) -> tuple[str, ...]:
    """The IPA phones of ``word`` in ``lang`` as espeak-ng says them (through phonemizer).

    Raises :class:`MouthingUnavailableError` without phonemizer or espeak-ng and
    :class:`MouthingError` for an unknown language or a word with no phones.
    """
    text = unicodedata.normalize("NFC", word).strip()
    if not text:
        raise MouthingError('the word is empty; write the word to mouth, e.g. "maison"')
    bad = next((c for c in text if unicodedata.category(c) == "Cc"), None)
    if bad is not None:  # a NUL would silently cut the word short in espeak-ng
        raise MouthingError(
            f"the word holds the control character U+{ord(bad):04X}; write the word to "
            'mouth in letters, e.g. "maison"'
        )
    if len(text) > MAX_WORD:
        raise MouthingError(
            f"the word is {len(text)} characters long; a mouthing says at most {MAX_WORD} "
            "(a word or a short phrase)"
        )
    backend = _backend(voice(lang))
    from phonemizer.separator import Separator

    out = backend.phonemize(
        [text], separator=Separator(phone=" ", word=" | ", syllable=""), strip=True
    )
    phones = tuple(p for p in (out[0] if out else "").split() if p != "|")
    if not phones:
        raise MouthingError(f"espeak-ng ({voice(lang)}) finds no phonemes in {word!r}")
    return phones


def _bare(phone: str) -> str:
    kept = "".join(c for c in unicodedata.normalize("NFD", phone) if c not in _DROP)
    return unicodedata.normalize("NFC", kept)


def visemes(phones: tuple[str, ...] | list[str]) -> tuple[str, ...]:
    """The viseme of each phone (two for a diphthong, one per symbol of a cluster the table
    lacks). Raises :class:`MouthingError` for a symbol without a viseme."""
    out: list[str] = []
    for phone in phones:
        bare = _bare(phone)
        if bare in IPA_VISEMES:
            out.append(IPA_VISEMES[bare])
            continue
        for c in bare:
            if c not in IPA_VISEMES:
                raise MouthingError(
                    f"the phone {phone!r} ({c!r}, U+{ord(c):04X}) has no viseme in the "
                    "OVRLipSync table"
                )
            out.append(IPA_VISEMES[c])
    return tuple(out)


def coarticulated(seq: tuple[str, ...], times: list[float]) -> list[dict[str, float]]:
    """The blended weights at each key time: the dominance-weighted mean of every viseme's
    target (Cohen & Massaro 1993, exponent 1); a :data:`CLOSURES` key is its own target
    alone (the shapes it does not name at 0: a neighbour's open jaw would part the lips)."""
    shapes = sorted({n for v in seq for n in VISEME_WEIGHTS[v]})
    out = []
    for t in times:
        dom = [DOMINANCE[v] * math.exp(-THETA * abs(t - c)) for v, c in zip(seq, times)]
        total = sum(dom)
        w = {
            n: sum(d * VISEME_WEIGHTS[v].get(n, 0.0) for d, v in zip(dom, seq)) / total
            for n in shapes
        }
        out.append(w)
    for w, v in zip(out, seq):
        if v in CLOSURES:  # the lips meet: no jaw or lip opening blended in from neighbours
            w.update({n: VISEME_WEIGHTS[v].get(n, 0.0) for n in w})
    return out


def fit(seq: tuple[str, ...], duration: float) -> tuple[tuple[str, ...], float]:
    """The visemes kept and the phone duration [s] for a block of ``duration`` seconds
    (module docstring): speech rate when it fits, shorter phones down to
    :data:`MIN_PHONE_S`, then the weakest visemes dropped (the first one is kept)."""
    seq = tuple(v for v in seq if v != "sil") or ("sil",)
    room = duration - 2 * KEY_HALF_S - MIN_PHONE_S  # the return to rest after the word
    if room < MIN_PHONE_S:
        raise MouthingError(
            f"the block lasts {duration:.3g} s; mouthing needs at least "
            f"{2 * MIN_PHONE_S + 2 * KEY_HALF_S:.3g} s",
            "sig",
        )
    n_max = max(1, math.floor(room / MIN_PHONE_S + 1e-9))
    kept = list(seq)
    while len(kept) > n_max:
        weakest = min(range(1, len(kept)), key=lambda i: (DOMINANCE[kept[i]], -i))
        del kept[weakest]
    return tuple(kept), min(PHONE_S, room / len(kept))


def keys(word: str, lang: str, duration: float) -> tuple[Key, ...]:
    """The viseme keys of ``word`` in ``lang`` fitted into a block of ``duration``
    seconds, and a last key at rest (``sil``, every shape the word used at 0)."""
    return plan(visemes(phonemes(word, lang)), duration)


def plan(seq: tuple[str, ...], duration: float) -> tuple[Key, ...]:
    """:func:`keys` from a viseme sequence (pure)."""
    kept, step = fit(seq, duration)
    times = [KEY_HALF_S + step * (k + 0.5) for k in range(len(kept))]
    weights = coarticulated(kept, times)
    out = [Key(t, v, w) for t, v, w in zip(times, kept, weights)]
    rest = {n: 0.0 for w in weights for n in w}
    end = min(duration - KEY_HALF_S, times[-1] + max(step, MIN_PHONE_S))
    out.append(Key(end, "sil", rest))
    return tuple(out)
