"""Blends bent around the body (azee_mj/detour.py): its pure functions, and the arbre ->
info-about transition on the real model, where the straight blend goes through the other
forearm."""

import json
from pathlib import Path

import mujoco
import numpy as np
import pytest

from azee_mj import detour as dt
from azee_mj import movement as mv
from azee_mj.blend import minjerk
from azee_mj.ikadapter import IKAdapter
from azee_mj.model import load_model
from azee_mj.schedule import Schedule, make_solver
from azee_mj.score import load_score
from azee_mj.timeline import realize

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
FPS = 50.0


@pytest.mark.parametrize("at", [0.1, 0.3, 0.5, 0.8])
def test_a_bump_is_zero_at_the_ends_one_at_its_top_with_flat_ends_and_top(at):
    s = np.linspace(0.0, 1.0, 2001)
    b = dt.bump(s, at)
    assert b[0] == 0.0 and b[-1] == 0.0
    assert dt.bump(np.array([at]), at)[0] == pytest.approx(1.0)
    assert b.min() >= 0.0 and b.max() == pytest.approx(1.0)
    slope = np.gradient(b, s)
    top = int(np.argmin(np.abs(s - at)))
    assert abs(slope[0]) < 1e-2 and abs(slope[-1]) < 1e-2 and abs(slope[top]) < 1e-1
    assert np.all(np.diff(b[: top + 1]) >= 0.0) and np.all(np.diff(b[top:]) <= 0.0)


def test_progress_of_a_straight_blend_is_its_minimum_jerk_fraction():
    u = minjerk(np.linspace(0.0, 1.0, 21))
    qa, qb = np.array([0.1, -0.4, 1.0]), np.array([0.7, 0.2, 0.5])
    q = qa + u[:, None] * (qb - qa)
    np.testing.assert_allclose(dt.progress(q), u, atol=1e-12)


def test_runs_span_from_the_frame_before_to_the_frame_after():
    flags = np.array([False, True, True, False, False, True, True])
    assert dt.runs(flags) == [(0, 3), (4, 6)]


def two_signs(first: str, second: str) -> dict:
    """A score of two bundled examples, 0.1 s apart (strong side R)."""
    return signs(first, second)


def signs(*names: str) -> dict:
    """A score chaining bundled examples, 0.1 s apart (strong side R), their blocks named
    ``S<i>_<root>``."""
    children, t = [], 0.0
    for i, n in enumerate(names):
        root = json.loads((EXAMPLES / f"{n}.json").read_text())["root"]
        d = root["end"] - root["start"]
        children.append({**root, "name": f"S{i}_{root['name']}", "start": t, "end": t + d})
        t += d + 0.1
    root = {"name": "TWO", "kind": "sync", "start": 0.0, "end": t, "children": children}
    return {"format": "azee-score", "version": 1, "strong_side": "R", "root": root}


def test_leaving_arbre_the_right_hand_goes_around_the_left_forearm_without_a_jump():
    r = realize(load_score(two_signs("arbre", "info-about")), fps=FPS)
    pos = r.site_pos[:, r.site_names.index("WR_R")]
    start = r.score_start
    arbre_end = json.loads((EXAMPLES / "arbre.json").read_text())["root"]["end"]
    moves = [
        m
        for m in mv.movements(pos, FPS)
        if r.time[m.first] <= start + arbre_end + 0.3 <= r.time[m.last]
    ]
    assert len(moves) == 1
    m = moves[0]
    assert m.peak_speed < 3.0  # the human range; stopped at the forearm and thrown past, 3.8
    sel = slice(m.first, m.last + 1)
    path = np.linalg.norm(np.diff(pos[sel], axis=0), axis=1).sum()
    net = np.linalg.norm(pos[m.last] - pos[m.first])
    assert path < 1.25 * net  # around the forearm, not stopped at it and thrown past it
    m_ = load_model()
    names = [mujoco.mj_id2name(m_, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(m_.njnt)]
    arm = [m_.jnt_qposadr[j] for j, n in enumerate(names) if n.startswith(("arm_R", "f_arm_R"))]
    jump = np.abs(np.diff(r.qpos[sel][:, arm], axis=0)).max()
    assert jump < np.radians(10.0)


@pytest.fixture(scope="module")
def sentence():
    """The 10-sign sentence of the benchmarks, realized: (score, rollout)."""
    five = ["bien", "pointing", "arbre", "info-about", "penser"]
    score = load_score(signs(*(five * 2)))
    return score, realize(score, fps=FPS)


def leaving(sentence, sign: str, wrist: str) -> mv.Movement:
    """The one movement of ``wrist`` under way 0.02 s after the sentence's block ``sign``
    ends."""
    score, r = sentence
    pos = r.site_pos[:, r.site_names.index(wrist)]
    leave = r.score_start + next(b.end for b in score.blocks() if b.path.endswith(sign)) + 0.02
    moves = [m for m in mv.movements(pos, FPS) if r.time[m.first] <= leave <= r.time[m.last]]
    assert len(moves) == 1
    return moves[0]


def net_move(sentence, m: mv.Movement, wrist: str) -> float:
    """How far [m] ``wrist`` is from where it started at the end of movement ``m``."""
    _, r = sentence
    pos = r.site_pos[:, r.site_names.index(wrist)]
    return float(np.linalg.norm(pos[m.last] - pos[m.first]))


def test_leaving_the_second_arbre_the_left_hand_goes_around_in_one_movement(sentence):
    # Leaving the sentence's second arbre (the right elbow on the back of the left hand)
    # for info-about, the straight blend of the left arm goes through the right forearm;
    # the first bend, through vias on different sides of it, zig-zagged: 3 speed peaks up
    # to 2.89 m/s over 608 mm of path for 235 mm of net move, 2.6 times the left
    # shoulder's torque limit. The shorter bend is kept.
    m = leaving(sentence, "S7_ARBRE", "WR_L")
    assert m.peaks == 1
    assert m.peak_speed < 2.0
    assert m.path_length < 1.5 * net_move(sentence, m, "WR_L")


def test_leaving_the_first_arbre_the_left_hand_goes_around_in_one_bell(sentence):
    # The same move out of the first arbre: every bend and retry zig-zagged (3 speed
    # peaks, 370 mm of path for 240 mm, the hand turned 114 degrees and back); one bell
    # grown around the right forearm goes around it in one curve.
    m = leaving(sentence, "S2_ARBRE", "WR_L")
    assert m.peaks == 1
    assert m.sparc >= -1.45
    assert m.path_length < 1.5 * net_move(sentence, m, "WR_L")


def test_leaving_the_temple_the_hand_goes_to_bien_in_one_bell(sentence):
    # Leaving penser's temple, the curling index grazes the head in the first frames; the
    # bend reached there in a few frames, a speed peak of its own.
    m = leaving(sentence, "S4_PENSER", "WR_R")
    assert m.peaks == 1
    assert m.sparc >= -1.45


@pytest.mark.parametrize(
    "candidate, kept, replaces",
    [
        ((2, 0.90), (2, 1.00), True),  # as many peaks, clearly shorter
        ((2, 0.97), (2, 1.00), False),  # as many peaks, about as long
        ((1, 1.04), (3, 1.00), True),  # fewer peaks, about as long
        ((1, 1.10), (3, 1.00), False),  # fewer peaks, clearly longer
        ((2, 0.80), (1, 1.00), True),  # clearly shorter: pacing may make it one bell
        ((3, 0.97), (1, 1.00), False),
    ],
)
def test_a_bend_replaces_another_when_shorter_or_as_long_with_fewer_peaks(
    candidate, kept, replaces
):
    assert dt.better(candidate, kept) is replaces


def test_a_rushed_first_bend_is_never_kept():
    """A first bend that moves the wrist faster than the human range (where the straight
    blend did not) gives way to an alternative that is not rushed, or to none."""
    solver = make_solver()
    detour = dt.Detour(IKAdapter(Schedule(load_score(two_signs("arbre", "info-about")), solver)))
    d = detour.schedule.track_dofs["arm_R"]
    times = np.arange(21) / FPS
    qa = solver.natural.copy()
    qb = qa.copy()
    qb[d[2]] += 0.6  # shoulder flexion: a slow reach, out of the body
    u = minjerk(np.linspace(0.0, 1.0, len(times)))
    run = qa + u[:, None] * (qb - qa)
    calm = run[:, d]
    assert not detour.rushed(run, calm, d, "arm_R", times)
    assert detour.shortest(run, times, "arm_R", calm) is calm  # one bell: kept
    zigzag = calm.copy()
    zigzag[1:-1:2, 2] += 0.5  # the shoulder thrown back and forth every other frame
    assert detour.rushed(run, zigzag, d, "arm_R", times)
    kept = detour.shortest(run, times, "arm_R", zigzag)
    assert kept is not zigzag
    assert kept is None or not detour.rushed(run, kept, d, "arm_R", times)
