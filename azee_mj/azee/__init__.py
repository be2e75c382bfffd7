"""Mini-AZee: compile AZee-style text (``.azee``) to ``azee-score`` v1 scores.

``:info-about(:cinema, :bien)`` or its corpus layout form becomes a score dict that
:func:`azee_mj.score.load_score` accepts. Rules (``seq``, ``info-about``, ``nicht-sondern``
...) lay their arguments out in time and overlay non-manual blocks; signs come from a
lexicon of score templates. This package produces scores only: it imports nothing from
solving or realizing.

    >>> from azee_mj.azee import compile_text
    >>> compile_text(":info-about(:cinema, :bien)")["root"]["end"]
    2.4
"""

from azee_mj.azee.catalogue import Param
from azee_mj.azee.errors import ExpressionError
from azee_mj.azee.evaluate import (
    compile_file,
    compile_score,
    compile_text,
    dump_score,
    rules_catalogue,
)
from azee_mj.azee.lexicon import Lexicon, Sign
from azee_mj.azee.rules import RULES, Rule
from azee_mj.azee.syntax import parse

__all__ = [
    "RULES",
    "ExpressionError",
    "Lexicon",
    "Param",
    "Rule",
    "Sign",
    "compile_file",
    "compile_score",
    "compile_text",
    "dump_score",
    "parse",
    "rules_catalogue",
]
