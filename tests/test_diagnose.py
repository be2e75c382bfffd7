"""azee_mj.diagnose: the words of a local minimum carry why the solver stopped."""

from __future__ import annotations

import numpy as np

from azee_mj import diagnose, ik
from azee_mj.posture.problem import Stop


def _result(**kw) -> ik.IKResult:
    return ik.IKResult(np.zeros(3), False, (), 0.0, 10, 0, 0.0, np.zeros(10), **kw)


def test_a_minimum_says_why_the_solver_stopped():
    assert diagnose.minimum_detail(_result(stop=Stop.STALL)) == (
        "a local minimum of the solver (no limit, reach or collision explains it); "
        "the solver stopped: three steps of little gain (a local minimum)"
    )


def test_a_result_without_a_run_keeps_the_plain_words():
    assert diagnose.minimum_detail(_result()) == (
        "a local minimum of the solver (no limit, reach or collision explains it)"
    )
