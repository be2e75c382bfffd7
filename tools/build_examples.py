#!/usr/bin/env python3
"""Keep the bundled lexicon and the composed examples in step with their sources.

Run from the repository root after changing an example, a digit sign or a rule::

    python tools/build_examples.py

1. Lexicon signs made from the examples: ``arbre``, ``armoire``, ``penser`` (the files as
   they are), ``bien`` (with ``loc`` replacing ``^ssp`` in K2) and ``ix`` (IX_R of
   ``pointing.json``, 0.75 s, ``loc`` the target, with the fingertip past the locus, the
   palm as near down as the index allows and the handshape taken in the lead-in: see
   ``ix``); the digits ``nb-0`` ... ``nb-9``.
   ``cinema`` is written by hand in the lexicon (the generated ``info-about.json`` takes it
   from there).
2. Examples compiled from expressions: each ``examples/NAME.azee`` gives
   ``examples/NAME.json``, keeping the prose annotations (``x-faithful``, ``x-guessed``) of
   the file it replaces. ``tests/test_azee.py`` checks that both are up to date.
"""

from __future__ import annotations

import copy
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from azee_mj.azee import compile_file, dump_score

EXAMPLES = ROOT / "examples"
LEXICON = ROOT / "azee_mj" / "azee" / "lexicon"
LOC = {"loc": {"kind": "locus", "default": "^ssp"}}
#: Annotations a generated example keeps from the file it replaces.
PROSE = ("x-faithful", "x-guessed")

#: How far past the locus the ``ix`` fingertip stops, on the line from the sternum through
#: the locus [m]. pointing.json stops half way from the chest (0.12 m in front of it): the
#: wrist then lies at the chest, and pointing at the strong side's locus folds the elbow to
#: its limit, turns the wrist to its limits and twists the trunk 36 degrees, still missing
#: the index direction by 5 degrees. The loci are 0.24 m in front of the sternum, nearer
#: than a pointing hand rests: the hand stops just past the locus, forearm forward.
IX_PAST = 0.1

#: Digit handshapes (strong hand); 6-9 add a weak hand in hs_5.
DIGIT_SHAPES = {0: "hs_o", 1: "hs_index", 2: "hs_v", 3: "hs_3", 4: "hs_4", 5: "hs_5"}
DIGIT_SECONDS, DIGIT_LEAD = 0.7, 0.3
#: Height of the palm above the locus, its offset to the strong side for one hand, and to
#: each side for two hands [m].
DIGIT_ABOVE, DIGIT_SIDE, DIGIT_HALF_GAP = 0.1, 0.1, 0.16
#: How much a palm turns from forward toward the body's midline (0.4: 22 degrees); with the
#: palm straight forward the arm cannot reach and the spine twists.
DIGIT_PALM_IN = 0.4


def write(path: Path, text: str) -> None:
    if not path.exists() or path.read_text(encoding="utf-8") != text:
        path.write_text(text, encoding="utf-8")
        print(f"{path.relative_to(ROOT)}: written")


def example(name: str) -> dict:
    return json.loads((EXAMPLES / f"{name}.json").read_text(encoding="utf-8"))


def replace_point(block: dict, child: str, old: str, new: str) -> None:
    """Replace the point ``old`` by ``new`` in the constraints of ``block``'s ``child``."""

    def sub(x):
        if isinstance(x, dict):
            return {k: sub(v) for k, v in x.items()}
        if isinstance(x, list):
            return [sub(v) for v in x]
        return new if x == old else x

    for c in block["children"]:
        if c["name"] == child:
            c["constraints"] = sub(c["constraints"])
            return
    raise KeyError(child)


def with_params(score: dict, params: dict) -> dict:
    out = {k: v for k, v in score.items() if k != "root"}
    out["x-params"] = params
    out["root"] = score["root"]
    return out


def bien() -> dict:
    s = example("bien")
    replace_point(s["root"], "K2", "^ssp", "$loc")
    return with_params(s, LOC)


def ix() -> dict:
    p = example("pointing")
    root = p["root"]
    shape = next(c for c in root["children"] if c["name"] == "HANDSHAPE")
    point = copy.deepcopy(next(c for c in root["children"] if c["name"] == "IX_R"))
    point["name"] = "IX"
    end = point["end"]
    # The hand takes its shape during the lead-in, as the arm moves: from the sign's start
    # it would have to change where the previous sign left the hand (at the temple after
    # penser, where an index cannot straighten).
    shape = dict(
        shape,
        start=point["start"],
        end=end,
        constraints=[{"type": "morph", "id": "hs_index", "weight": 1.0, "side": "s"}],
    )
    replace_point({"children": [point]}, "IX", "^Rssp", "$loc")
    place, aim, palm, _look = point["constraints"]
    place["at"] = {"translate": "$loc", "by": {"scale": {"unit": aim["vector"]}, "by": IX_PAST}}
    # palm down as far as the index allows: "down" less its part along the pointing line
    palm["vector"] = {"cross": [aim["vector"], {"cross": ["down", aim["vector"]]}]}
    return {
        "format": "azee-score",
        "version": 1,
        "strong_side": "R",
        "x-source": "IX (index pointing) at 'loc: IX_R of examples/pointing.json",
        "x-guessed": "as pointing.json (index along the line from the sternum to the "
        "locus, palm down, gaze at the locus; 0.35 s lead-in, 0.4 s held), but "
        f"the fingertip {IX_PAST} m past the locus on that line (half way from "
        "the chest, the strong hand cannot point at its own side), the palm as "
        "near down as the index allows (within 15 degrees), and the hs_index handshape taken during "
        "the lead-in",
        "x-params": {"loc": {"kind": "locus", "default": "^ssp"}},
        "root": {"name": "IX", "kind": "sync", "start": 0, "end": end, "children": [shape, point]},
    }


def hand(side: str, shape: str, lat: float) -> tuple[dict, dict]:
    """The handshape and the hand placement of one hand of a digit."""
    at = {
        "translate": "$loc",
        "by": {"add": [{"scale": "up", "by": DIGIT_ABOVE}, {"scale": f"lat({side})", "by": lat}]},
    }
    other = "w" if side == "s" else "s"
    shape_c = {"type": "morph", "id": shape, "weight": 1.0, "side": side}
    place = [
        {"type": "place", "site": f"@PA({side})", "at": at},
        {
            "type": "orient",
            "bone": f"!palm({side})",
            "axis": "nrm",
            "rel": "along",
            "vector": {"add": ["fwd", {"scale": f"lat({other})", "by": DIGIT_PALM_IN}]},
        },
        {"type": "orient", "bone": f"!palm({side})", "axis": "dir", "rel": "along", "vector": "up"},
    ]
    return shape_c, place


def digit(n: int) -> dict:
    if n <= 5:
        hands = [hand("s", DIGIT_SHAPES[n], DIGIT_SIDE)]
    else:
        hands = [hand("w", "hs_5", DIGIT_HALF_GAP), hand("s", DIGIT_SHAPES[n - 5], DIGIT_HALF_GAP)]
    shape = [h[0] for h in hands]
    place = [c for h in hands for c in h[1]]
    return {
        "format": "azee-score",
        "version": 1,
        "strong_side": "R",
        "x-source": f"LSF number {n}, palm forward, {DIGIT_ABOVE} m above 'loc",
        "x-guessed": "handshapes (1-4 index, +middle, thumb+index+middle, four fingers; 5 "
        "spread; 0 half-bent with the thumb opposed; 6-9 a weak 5 and a strong "
        "n-5), the palm facing forward and 22 degrees inward, fingers up, the "
        "place (0.1 m above the locus, 0.1 m to the strong side; two hands 0.32 m "
        f"apart) and the timing ({DIGIT_LEAD} s lead-in, {DIGIT_SECONDS} s in all)",
        "x-params": LOC,
        "root": {
            "name": f"NB_{n}",
            "kind": "sync",
            "start": 0,
            "end": DIGIT_SECONDS,
            "children": [
                {
                    "name": "SHAPE",
                    "kind": "cstr",
                    "start": 0,
                    "end": DIGIT_SECONDS,
                    "constraints": shape,
                },
                {
                    "name": "HAND",
                    "kind": "cstr",
                    "start": DIGIT_LEAD,
                    "end": DIGIT_SECONDS,
                    "constraints": place,
                },
            ],
        },
    }


def main() -> int:
    for name in ("arbre", "armoire", "penser"):
        write(LEXICON / f"{name}.json", dump_score(example(name)))
    write(LEXICON / "bien.json", dump_score(bien()))
    write(LEXICON / "ix.json", dump_score(ix()))
    for n in range(10):
        write(LEXICON / f"nb-{n}.json", dump_score(digit(n)))
    for src in sorted(EXAMPLES.glob("*.azee")):
        out = EXAMPLES / f"{src.stem}.json"
        score = compile_file(src)
        if out.exists():
            old = json.loads(out.read_text(encoding="utf-8"))
            prose = {k: old[k] for k in PROSE if k in old}
            score = {
                **{k: v for k, v in score.items() if k != "root"},
                **prose,
                "root": score["root"],
            }
        write(out, dump_score(score))
    return 0


if __name__ == "__main__":
    sys.exit(main())
