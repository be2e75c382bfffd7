"""Load and validate an AZee score (``azee-score`` version 1) into immutable records.

The package: :mod:`~azee_mj.score.records` (the dataclasses), :mod:`~azee_mj.score.references`
(``@site``, ``^locus``, ``!bone``), :mod:`~azee_mj.score.expressions` (walkers),
:mod:`~azee_mj.score.validation` (checks and messages), :mod:`~azee_mj.score.loading`
(:func:`load_score`). Its public names are re-exported here.

The input contract is the project's score-format document (``azee-score`` version 1):
nested, timed blocks (``sync``, ``cstr``, ``hold``, ``transpath``) whose leaves are
articulation constraints (``place``, ``orient``, ``morph``, ``look``, ``trill``).
:func:`load_score` reads a JSON file or an already-parsed dict, checks *everything*, and
returns a :class:`Score`; a bad score raises :class:`~azee_mj.errors.ScoreError` before
anything is solved.

Conventions of the records:

- Times are **absolute** seconds from the root block's start: the file's relative times are
  added up at load time (the root spans ``[0, root.end - root.start]``). Intervals are
  half-open ``[start, end)`` [s].
- Angles are radians (``Orient.tol``, a bone ``Trill.amplitude``); degrees exist only in the
  JSON (fields ending in ``_deg``). Lengths are metres, frequencies hertz.
- References are resolved with the score's strong side: ``@I_TIP(s)`` becomes
  ``SiteRef("I_TIP_R")``, ``!index(s,2)`` becomes ``BoneRef("index_R_2")``, ``lat(s)``
  becomes ``VAxis((0, -1, 0), "right")`` when the strong side is ``R`` (``+y`` is the
  signer's left). Records keep AZee names; :meth:`SiteRef.model_site` and
  :meth:`BoneRef.model_body` map them onto a model with a :class:`~azee_mj.sites.SignerMap`.
- Point and vector expressions are small frozen records; what they read is found by the
  walkers of :mod:`azee_mj.score.expressions`.

Error messages are one line::

    <dotted block path>: <where in the block>: <what is wrong>; <what is valid>

e.g. ``ROOT.K1: constraint 1 (place): unknown site 'I_TPI_R'; did you mean 'I_TIP_R'?
(azee-mj sites lists all)`` or ``ROOT.K1: field 'start': expected a number, got "0.4"``.
Errors outside any block start with ``score``; a block whose name is not known yet is
located by its parent and position (``ROOT: child 2: ...``, ``score: root block: ...``).
Inside a constraint the offending field is named (``field 'at.translate'``), except its
subject (its ``site`` or ``bone``), which the constraint itself names. ``ScoreError.path``
is the dotted block path ('' above the root) and ``ScoreError.field`` the offending key
(dotted inside expressions and transpath paths, e.g. ``at.mid[2]``, ``path.bulge``).
**Every index in a message is 1-based**: ``constraint 1`` is the first constraint of its
block, ``child 2`` the second block of a ``children`` list, and ``at.mid[1]`` the first
item of a list inside an expression. Lists of more than 8 valid names are abbreviated.

Beyond the format document, the loader also rejects (documented extensions): block names
that are empty or contain ``.`` (they would break dotted paths), a ``hold`` that starts
before the block it holds has ended (it keeps the posture reached at that end), a locus
where a moving body site is needed (``place``/``trill``/``transpath`` ``site``), duplicate
keys in a JSON object, and non-finite numbers. A literal full name (``@I_TIP_R``,
``!index_R_2``) is accepted as the absolute-side spelling of ``@I_TIP(R)``.
"""

from azee_mj.score.expressions import (
    depends_on_body,
    eval_point,
    eval_vector,
    referenced_bones,
    referenced_sites,
)
from azee_mj.score.loading import load_score
from azee_mj.score.records import (
    DEFAULT_TOL,
    DEFAULT_TOL_DEG,
    FORMAT,
    NAMED_DIRECTIONS,
    TIME_SLACK,
    VERSION,
    ZERO_NORM,
    Arc,
    Axis,
    Block,
    BlockKind,
    BoneRef,
    Circle,
    Constraint,
    Look,
    MorphC,
    Orient,
    Place,
    PLiteral,
    PMid,
    PointExpr,
    PSite,
    PTranslate,
    Rel,
    Route,
    Score,
    SiteRef,
    Straight,
    Trill,
    VAdd,
    VAxis,
    VBoneAxis,
    VCross,
    VectorExpr,
    VFrom,
    VLiteral,
    VOpp,
    VScale,
    VUnit,
)

__all__ = [
    "DEFAULT_TOL",
    "DEFAULT_TOL_DEG",
    "FORMAT",
    "NAMED_DIRECTIONS",
    "TIME_SLACK",
    "VERSION",
    "ZERO_NORM",
    "Arc",
    "Axis",
    "Block",
    "BlockKind",
    "BoneRef",
    "Circle",
    "Constraint",
    "Look",
    "MorphC",
    "Orient",
    "PLiteral",
    "PMid",
    "PSite",
    "PTranslate",
    "Place",
    "PointExpr",
    "Rel",
    "Route",
    "Score",
    "SiteRef",
    "Straight",
    "Trill",
    "VAdd",
    "VAxis",
    "VBoneAxis",
    "VCross",
    "VFrom",
    "VLiteral",
    "VOpp",
    "VScale",
    "VUnit",
    "VectorExpr",
    "depends_on_body",
    "eval_point",
    "eval_vector",
    "load_score",
    "referenced_bones",
    "referenced_sites",
]
