"""Trills: the envelope, the offset and the least-squares step called directly, and a
site trill added to frames of the real signer."""

from __future__ import annotations

import numpy as np
import pytest

from azee_mj.ikadapter import IKAdapter
from azee_mj.schedule import Schedule
from azee_mj.score import load_score
from azee_mj.trills import (
    TRILL_RAMP,
    add_trills,
    least_squares_step,
    trill_envelope,
    trill_offset,
)

FPS = 100.0


def test_envelope_ramps_up_and_down_over_trill_ramp():
    t = np.array([0.5, 0.5 + TRILL_RAMP / 2, 0.5 + TRILL_RAMP, 0.8, 1.0 - TRILL_RAMP / 4])
    np.testing.assert_allclose(trill_envelope(t, 0.5, 1.0), [0.0, 0.5, 1.0, 1.0, 0.25])


def test_offset_oscillates_at_its_amplitude_and_frequency():
    t = np.linspace(0.0, 1.0, 100001)
    x = trill_offset(0.01, 4.0, 1.0, t, 0.0)
    assert x.max() == pytest.approx(0.01, rel=1e-6) and x.min() == pytest.approx(-0.01, rel=1e-6)
    crossings = np.flatnonzero(np.diff(np.sign(x[1:-1])) != 0)
    assert len(crossings) == 2 * 4 - 1  # 4 periods in 1 s
    assert trill_offset(0.01, 4.0, 0.5, 0.0625, 0.0) == pytest.approx(0.005)  # at a peak


def test_least_squares_step_meets_the_target_with_the_least_norm():
    rng = np.random.default_rng(3)
    J = rng.normal(size=(3, 7))
    target = np.array([0.01, -0.02, 0.005])
    dq = least_squares_step(J, target)
    np.testing.assert_allclose(J @ dq, target, atol=1e-6)
    exact = np.linalg.pinv(J) @ target  # the least-norm solution: in the rows' span
    np.testing.assert_allclose(dq, exact, atol=1e-6)


def test_a_site_trill_moves_the_site_along_its_vector(solver):
    score = load_score(
        {
            "format": "azee-score",
            "version": 1,
            "root": {
                "name": "T",
                "kind": "cstr",
                "start": 0.0,
                "end": 0.5,
                "constraints": [
                    {
                        "type": "trill",
                        "site": "@I_TIP(s)",
                        "vector": "fwd",
                        "amplitude": 0.01,
                        "frequency": 4,
                    },
                ],
            },
        }
    )
    adapter = IKAdapter(Schedule(score, solver))
    times = np.arange(50) / FPS
    q0 = np.tile(solver.natural, (len(times), 1))
    q = add_trills(adapter, q0.copy(), times)
    sid = solver.site_id("I_TIP_R")
    moved = np.array([solver.at(q[f]).d.site_xpos[sid].copy() for f in range(len(times))])
    rest = solver.at(solver.natural).d.site_xpos[sid].copy()
    want = trill_offset(0.01, 4.0, trill_envelope(times, 0.0, 0.5), times, 0.0)
    # forward is +x in the signer frame; the step is linear in the joints, so the site
    # follows to first order: within 1 % of the amplitude, on and across the vector
    np.testing.assert_allclose(moved[:, 0] - rest[0], want, atol=0.01 * 0.01)
    np.testing.assert_allclose(moved[:, 1:] - rest[1:], 0.0, atol=0.01 * 0.01)
    assert np.abs(moved[:, 0] - rest[0]).max() > 0.9 * 0.01
    assert not adapter.results  # nothing went through the body: no solve
