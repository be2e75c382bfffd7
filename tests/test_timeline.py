"""The realizer on the real signer: schedule, each block and constraint kind, motion."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import mujoco
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scores import cstr, envelope, sync

from azee_mj import timeline
from azee_mj.check import check_poses
from azee_mj.ikadapter import IKAdapter
from azee_mj.keyposes import KeyPoser
from azee_mj.schedule import FramePairs, Mode, Schedule, contact_pairs, make_solver
from azee_mj.score import load_score
from azee_mj.sites import DEFAULT_MAP
from azee_mj.timing import frame_range

DATA = Path(__file__).parent / "data"


@pytest.fixture(scope="module")
def kinds(solver) -> timeline.Rollout:
    return timeline.realize(DATA / "kinds.json", solver=solver)


def _dofs(solver, track):
    return [solver.model.jnt_qposadr[solver.joint_id(j)] for j in DEFAULT_MAP.tracks[track]]


def _frames(rollout, start, end):
    """Frames inside ``[start, end)`` of the score's time (the rollout's clock runs
    ``score_start`` ahead: the lead-in from rest comes first)."""
    t = rollout.time - rollout.score_start
    return np.flatnonzero((t >= start - 1e-9) & (t < end - 1e-9))


def _site(rollout, name):
    return rollout.site_pos[:, rollout.site_names.index(name)]


def test_rollout_shapes_and_time_line(kinds, solver):
    T = len(kinds.time)
    np.testing.assert_array_equal(kinds.time, np.arange(T) / 50.0)
    # the score's 3 s start on a frame, after the lead-in, and the return to rest follows
    assert kinds.score_start * 50.0 == pytest.approx(round(kinds.score_start * 50.0), abs=1e-9)
    assert kinds.time[-1] > kinds.score_start + 3.0
    assert kinds.qpos.shape == (T, solver.model.nq)
    assert kinds.site_pos.shape == (T, len(DEFAULT_MAP.sites), 3)
    assert np.all(np.isfinite(kinds.qpos))


def test_every_constraint_holds_over_its_interval(kinds):
    assert [t.block for t in kinds.traces if not t.ok] == []


def test_schedule_assigns_blocks_to_the_tracks_they_drive(kinds):
    blocks = {k: {i.block for i in v} for k, v in kinds.schedule.items()}
    assert blocks["arm_R"] == {"ALL.A", "ALL.ARC", "ALL.B", "ALL.CIRC", "ALL.C", "ALL.KEEP"}
    assert "ALL.C" in blocks["arm_L"]  # a contact drives both sides it joins
    assert blocks["hand_R"] == {"ALL.SHAPE"} and blocks["hand_L"] == {"ALL.SHAPE"}
    assert blocks["eyes"] == {"ALL.C", "ALL.KEEP"}
    assert "ALL.SHAKE" in blocks["head"]
    assert blocks["face"] == {"ALL.C", "ALL.KEEP"}


def test_no_joint_leaves_its_range_or_moves_faster_than_25_rad_s(kinds, solver):
    m = solver.model
    q = kinds.qpos[:, m.jnt_qposadr]
    assert np.all(q >= m.jnt_range[:, 0] - 1e-9) and np.all(q <= m.jnt_range[:, 1] + 1e-9)
    hinge = m.jnt_type == mujoco.mjtJoint.mjJNT_HINGE
    speed = np.abs(np.diff(q[:, hinge], axis=0)) * kinds.fps
    assert speed.max() < 25.0


def test_no_penetration_at_any_frame(kinds, solver):
    allowed = contact_pairs(DATA / "kinds.json", kinds.time, score_start=kinds.score_start)
    report = check_poses(solver.model, kinds.qpos, allowed=allowed)
    assert report.clean, report.penetrations[:3]


def test_contact_pairs_answer_each_frame_as_its_contact_windows_say(solver):
    score = load_score(DATA / "kinds.json")
    fps, start, n = 50.0, 0.36, 400
    times = np.arange(n) / fps
    allowed = contact_pairs(score, times, solver, start)
    sched, lead = Schedule(score, solver), round(start * fps)
    table: dict[int, set] = {}
    for w in sched.contacts:
        assert all((b, a) in w.pairs for a, b in w.pairs)  # both orders
        for f in frame_range(w.start, w.end, fps, n - lead):
            table.setdefault(f + lead, set()).update(
                (sched.body_names[a], sched.body_names[b]) for a, b in w.pairs if a < b
            )
    assert table and dict(allowed) == table and len(allowed) == len(table)
    assert all(allowed.get(f, frozenset()) == table.get(f, set()) for f in range(-2, n + 2))


def test_frame_pairs_join_overlapping_spans_and_know_no_other_frame():
    ab, cd = frozenset({("a", "b")}), frozenset({("c", "d")})
    pairs = FramePairs({(0, 10): ab, (5, 15): cd, (20, 20): cd})
    assert [pairs[f] for f in (0, 4, 5, 9, 10, 14)] == [ab, ab, ab | cd, ab | cd, cd, cd]
    assert list(pairs) == list(range(15)) and len(pairs) == 15
    assert pairs.get(15) is None and pairs.get(-1) is None and pairs.get("5") is None
    assert pairs == {f: (ab if f < 5 else ab | cd if f < 10 else cd) for f in range(15)}


def test_morphs_set_the_hand_shapes(kinds, solver):
    m = solver.model
    f = _frames(kinds, 0.0, 3.0)
    fist = DEFAULT_MAP.morphs["fist"].joint_changes("L")
    for j, v in fist.items():
        adr = m.jnt_qposadr[solver.joint_id(j)]
        lo, hi = m.jnt_range[solver.joint_id(j)]
        np.testing.assert_allclose(kinds.qpos[f, adr], np.clip(v, lo, hi), atol=0.02)
    for j, v in DEFAULT_MAP.morphs["flat"].joint_changes("R").items():
        adr = m.jnt_qposadr[solver.joint_id(j)]
        np.testing.assert_allclose(kinds.qpos[f, adr], v, atol=0.02)


def test_face_morph_blends_in_and_out(kinds, solver):
    adr = solver.model.jnt_qposadr[solver.joint_id("brow_R_raise")]
    brow = kinds.qpos[:, adr]
    assert brow[0] == pytest.approx(0.0)
    raised = DEFAULT_MAP.morphs["brows_raise"].joint_changes("R")["brow_R_raise"]
    assert raised > 0.002
    assert brow[_frames(kinds, 2.0, 2.8)] == pytest.approx(raised, abs=2e-4)
    assert np.all(np.diff(brow[_frames(kinds, 1.4, 2.0)]) >= -1e-12)  # rises in the gap


def test_transpath_arc_stays_on_its_circle(kinds):
    f = _frames(kinds, 0.5, 0.9)
    p = _site(kinds, "M_TIP_R")[f]
    a, b = _site(kinds, "M_TIP_R")[f[0]], _site(kinds, "M_TIP_R")[_frames(kinds, 0.9, 1.0)[0]]
    # All points on one circle through both ends (the arc's), within 1 mm; the middle of the
    # arc is 5 cm above the chord's midpoint.
    centre, radius = _circle(a, p[len(p) // 2], b)
    assert np.abs(np.linalg.norm(p - centre, axis=1) - radius).max() < 1e-3
    top = (a + b) / 2 + [0.0, 0.0, 0.05]
    assert abs(np.linalg.norm(top - centre) - radius) < 1e-3


def test_transpath_circle_turns_about_its_centre(kinds, solver):
    f = _frames(kinds, 1.4, 2.0)
    p = _site(kinds, "M_TIP_R")[f]
    d = solver.data
    d.qpos[:] = kinds.qpos[f[0]]
    mujoco.mj_kinematics(solver.model, d)
    centre = d.site_xpos[solver.site_id("ssp")] + np.array([0.0, -0.08, 0.12])
    r = p - centre
    # About the fwd axis the angle sweeps more than a full turn (one turn plus the way to
    # the end point); the offset along fwd moves steadily from the start's to the end's.
    ang = np.unwrap(np.arctan2(r[:, 2], r[:, 1]))
    assert abs(ang[-1] - ang[0]) > 2 * np.pi
    dx = np.diff(r[:, 0])
    assert np.all(dx * np.sign(r[-1, 0] - r[0, 0]) >= -1e-4)


def test_site_trill_oscillates_at_its_amplitude_and_frequency(kinds):
    f = _frames(kinds, 0.9, 1.4)
    z = _site(kinds, "M_TIP_R")[f, 2]
    t = kinds.time[f] - kinds.score_start - 0.9
    fit = np.linalg.lstsq(np.c_[np.sin(2 * np.pi * 4 * t), np.ones_like(t)], z, rcond=None)[0]
    assert fit[0] == pytest.approx(0.01, rel=0.15)


def test_bone_trill_shakes_the_head(kinds, solver):
    d, yaw = solver.data, []
    for f in _frames(kinds, 0.3, 1.1):
        d.qpos[:] = kinds.qpos[f]
        mujoco.mj_kinematics(solver.model, d)
        face = d.xmat[solver.body_id("head")].reshape(3, 3) @ np.asarray(
            DEFAULT_MAP.bones["head"].nrm
        )
        yaw.append(np.degrees(np.arctan2(face[1], face[0])))
    assert max(yaw) - min(yaw) == pytest.approx(2 * 8.0, rel=0.1)  # excursion 2A


def test_look_points_both_eyes_at_the_target(kinds, solver):
    f = _frames(kinds, 2.0, 2.4)[-1]
    d = solver.data
    d.qpos[:] = kinds.qpos[f]
    mujoco.mj_kinematics(solver.model, d)
    target = d.site_xpos[solver.site_id("ssp")] + np.array([0.1, 0.0, 0.3])
    for eye in ("eye_L", "eye_R"):
        b = solver.body_id(eye)
        gaze = d.xmat[b].reshape(3, 3) @ np.asarray(DEFAULT_MAP.bones[eye].dir)
        want = (target - d.xpos[b]) / np.linalg.norm(target - d.xpos[b])
        assert np.degrees(np.arccos(np.clip(gaze @ want, -1, 1))) < 1.0


def test_hold_keeps_what_the_block_reached(kinds, solver):
    end_c = kinds.qpos[_frames(kinds, 2.0, 2.4)[-1]]
    for f in _frames(kinds, 2.4, 2.8):
        for track in ("arm_R", "arm_L", "eyes"):
            np.testing.assert_allclose(
                kinds.qpos[f, _dofs(solver, track)], end_c[_dofs(solver, track)], atol=0.02
            )


def _two_track_score():
    return envelope(
        sync(
            "TWO",
            2.0,
            cstr(
                "STILL",
                0,
                2.0,
                {
                    "type": "place",
                    "site": "@PA(w)",
                    "at": {"translate": "^ssp", "by": [0, 0.1, -0.05]},
                },
                {
                    "type": "orient",
                    "bone": "!palm(w)",
                    "axis": "nrm",
                    "rel": "along",
                    "vector": "up",
                },
            ),
            cstr(
                "K1",
                0.2,
                0.6,
                {
                    "type": "place",
                    "site": "@I_TIP(s)",
                    "at": {"translate": "^Rssp", "by": [0, 0, 0.2]},
                },
            ),
            cstr(
                "K2",
                1.2,
                1.6,
                {
                    "type": "place",
                    "site": "@I_TIP(s)",
                    "at": {"translate": "^ssp", "by": [0, -0.05, 0.25]},
                },
            ),
        )
    )


def test_one_hand_moves_while_the_other_holds_still(solver):
    multi = timeline.realize(_two_track_score(), solver=solver)
    # STILL holds the left arm over the whole score: still from the score's start to its
    # end (it comes from rest before and returns to rest after)
    left = multi.qpos[_frames(multi, 0.0, 2.0)][:, _dofs(solver, "arm_L")]
    assert np.abs(left - left[0]).max() < 1e-9
    right = multi.qpos[:, _dofs(solver, "arm_R")]
    assert np.abs(np.diff(right, axis=0)).max() > 0.01
    # The right hand keeps moving through the left block's (absent) keys: no stop at 0.6 s
    # other than its own.
    assert all(t.ok for t in multi.traces)


def test_placement_relative_to_the_other_hand_moves_both_hands(solver):
    # The strong tip placed beside the weak one (a point riding on the weak arm): both arms
    # are one problem, and their index tips may touch; the forehead-relative point of the
    # weak tip does not move the head.
    beside = {"translate": "@I_TIP(w)", "by": {"scale": "lat(s)", "by": 0.0136}}
    score = envelope(
        cstr(
            "TOP",
            0,
            0.6,
            {"type": "morph", "id": "flat", "weight": 1.0, "side": "s"},
            {"type": "morph", "id": "flat", "weight": 1.0, "side": "w"},
            {
                "type": "place",
                "site": "@I_TIP(w)",
                "at": {"translate": "@FH", "by": {"scale": "fwd", "by": 0.2}},
            },
            {"type": "place", "site": "@I_TIP(s)", "at": beside},
            {"type": "orient", "bone": "!palm(s)", "axis": "nrm", "rel": "along", "vector": "down"},
            {"type": "orient", "bone": "!palm(w)", "axis": "nrm", "rel": "along", "vector": "down"},
        )
    )
    rollout = timeline.realize(score, solver=solver)
    tracks = {k for k, v in rollout.schedule.items() if v}
    assert {"arm_R", "arm_L", "hand_R", "hand_L"} <= tracks and "head" not in tracks
    assert [t.describe() for t in rollout.traces if not t.ok] == []
    inside = _frames(rollout, 0.0, 0.6)  # the block's frames, after the lead-in from rest
    last = inside[-1]
    gap = _site(rollout, "I_TIP_R")[last] - _site(rollout, "I_TIP_L")[last]
    np.testing.assert_allclose(gap, [0.0, -0.0136, 0.0], atol=1e-3)
    head = _dofs(solver, "head")
    assert np.abs(rollout.qpos[:, head] - rollout.qpos[0, head]).max() == 0.0
    allowed = contact_pairs(load_score(score), rollout.time, solver, rollout.score_start)
    assert set(allowed) == set(inside.tolist())
    # The two hands touch as parts: any body of one hand with any body of the other.
    pairs = {tuple(sorted(p)) for v in allowed.values() for p in v}
    m = solver.model
    hand = {
        s: {m.body(b).name for b in range(m.nbody) if _in_hand(m, b, f"palm_{s}")} for s in "LR"
    }
    assert pairs == {tuple(sorted((a, b))) for a in hand["L"] for b in hand["R"]}
    assert ("index_L_3", "index_R_3") in pairs


def _in_hand(m, body: int, palm: str) -> bool:
    while body > 0:
        if m.body(body).name == palm:
            return True
        body = int(m.body_parentid[body])
    return False


def test_the_head_waits_for_a_hand_held_at_the_chin(solver):
    # The thumb tip holds in front of the chin until 1.0 s and the head turns right from
    # 1.1 s: the head's blend, which would start 0.6 s ahead, waits for the hold to end.
    at_chin = {"translate": "@CH", "by": {"scale": "fwd", "by": 0.06}}
    turn = {
        "type": "orient",
        "bone": "!head",
        "axis": "nrm",
        "rel": "along",
        "vector": [1.0, -0.6, 0.0],
    }
    score = envelope(
        sync(
            "S",
            1.6,
            cstr("K", 0.2, 1.0, {"type": "place", "site": "@T_TIP(s)", "at": at_chin}),
            cstr("TURN", 1.1, 1.6, turn),
        )
    )
    rollout = timeline.realize(score, solver=solver)
    head = _dofs(solver, "head")
    held, turn = _frames(rollout, 0.0, 1.0), _frames(rollout, 1.0, 1.1)
    # the head stays at rest until the hand leaves the chin, then turns (its lead-in
    # starts no earlier than that)
    assert np.abs(rollout.qpos[held][:, head] - rollout.qpos[0, head]).max() == 0.0
    assert np.abs(rollout.qpos[turn[-1], head] - rollout.qpos[0, head]).max() > 0.2
    assert [t.describe() for t in rollout.traces if not t.ok] == []


def test_flattened_mode_jerks_a_track_at_another_tracks_key(solver):
    score = _two_track_score()
    score["root"]["children"].append(
        {
            "name": "BROWS",
            "kind": "cstr",
            "start": 0.85,
            "end": 1.0,
            "constraints": [{"type": "morph", "id": "brows_raise", "weight": 1.0}],
        }
    )
    flat = timeline.realize(score, solver=solver, mode="flattened")
    multi = timeline.realize(score, solver=solver)
    arm = _dofs(solver, "arm_R")
    speed = lambda r: np.abs(np.diff(r.qpos[:, arm], axis=0)).max(axis=1) * r.fps
    # Multitrack: the right arm blends K1 -> K2 straight through the brows' key at 0.85 s.
    # Flattened: every key is a whole-body posture, so the arm waits for the brows' keys and
    # then hurries: a jerk caused by a block on another track.
    during = _frames(multi, 0.6, 1.2)
    assert speed(multi)[during[:-1]].min() > 0.0
    assert speed(flat).max() > 1.5 * speed(multi).max()
    head = _dofs(solver, "head")
    assert np.abs(multi.qpos[:, head] - multi.qpos[0, head]).max() == 0.0


def _mirror_site(name: str) -> str:
    parts = name.split("_")
    for i in range(len(parts) - 1, 0, -1):
        if parts[i] in ("L", "R"):
            parts[i] = {"L": "R", "R": "L"}[parts[i]]
            return "_".join(parts)
    return name


def test_mirrored_score_mirrors_the_signing(solver):
    score = json.loads((DATA / "good.json").read_text())
    right = timeline.realize(score, solver=solver)
    score["strong_side"] = "L"
    left = timeline.realize(score, solver=solver)
    idx = [right.site_names.index(_mirror_site(n)) for n in left.site_names]
    mirrored = right.site_pos[:, idx] * np.array([1.0, -1.0, 1.0])
    assert np.abs(left.site_pos - mirrored).max() < 1e-3


def test_golden_rollout(solver):
    """tests/data/good_golden.npz holds the expected rollout of good.json; regenerate with
    ``python -c "from tests.test_timeline import write_golden; write_golden()"`` after an
    intended change, and say why in the commit."""
    golden = np.load(DATA / "good_golden.npz")
    r = timeline.realize(DATA / "good.json", solver=make_solver(seed=0))
    np.testing.assert_array_equal(r.time, golden["time"])
    # Same posture to 1 mm at every site (solver round-off and restarts aside).
    assert np.abs(r.site_pos - golden["site_pos"]).max() < 1e-3


def write_golden():
    r = timeline.realize(DATA / "good.json", solver=make_solver(seed=0))
    np.savez_compressed(DATA / "good_golden.npz", time=r.time, qpos=r.qpos, site_pos=r.site_pos)


def _circle(a, b, c):
    ab, ac = b - a, c - a
    n = np.cross(ab, ac)
    cc = a + (np.cross(n, ab) * (ac @ ac) + np.cross(ac, n) * (ab @ ab)) / (2 * (n @ n))
    return cc, np.linalg.norm(a - cc)


# --- schedule properties ---------------------------------------------------------------

_TRACK_CONSTRAINTS = {
    "arm_R": {
        "type": "place",
        "site": "@I_TIP(R)",
        "at": {"translate": "^Rssp", "by": [0, 0, 0.1]},
    },
    "arm_L": {
        "type": "place",
        "site": "@I_TIP(L)",
        "at": {"translate": "^Lssp", "by": [0, 0, 0.1]},
    },
    "face": {"type": "morph", "id": "jaw_open", "weight": 0.5},
    "hand_R": {"type": "morph", "id": "fist", "side": "R", "weight": 1.0},
}


@st.composite
def _blocks(draw, depth=0, steps=40, prefix="B"):
    """Blocks on a grid of 0.05 s inside a parent of ``steps`` grid steps."""
    n = draw(st.integers(1, 3))
    out = []
    for i in range(n):
        ia = draw(st.integers(0, steps - 2))
        ib = draw(st.integers(ia + 2, steps))
        a, b = ia * 0.05, ib * 0.05
        name = f"{prefix}{i}"
        if depth < 2 and ib - ia >= 6 and draw(st.booleans()):
            kids = draw(_blocks(depth + 1, ib - ia, name + "_"))
            out.append({"name": name, "kind": "sync", "start": a, "end": b, "children": kids})
        else:
            track = draw(st.sampled_from(sorted(_TRACK_CONSTRAINTS)))
            out.append(
                {
                    "name": name,
                    "kind": "cstr",
                    "start": a,
                    "end": b,
                    "constraints": [copy.deepcopy(_TRACK_CONSTRAINTS[track])],
                }
            )
    return out


@settings(
    max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(_blocks())
def test_schedule_intervals_lie_within_their_parents(solver, children):
    score = load_score(
        {
            "format": "azee-score",
            "version": 1,
            "root": {"name": "R", "kind": "sync", "start": 0, "end": 2.0, "children": children},
        }
    )
    schedule = Schedule(score, solver)
    sched = schedule.intervals()
    parents = {c.path: b for b in score.blocks() for c in b.children}
    for track, intervals in sched.items():
        for iv in intervals:
            block = score.block(iv.block)
            assert (iv.start, iv.end) == (block.start, block.end)
            p = parents.get(iv.block)
            while p is not None:
                assert p.start - 1e-9 <= iv.start and iv.end <= p.end + 1e-9
                p = parents.get(p.path)
            assert track in set().union(*(schedule.comp.tracks_of(c) for c in block.constraints))
    # Keys of a track exactly cover the union of its blocks' intervals (in time order).
    keys = KeyPoser(IKAdapter(schedule), Mode.MULTITRACK).key_postures()
    for track, intervals in sched.items():
        covered = sorted((k.start, k.end) for k in keys[track])
        assert covered == sorted(set(covered))
        for iv in intervals:
            inside = [k for k in covered if iv.start - 1e-9 <= k[0] and k[1] <= iv.end + 1e-9]
            assert inside and inside[0][0] == pytest.approx(iv.start)
            assert inside[-1][1] == pytest.approx(iv.end)


def test_a_pinch_lets_only_its_two_phalanges_touch(solver):
    """Two digits of one hand: only the thumb's and the index's tip phalanges may touch,
    not the rest of the hand with itself."""
    score = envelope(
        sync(
            "C", 0.8, cstr("K", 0.4, 0.8, {"type": "place", "site": "@T_TIP(s)", "at": "@I_TIP(s)"})
        )
    )
    times = np.arange(41) / 50.0
    allowed = contact_pairs(load_score(score), times, solver)
    pairs = {tuple(sorted(p)) for v in allowed.values() for p in v}
    assert pairs == {("index_R_3", "thumb_R_3")}
