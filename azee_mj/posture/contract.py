"""The contract between Python and the compiled solver core (``azee_mj/_ikcore_shared.h``).

Three records cross the boundary, each a numpy structured dtype here mirrored by a C struct
there (the core's ``layout()`` reports the struct sizes and field offsets, and a test holds
them equal to these dtypes):

- :data:`BLOCK`: one constraint's block of rows (kind, first row, row count, ids, constants).
- :data:`TERM`: a point term of a block (a site or a body origin, with its coefficient).
- :data:`TUNABLES`: the solver's constants, given once to each core; their values are
  defined here only.

Units: metres, radians.
"""

from __future__ import annotations

import functools

import numpy as np

from azee_mj.constraints import COLLISION_TOL

#: Row block kinds: a placement at a linear combination of fixed points, sites and body
#: origins; an orientation; a joint target; a general form written by Python.
POINT, ORIENT, JOINT, GENERIC = 0, 1, 2, 3
#: Point term kinds.
SITE, BODY = 0, 1
#: How the core takes a hard constraint's norm from its rows (``hard_norm``): as they are,
#: or as the angle of an orientation whose rows measure the angle's chord (along, opposite,
#: a look's eyes) or its sine (perpendicular). The norm is then 1 where the residual the
#: report measures reaches the tolerance.
HARD_LINEAR, HARD_CHORD, HARD_SINE = 0, 1, 2
#: Added to the kind of a ranged orientation (:attr:`~azee_mj.constraints.Orient.ranged`):
#: see ``RANGE_FREE``.
HARD_RANGE = 4

BLOCK = np.dtype(
    [
        ("kind", "i4"),
        ("start", "i4"),
        ("k", "i4"),
        ("hard", "i4"),
        ("perp", "i4"),
        ("id", "i4"),
        ("id2", "i4"),
        ("dof", "i4"),
        ("t0", "i4"),
        ("nt", "i4"),
        ("c", "f8", 3),
        ("local", "f8", 3),
        ("local2", "f8", 3),
        ("value", "f8"),
    ],
    align=True,
)
TERM = np.dtype([("kind", "i4"), ("id", "i4"), ("coef", "f8")], align=True)
TUNABLES = np.dtype(
    [
        ("mu0", "f8"),
        ("max_step", "f8"),
        ("met_gain", "f8"),
        ("far_cost", "f8"),
        ("far_gain", "f8"),
        ("collision_tol", "f8"),
        ("null_tol", "f8"),
        ("natural_step", "f8"),
        ("natural_iter", "i4"),
        ("pad_", "i4"),
        ("range_free", "f8"),
    ],
    align=True,
)

#: Initial Levenberg-Marquardt damping, relative to the mean diagonal of J^T J.
MU0 = 1e-3
#: Largest change of one joint in one iteration [rad or m] (a trust region).
MAX_STEP = 0.4
#: Once every constraint is within its tolerance, an LM step that lowers the cost by less
#: than this fraction ends the run: a limit or a contact holds a row short of the 5 % stop,
#: and the polish starts from there.
MET_GAIN = 0.25
#: Far from the tolerances (cost over ``FAR_COST``, rows scaled to 1 at their tolerance) a
#: step gaining less than ``FAR_GAIN`` counts as a stall: a local minimum that crawls is left
#: for the next start (the best unmet attempt is then converged without it).
FAR_COST = 4.0
FAR_GAIN = 1e-2
#: Directions in which the constraint rows change by less than this fraction of their
#: scale (root of the trace of A^T A) count as the constraints' null space.
NULL_TOL = 1e-4
#: Most natural-posture steps once the constraints are met.
NATURAL_ITER = 30
#: First trust radius of a natural-posture step [rad].
NATURAL_STEP = 0.2
#: A ranged orientation's rows are zero within this fraction of its tolerance and grow to
#: their full value at it (its norm: 0, then 1 at the tolerance). The reaching turns such
#: an axis only into its range, not to its middle, and the polish turns it freely there: a
#: palm asked within 30 degrees of facing down stays as the arm brings it, rather than the
#: whole arm turning it exactly down (the upper arm raised to horizontal for *penser*).
RANGE_FREE = 0.8


@functools.cache
def tunables() -> np.ndarray:
    """The one :data:`TUNABLES` record a core is made with (made once; read-only)."""
    out = np.zeros(1, TUNABLES)
    out[0] = (
        MU0,
        MAX_STEP,
        MET_GAIN,
        FAR_COST,
        FAR_GAIN,
        COLLISION_TOL,
        NULL_TOL,
        NATURAL_STEP,
        NATURAL_ITER,
        0,
        RANGE_FREE,
    )
    out.flags.writeable = False
    return out


def layout(dtype: np.dtype) -> tuple[int, dict[str, int]]:
    """(itemsize, {field: offset}) of ``dtype``, as the core's ``layout()`` reports a struct."""
    return dtype.itemsize, {name: dtype.fields[name][1] for name in dtype.names}
