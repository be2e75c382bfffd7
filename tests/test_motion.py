"""Motion a signer makes (pass 2 with rest): the lead-in from rest before the score, the
return to rest after, no clamp on the speed a score's timing needs (a finding instead),
tempo, and the rollout file keeping the score's start and the findings."""

import json
from pathlib import Path

import numpy as np
import pytest
from scores import cstr, envelope, sync

from azee_mj import movement as mv
from azee_mj import timeline
from azee_mj.blend import MIN_LEAD, REST_HOLD, REST_SPEED
from azee_mj.cli import main
from azee_mj.rollout_io import load_rollout, save_rollout
from azee_mj.schedule import make_solver
from azee_mj.score import load_score
from azee_mj.sites import DEFAULT_MAP

DATA = Path(__file__).parent / "data"
GOOD = DATA / "good.json"


@pytest.fixture(scope="module")
def solver():
    return make_solver(seed=0)


@pytest.fixture(scope="module")
def good(solver):
    return timeline.realize(GOOD, solver=solver)


def _wrist_moves(r, site="WR_R"):
    pos = r.site_pos[:, r.site_names.index(site)]
    return [(m, r.time[m.first], r.time[m.last]) for m in mv.movements(pos, r.fps)]


def test_the_lead_in_comes_from_rest_before_the_score_at_a_human_speed(good, solver):
    np.testing.assert_allclose(good.qpos[0], solver.natural)  # rest
    assert good.score_start >= MIN_LEAD
    assert good.score_start * good.fps == pytest.approx(round(good.score_start * good.fps))
    lead = [m for m, t0, t1 in _wrist_moves(good) if t1 <= good.score_start + 0.04]
    assert len(lead) == 1
    # one bell: a single peak sized for REST_SPEED, smooth as minimum jerk
    assert lead[0].peaks == 1 and lead[0].peak_speed < 1.15 * REST_SPEED
    assert -1.6 <= lead[0].sparc <= -1.35


def test_the_blocks_keep_their_time_on_the_rollouts_clock(good, solver):
    plain = timeline.realize(GOOD, solver=solver, rest=False)
    assert plain.score_start == 0.0 and len(plain.time) == round(1.2 * 50) + 1
    moved = {
        t: [(i.block, i.start - good.score_start, i.end - good.score_start) for i in v]
        for t, v in good.schedule.items()
    }
    same = {t: [(i.block, i.start, i.end) for i in v] for t, v in plain.schedule.items()}
    assert moved.keys() == same.keys()
    for t, ivs in same.items():
        np.testing.assert_allclose([x[1:] for x in moved[t]], [x[1:] for x in ivs])
    assert all(t.ok for t in good.traces) and all(t.ok for t in plain.traces)
    # without rest each track starts in its first posture: no lead-in movement
    assert not [m for m, t0, t1 in _wrist_moves(plain) if t0 < 0.01]


def test_every_track_returns_to_rest_after_a_hold(good, solver):
    np.testing.assert_allclose(good.qpos[-1], solver.natural, atol=1e-9)
    end = good.score_start + 1.2
    # still for the hold after the last block, then one smooth return
    still = (good.time >= end) & (good.time < end + REST_HOLD - 1e-9)
    q = good.qpos[still]
    assert np.abs(q - q[0]).max() < 1e-9
    back = [m for m, t0, t1 in _wrist_moves(good) if t0 >= end]
    assert len(back) == 1 and back[0].peaks == 1 and back[0].peak_speed < 3.0
    assert -1.6 <= back[0].sparc <= -1.35


def _beside(side: str) -> dict:
    """25 cm in front of the signing space, 15 cm to ``side``."""
    by = {"add": [{"scale": "fwd", "by": 0.25}, {"scale": side, "by": 0.15}]}
    return {"translate": "^ssp", "by": by}


def test_a_hand_with_no_further_block_relaxes(solver):
    weak = {"type": "place", "site": "@WR(w)", "at": _beside("lat(w)")}
    strong = {"type": "place", "site": "@WR(s)", "at": _beside("lat(s)")}
    score = envelope(sync("S", 3.0, cstr("WEAK", 0.2, 0.6, weak), cstr("STRONG", 0.2, 3.0, strong)))
    r = timeline.realize(score, solver=solver)
    arm = [solver.model.jnt_qposadr[solver.joint_id(j)] for j in DEFAULT_MAP.tracks["arm_L"]]
    at = round((r.score_start + 2.9) * r.fps)  # the strong hand still signs: the weak rests
    np.testing.assert_allclose(r.qpos[at, arm], solver.natural[arm], atol=1e-9)
    assert all(t.ok for t in r.traces)


def test_a_hand_whose_next_block_is_far_pauses_at_rest_and_meets_it(solver):
    weak = {"type": "place", "site": "@WR(w)", "at": _beside("lat(w)")}
    strong = {"type": "place", "site": "@WR(s)", "at": _beside("lat(s)")}
    blocks = cstr("W1", 0.2, 0.6, weak), cstr("W2", 3.4, 3.8, weak), cstr("S", 0.2, 4.0, strong)
    score = envelope(sync("S", 4.0, *blocks))
    r = timeline.realize(score, solver=solver)
    arm = [solver.model.jnt_qposadr[solver.joint_id(j)] for j in DEFAULT_MAP.tracks["arm_L"]]
    mid = round((r.score_start + 2.0) * r.fps)  # halfway through the 2.8 s gap: at rest
    np.testing.assert_allclose(r.qpos[mid, arm], solver.natural[arm], atol=1e-9)
    assert all(t.ok for t in r.traces)  # both weak blocks met, at their times
    spans = {i.block: (i.start - r.score_start, i.end - r.score_start) for i in r.schedule["arm_L"]}
    assert spans["S.W2"] == pytest.approx((3.4, 3.8))
    # the return and the lead-in back: each one bell at a human speed
    moves = [m for m, t0, t1 in _wrist_moves(r, "WR_L") if 0.6 < t0 - r.score_start < 3.4]
    assert len(moves) == 2
    for m in moves:
        assert m.peaks == 1 and m.peak_speed <= 3.0 and -1.6 <= m.sparc <= -1.35
    # a threshold above the gap: the hand holds its posture through it, as before
    held = timeline.realize(score, solver=solver, rest_gap=3.0)
    assert np.abs(held.qpos[mid, arm] - solver.natural[arm]).max() > 0.1
    assert all(t.ok for t in held.traces)


def test_tempo_scales_the_scores_time(solver):
    slow = timeline.realize(GOOD, solver=solver, tempo=0.5)
    spans = {
        i.block: (i.start - slow.score_start, i.end - slow.score_start)
        for v in slow.schedule.values()
        for i in v
    }
    k2 = load_score(GOOD).block("GOOD.K2")
    assert spans["GOOD.K2"] == pytest.approx((2 * k2.start, 2 * k2.end))  # at half speed
    with pytest.raises(Exception, match="tempo must be a number from 0.1 to 10"):
        timeline.realize(GOOD, solver=solver, tempo=0.0)


def test_a_jump_the_score_times_is_a_speed_finding_and_strict_fails(solver, tmp_path, capsys):
    r = timeline.realize(DATA / "high_at_zero.json", solver=solver)
    found = [f for f in r.findings if f.kind == "speed"]
    assert found and {f.block for f in found} == {"HIGH_AT_ZERO.DOWN"}
    assert max(f.value for f in found if f.unit == "m/s") > 3.0
    assert all(t.ok for t in r.traces)  # no constraint gives way to the speed
    path = tmp_path / "r.npz"
    save_rollout(path, r)
    back = load_rollout(path, solver.model.nq)
    assert back.score_start == r.score_start and back.findings == r.findings
    out = str(tmp_path / "s.npz")
    assert main(["realize", str(DATA / "high_at_zero.json"), "-o", out]) == 0
    capsys.readouterr()
    assert main(["realize", str(DATA / "high_at_zero.json"), "-o", out, "--strict"]) == 1
    said = [x for x in capsys.readouterr().out.splitlines() if x.startswith("  finding: speed")]
    assert said and "finding: speed: WR_R" in said[0]
    # check says the same findings, and fails on them as realize --strict does (issue 27)
    assert main(["check", out, "--score", str(DATA / "high_at_zero.json")]) == 1
    checked = capsys.readouterr().out.splitlines()
    assert [x for x in checked if x.startswith("  finding: speed")] == said


def test_bad_motion_options_exit_2(tmp_path, capsys):
    out = str(tmp_path / "x.npz")
    assert main(["realize", str(GOOD), "-o", out, "--tempo", "0"]) == 2
    assert "--tempo must be a number from 0.1 to 10, got 0" in capsys.readouterr().err
    assert main(["realize", str(GOOD), "-o", out, "--rest-hold", "-1"]) == 2
    capsys.readouterr()
    assert main(["realize", str(GOOD), "-o", out, "--rest-gap", "-1"]) == 2
    said = "--rest-gap must be a number of seconds from 0 (inf: never), got -1"
    assert said in capsys.readouterr().err
    with pytest.raises(Exception, match="the rest gap must be a number of seconds from 0"):
        timeline.realize(GOOD, rest_gap=float("nan"))
    assert not Path(out).exists()


def test_a_two_handed_transition_is_paced_into_one_bell_and_keeps_its_holds(solver):
    """nicht-sondern's hands go from NICHT's hold (to 2.0 s) into the two index tips'
    contact (HANDS_CONTACT from 2.3 s), pushed out of each other frame by frame: the left
    wrist had two speed peaks; paced, one for each hand, and the constraints of the
    blocks either side are still met at every frame."""
    score = load_score(Path(__file__).parents[1] / "examples" / "nicht-sondern.json")
    r = timeline.realize(score, solver=solver)
    t0, t1 = r.score_start + 2.0, r.score_start + 2.3
    for site in ("WR_L", "WR_R"):
        moves = [m for m, a, b in _wrist_moves(r, site) if a < t1 and b > t0]
        assert len(moves) == 1 and moves[0].peaks == 1, site
    for tr in r.traces:
        if tr.block.endswith(("NICHT.GROUND", "NICHT.TRUNK", "HANDS_CONTACT")):
            assert np.all(np.asarray(tr.active) <= tr.tol), tr.block


def test_a_hold_keeps_the_trunk_and_the_next_movement_is_one_bell(solver):
    """info-about holds its topic (TOPIC_HOLD, 0.9 to 1.2 s of the score) with the trunk
    the topic recruited; the trunk used to relax during the hold, so the held strong wrist
    drifted, then moved again to the first key (K1 at 1.5 s): one movement with two speed
    peaks. The trunk now stays still through the hold and relaxes with the arm's next
    movement: one bell."""
    score = load_score(Path(__file__).parents[1] / "examples" / "info-about.json")
    r = timeline.realize(score, solver=solver)
    spine = [solver.model.joint(j).qposadr[0] for j in DEFAULT_MAP.tracks["spine"]]
    held = (r.time >= r.score_start + 0.9 - 1e-9) & (r.time < r.score_start + 1.2 - 1e-6)
    assert np.abs(np.diff(r.qpos[held][:, spine], axis=0)).max() < 1e-9
    t0, t1 = r.score_start + 0.9, r.score_start + 1.5
    moves = [m for m, a, b in _wrist_moves(r, "WR_R") if a < t1 and b > t0]
    assert len(moves) == 1 and moves[0].peaks == 1
    # it starts when the hold ends
    assert r.time[moves[0].first] >= r.score_start + 1.2 - 0.04


def _sentence(names: list[str]) -> dict:
    """The examples ``names`` chained 0.1 s apart (``bench/realize.py``'s sentence)."""
    children, t = [], 0.0
    for i, n in enumerate(names):
        root = json.loads((Path(__file__).parents[1] / "examples" / f"{n}.json").read_text())[
            "root"
        ]
        d = root["end"] - root["start"]
        children.append({**root, "name": f"S{i}_{root['name']}", "start": t, "end": t + d})
        t += d + 0.1
    root = {"name": "SENTENCE", "kind": "sync", "start": 0.0, "end": t, "children": children}
    return {"format": "azee-score", "version": 1, "strong_side": "R", "root": root}


def test_a_detour_paced_is_one_bell_when_its_smoothed_corner_pushed_out_is_not(solver):
    """The 10-sign sentence's weak hand leaving the second info-about for penser (11.06 to
    11.72 s of the score) goes around the body by a bend near its end. Pacing its path
    smoothed cut the bend's corner into the body, and the frames pushed out frame by frame
    left three speed peaks; the bend's own path, paced, is one bell, and is now kept."""
    signs = ["bien", "pointing", "arbre", "info-about", "penser"] * 2
    r = timeline.realize(load_score(_sentence(signs)), solver=solver)
    t0, t1 = r.score_start + 11.2, r.score_start + 11.5
    moves = [m for m, a, b in _wrist_moves(r, "WR_L") if a < t1 and b > t0]
    assert len(moves) == 1 and moves[0].peaks == 1
    assert moves[0].sparc >= -1.45


def test_a_bend_around_the_body_keeps_every_frame_within_the_joint_ranges(solver):
    # apart-cross's return to rest: the right clavicle, held at its bound in the crossed
    # key, was bent 2.6 mrad past it by the detour's curve
    path = Path(__file__).resolve().parent.parent / "bench/data/motion/apart-cross.json"
    r = timeline.realize(load_score(json.loads(path.read_text())), solver=solver)
    q = np.asarray(r.qpos)
    assert (q >= solver.lower).all() and (q <= solver.upper).all()


def test_a_trunk_recruited_for_the_first_sign_leans_in_with_the_arms(solver):
    """Both flat hands far forward: the trunk helps from the first key. It came from rest
    in 0.3 s (its own lean's time) while the arms took 1.03 s, so each wrist's lead-in
    had two speed peaks (SPARC -1.72); the trunk now takes the arms' lead-in: one bell,
    the trunk and both arms starting together."""
    far = {"add": [{"scale": "fwd", "by": 0.62}, {"scale": "lat(s)", "by": 0.12}]}
    far_w = {"add": [{"scale": "fwd", "by": 0.62}, {"scale": "lat(w)", "by": 0.12}]}
    score = envelope(
        sync(
            "REACH",
            0.8,
            cstr(
                "SHAPE",
                0.2,
                0.8,
                {"type": "morph", "id": "flat", "weight": 1.0, "side": "s"},
                {"type": "morph", "id": "flat", "weight": 1.0, "side": "w"},
            ),
            cstr(
                "FAR",
                0.2,
                0.8,
                {"type": "place", "site": "@PA(s)", "at": {"translate": "@AB", "by": far}},
                {"type": "place", "site": "@PA(w)", "at": {"translate": "@AB", "by": far_w}},
            ),
        )
    )
    r = timeline.realize(load_score(score), solver=solver)
    spine = [solver.model.joint(j).qposadr[0] for j in DEFAULT_MAP.tracks["spine"]]
    lead = r.time < r.score_start + 0.2
    assert np.abs(r.qpos[-1, spine] - r.qpos[0, spine]).max() < 1e-9  # back at rest
    assert np.abs(r.qpos[lead][:, spine] - r.qpos[0, spine]).max(axis=1)[1] > 0.0  # leaning
    for wrist in ("WR_R", "WR_L"):
        moves = [m for m, a, b in _wrist_moves(r, wrist) if a < r.score_start + 0.2]
        assert len(moves) == 1 and moves[0].peaks == 1
        assert -1.6 <= moves[0].sparc <= -1.35
