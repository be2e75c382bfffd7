"""Trills: the envelope, the offset and the least-squares steps called directly, a site
trill added to frames of the real signer, and a fingertip flickering while another block
holds its hand."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from azee_mj.ikadapter import IKAdapter
from azee_mj.schedule import Schedule
from azee_mj.score import load_score
from azee_mj.timeline import realize
from azee_mj.trills import (
    FINGER_TRILL_MAX,
    TRILL_RAMP,
    add_trills,
    held_step,
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


def test_a_held_step_keeps_the_held_rows_and_meets_the_target_when_it_can():
    rng = np.random.default_rng(4)
    J, H = rng.normal(size=(3, 9)), rng.normal(size=(4, 9))
    target = np.array([0.01, -0.02, 0.005])
    dq = held_step(J, H, target)
    np.testing.assert_allclose(H @ dq, 0.0, atol=1e-9)
    np.testing.assert_allclose(J @ dq, target, atol=1e-6)  # 5 free directions for 3 rows
    # the least norm among them: no part along the held rows' span
    np.testing.assert_allclose(np.linalg.lstsq(H.T, dq, rcond=None)[0], 0.0, atol=1e-6)
    np.testing.assert_array_equal(
        held_step(J, np.zeros((0, 9)), target), least_squares_step(J, target)
    )


def test_a_damped_step_is_bounded_however_singular_the_jacobian():
    # a folded finger: its tip can hardly move along the trill; the damping bounds the turn
    J = np.array([[1e-4, 0.0], [0.0, 0.05], [0.0, 0.0]])
    target = np.array([0.012, 0.0, 0.0])
    damping = (0.012 / (2.0 * FINGER_TRILL_MAX)) ** 2
    for H in (np.zeros((0, 2)), np.array([[0.0, 1.0]])):
        dq = held_step(J, H, target, damping)
        assert np.abs(dq).max() <= FINGER_TRILL_MAX + 1e-12
    assert np.abs(held_step(J, np.zeros((0, 2)), target)).max() > 4 * FINGER_TRILL_MAX


def test_a_fingertip_flickers_while_another_block_holds_its_hand(solver):
    # info-about: the middle fingertip trills up and down (12 mm, 5 Hz) while the wrist is
    # placed at the other palm and the palm oriented within 1 degree (another block): the
    # fingers flicker, the wrist stays, and every frame keeps the placement
    root = Path(__file__).resolve().parent.parent
    score = load_score(json.loads((root / "examples" / "info-about.json").read_text()))
    r = realize(score, fps=50, solver=solver)
    (flicker,) = [b for b in score.blocks() if b.path.endswith("FLICKER")]
    t = r.time - r.score_start
    sel = (t >= flicker.start + TRILL_RAMP) & (t < flicker.end - TRILL_RAMP)

    def wiggle(site: str) -> float:  # peak to peak [m] about a smooth fit, up and down
        z = r.site_pos[:, r.site_names.index(site), 2][sel]
        z = z - np.polyval(np.polyfit(t[sel], z, 2), t[sel])
        return float(z.max() - z.min())

    assert wiggle("M_TIP_R") > 0.005  # it was 1 mm: the arm's shake, undone frame by frame
    assert wiggle("WR_R") < 1e-4
    beam = [tr for tr in r.traces if tr.block.endswith("BEAM")]
    assert beam and all(tr.ok for tr in beam)


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
