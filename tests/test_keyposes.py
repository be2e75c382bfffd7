"""Pass 1 pieces: components, violation, and one group solved on the real signer."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scores import cstr, envelope, shaped

from azee_mj import ik
from azee_mj.ergonomics import ergonomics
from azee_mj.ikadapter import IKAdapter
from azee_mj.keyposes import Active, GroupPoser, KeyPoser, components, solve_order, violation
from azee_mj.preferences import ELBOW_RAISED
from azee_mj.schedule import DrivenConstraint, Mode, Schedule
from azee_mj.score import load_score
from azee_mj.sites import DEFAULT_MAP

ROOT = Path(__file__).resolve().parents[1]


def _score(constraints, end=0.5):
    return load_score(envelope(cstr("K", 0.0, end, *constraints)))


def test_components_join_the_track_sets_that_share_a_track():
    groups = components([{"arm_R"}, {"hand_R"}, {"arm_L", "arm_R"}, {"head"}, {"head", "eyes"}])
    assert sorted(map(sorted, groups)) == [["arm_L", "arm_R"], ["eyes", "head"], ["hand_R"]]
    assert components([]) == []


def test_solve_order_puts_a_group_before_the_groups_whose_targets_it_moves():
    def item(tracks, con):
        return Active(DrivenConstraint(con, {}, set(tracks), None), True)

    # the head's constraint names a body the spine moves; the hand's a body the head moves
    moves = {"look": frozenset({"spine", "head"}), "touch": frozenset({"head", "arm_R"})}
    items = [item({"head"}, "look"), item({"arm_R"}, "touch"), item({"spine"}, None)]
    groups = [{"arm_R"}, {"head"}, {"spine"}]
    assert solve_order(groups, items, moves.get) == [{"spine"}, {"head"}, {"arm_R"}]
    # nothing named: hands and the face first, then the groups driven by morphs only
    morph_only = [item({"hand_R"}, None), item({"spine"}, None), item({"arm_L"}, "x")]
    order = solve_order([{"spine"}, {"arm_L"}, {"hand_R"}], morph_only, lambda c: frozenset())
    assert order == [{"hand_R"}, {"spine"}, {"arm_L"}]


def test_violation_sums_the_missed_tolerances_and_the_penetration():
    def res(values, penetration=0.0):
        residuals = tuple(ik.Residual(f"c{i}", "place", v, 1e-3, "m") for i, v in enumerate(values))
        return ik.IKResult(np.zeros(1), False, residuals, penetration, 0, 0, 0.0, np.zeros(0))

    assert violation(res([5e-4])) == 0.0  # met
    assert violation(res([3e-3, 5e-4])) == pytest.approx(3.0)
    assert violation(res([2e-3], penetration=5e-4)) == pytest.approx(2.5)


def test_a_group_solve_meets_its_placement_on_the_signer(solver):
    target = [0.3, -0.15, 1.2]
    score = _score([{"type": "place", "site": "@I_TIP(s)", "at": target}])
    adapter = IKAdapter(Schedule(score, solver))
    poser = KeyPoser(adapter, Mode.MULTITRACK)
    keys = poser.key_postures()
    arm = keys["arm_R"]
    assert len(arm) == 1 and (arm[0].start, arm[0].end) == (0.0, 0.5)
    tip = solver.at(arm[0].q).d.site_xpos[solver.site_id("I_TIP_R")]
    assert np.linalg.norm(tip - target) <= 1e-3
    assert not keys["arm_L"] and not keys["head"]  # untouched tracks have no key
    assert poser.reasons == {}
    assert len(adapter.results) >= 1


def test_a_group_still_held_is_kept_without_a_solve(solver):
    score = _score([{"type": "place", "site": "@I_TIP(s)", "at": [0.3, -0.15, 1.2]}])
    sched = Schedule(score, solver)
    adapter = IKAdapter(sched)
    keys = KeyPoser(adapter, Mode.MULTITRACK).key_postures()
    before = len(adapter.results)
    groups = GroupPoser(adapter)
    (dc,) = sched.block_constraints(sched.blocks[0])
    state = keys["arm_R"][0].q.copy()
    kept = groups.solve({"arm_R"}, [Active(dc, False)], state, keys, 0.5)
    assert kept.converged and kept.result.iterations == 0
    np.testing.assert_array_equal(kept.qpos, state)
    assert len(adapter.results) == before


def test_a_pinch_without_a_hand_shape_bends_the_fingers_not_the_arm(solver):
    # the thumb tip on the index pad, no morph: only the hand's joints bring them together
    score = _score([{"type": "place", "site": "@T_TIP(s)", "at": "@I_PAD(s)"}])
    sched = Schedule(score, solver)
    (dc,) = sched.block_constraints(sched.blocks[0])
    assert dc.tracks == {"hand_R"}
    keys = KeyPoser(IKAdapter(sched), Mode.MULTITRACK).key_postures()
    assert not keys["arm_R"] and not keys["spine"]
    d = solver.at(keys["hand_R"][0].q).d
    gap = d.site_xpos[solver.site_id("T_TIP_R")] - d.site_xpos[solver.site_id("I_PAD_R")]
    assert np.linalg.norm(gap) <= 1e-3
    # the fingers no placement names keep their natural posture
    m, q = solver.model, keys["hand_R"][0].q
    for j in ("ring_R_1_flex", "little_R_2_flex"):
        a = m.jnt_qposadr[solver.joint_id(j)]
        assert q[a] == pytest.approx(sched.home[a], abs=0.05)


def test_a_pinch_of_two_hands_is_not_a_pinch(solver):
    score = _score([{"type": "place", "site": "@I_TIP(s)", "at": "@I_TIP(w)"}])
    sched = Schedule(score, solver)
    (dc,) = sched.block_constraints(sched.blocks[0])
    assert sched.comp.pinch_track(dc.source) is None
    assert dc.tracks == {"arm_R", "arm_L"}


#: weak-idle's contact: the strong palm in front of the chest, the weak palm on it, no
#: hand shape given.
PALMS = (
    {
        "type": "place",
        "site": "@PA(s)",
        "at": {"translate": "^ssp", "by": {"scale": "fwd", "by": 0.05}},
    },
    {"type": "place", "site": "@PA(w)", "at": "@PA(s)"},
)


def test_palms_together_without_a_hand_shape_open_the_fingers_as_little_as_they_need(solver, model):
    # the resting hands' curled fingers kept the palms 29.6 mm apart; free, they open
    sched = Schedule(_score(list(PALMS)), solver)
    tracks = [dc.tracks for dc in sched.block_constraints(sched.blocks[0])]
    assert tracks == [{"arm_R"}, {"arm_R", "arm_L", "hand_R", "hand_L"}]
    keys = KeyPoser(IKAdapter(sched), Mode.MULTITRACK).key_postures()
    q = sched.home.copy()
    for track, d in sched.track_dofs.items():
        if keys[track]:
            q[d] = keys[track][-1].q[d]
    d = solver.at(q).d
    gap = d.site_xpos[solver.site_id("PA_R")] - d.site_xpos[solver.site_id("PA_L")]
    assert np.linalg.norm(gap) <= 1e-3
    e = ergonomics(model, q)
    assert e.trunk_angle < np.deg2rad(10.0) and e.head_angle < np.deg2rad(15.0)
    assert all(e.arm(side).elbow_above_shoulder < 0.0 for side in "RL")
    # relaxed: each hand nearer its resting posture than the flat hand shape would be
    for side in "RL":
        changes = DEFAULT_MAP.morphs["flat"].joint_changes(side)
        cols = [model.jnt_qposadr[solver.joint_id(j)] for j in changes]
        flat = model.qpos0[cols] + np.array(list(changes.values()))
        home = sched.home[cols]
        assert np.abs(q[cols] - home).sum() < np.abs(flat - home).sum()


def test_a_palm_contact_keeps_the_hand_shape_a_block_over_it_gives(solver):
    flat = [{"type": "morph", "id": "flat", "weight": 1.0, "side": s} for s in "sw"]
    sched = Schedule(load_score(shaped(flat, 0.2, 0.6, *PALMS)), solver)
    touch = next(b for b in sched.blocks if b.path == "C.K")
    tracks = [dc.tracks for dc in sched.block_constraints(touch)]
    assert tracks == [{"arm_R"}, {"arm_R", "arm_L"}]
    assert sched.comp.palm_hands(touch.constraints[1]) == {"hand_R", "hand_L"}
    # a palm at a point in space touches nothing: its fingers stay as they are
    assert sched.comp.palm_hands(touch.constraints[0]) == set()


def test_a_miss_does_not_bow_the_trunk(solver):
    # an index pad on a point inside the belly: no posture meets it, leaning cannot help
    score = _score([{"type": "place", "site": "@I_PAD(s)", "at": [0.0, -0.05, 0.25]}])
    adapter = IKAdapter(Schedule(score, solver))
    poser = KeyPoser(adapter, Mode.MULTITRACK)
    keys = poser.key_postures()
    d = adapter.schedule.track_dofs["spine"]
    home = adapter.schedule.home
    for k in keys["spine"]:
        assert np.abs(k.q[d] - home[d]).max() <= np.deg2rad(5.0) + 1e-9
    assert poser.reasons  # the report still says why it missed


def _flat_contacts(solver, *placements):
    """The key postures of flat hands placed by ``placements`` ((site, at), ...) from 0.4 s
    to 0.8 s, as bench/natural.py writes a contact, checked met: (poser, the posture of
    every track's last key)."""
    sides = "sw" if any("(w)" in a for a, _ in placements) else "s"
    flat = [{"type": "morph", "id": "flat", "weight": 1.0, "side": s} for s in sides]
    touch = [{"type": "place", "site": a, "at": b} for a, b in placements]
    score = load_score(shaped(flat, 0.4, 0.8, *touch, names=("C", "S", "T")))
    poser = KeyPoser(IKAdapter(Schedule(score, solver)), Mode.MULTITRACK)
    keys = poser.key_postures()
    q = poser.schedule.home.copy()
    for track, d in poser.schedule.track_dofs.items():
        if keys[track]:
            q[d] = keys[track][-1].q[d]
    k = solver.at(q)
    for a, b in placements:
        site, at = (
            poser.schedule.smap.sites[x.strip("@").replace("(s)", "_R").replace("(w)", "_L")]
            for x in (a, b)
        )
        gap = k.d.site_xpos[solver.site_id(site)] - k.d.site_xpos[solver.site_id(at)]
        assert np.linalg.norm(gap) <= 1e-3, (a, b)
    return poser, q


def test_a_palm_on_the_back_of_the_head_raises_the_arm_instead_of_bowing(solver):
    # the limbs alone miss from their two-bone starts; main met it with the trunk and the
    # head 20 degrees from upright: another elbow branch meets it upright
    poser, q = _flat_contacts(solver, ("@PA(s)", "@BEB"))
    assert poser.reasons == {}
    e = ergonomics(solver.model, q)
    assert np.degrees(e.trunk_angle) <= 10.0 and np.degrees(e.head_angle) <= 15.0
    assert e.elbows_ok()  # the hand is above the eyes: the raised elbow is allowed


def test_two_palms_on_the_belly_lean_no_further_than_the_posture_limit(solver):
    # the hand placed first lies where the other must go upright: the trunk helps, then
    # comes back toward upright with both arms solved anew (main: 12 degrees)
    poser, q = _flat_contacts(solver, ("@PA(s)", "@AB_R"), ("@PA(w)", "@AB_L"))
    assert poser.reasons == {}
    assert np.degrees(ergonomics(solver.model, q).trunk_angle) <= 10.0


def test_two_palms_on_the_cheeks_keep_their_elbows_low(solver):
    # another elbow branch meets them too, but with an elbow over its shoulder: not kept
    _, q = _flat_contacts(solver, ("@PA(s)", "@CK_R"), ("@PA(w)", "@CK_L"))
    e = ergonomics(solver.model, q)
    assert e.elbows_ok() and max(e.right.elbow_above_shoulder, e.left.elbow_above_shoulder) < 0
    assert np.degrees(e.trunk_angle) <= 10.0


def test_joined_hands_with_an_oriented_palm_start_turned_as_asked(solver):
    # the strong hand's edge on the weak palm, the weak palm up: both sides constrained,
    # the hands flat from the start, the contact from 0.4 s (as bench/natural.py writes it)
    flat = {"type": "morph", "id": "flat", "weight": 1.0}
    touch = [
        {"type": "place", "site": "@H_EDGE(s)", "at": "@PA(w)"},
        {"type": "orient", "bone": "!palm(w)", "axis": "nrm", "rel": "along", "vector": "up"},
    ]
    score = load_score(shaped([flat], 0.4, 0.8, *touch, names=("C", "S", "T")))
    poser = KeyPoser(IKAdapter(Schedule(score, solver)), Mode.MULTITRACK)
    keys = poser.key_postures()
    assert poser.reasons == {}
    k = solver.at(keys["arm_L"][-1].q)
    edge = k.d.site_xpos[solver.site_id("H_EDGE_R")]
    assert np.linalg.norm(edge - k.d.site_xpos[solver.site_id("PA_L")]) <= 1e-3
    normal = k.d.xmat[solver.body_id("palm_L")].reshape(3, 3) @ np.array([0.0, -1.0, 0.0])
    assert np.degrees(np.arccos(np.clip(normal[2], -1, 1))) <= 1.0 + 1e-6


def test_a_turned_trunk_does_not_lean_a_bent_one_does(solver):
    # the arms are solved again another way only for a trunk bent from upright
    score = _score([{"type": "place", "site": "@I_TIP(s)", "at": [0.3, -0.15, 1.2]}])
    poser = KeyPoser(IKAdapter(Schedule(score, solver)), Mode.MULTITRACK)
    home = poser.schedule.home
    m = solver.model
    assert not poser.leans(home)
    for joint, leans in [("back_1_rot", False), ("back_2_rot", False), ("back_1_flex", True)]:
        q = home.copy()
        q[m.jnt_qposadr[solver.joint_id(joint)]] += 0.1
        assert poser.leans(q) is leans, joint
    assert sorted(m.joint(int(i)).name for i in m.dof_jntid[poser.tilt]) == [
        "back_1_flex",
        "back_1_lat",
        "back_2_flex",
        "back_2_lat",
    ]


def _touch_key(solver, score):
    """The arm key posture of the strong hand at the block named ``TOUCH`` of ``score``
    (JSON), and its side."""
    side = score["strong_side"]
    poser = KeyPoser(IKAdapter(Schedule(load_score(score), solver)), Mode.MULTITRACK)
    keys = poser.key_postures()[f"arm_{side}"]
    (touch,) = [k for k in keys if any(c.label.endswith("TOUCH#1") for c in k.cons)]
    assert poser.reasons == {}
    return touch.q, side


@pytest.mark.parametrize("side", ["R", "L"])
def test_a_fingertip_on_the_temple_comes_from_below_with_the_elbow_low(solver, side):
    # the index tip on the temple, its direction free: the usual starts come at the
    # temple head-on from the side and fold the arm up there (main: the elbow 12 mm below
    # the shoulder, the upper arm 88 degrees from hanging, abducted 45)
    index = [
        {"type": "morph", "id": "fist", "weight": 1.0, "side": "s"},
        {"type": "morph", "id": "index_bend", "weight": -1.04, "side": "s"},
        {"type": "morph", "id": "index_hook", "weight": -1.1, "side": "s"},
    ]
    touch = {"type": "place", "site": "@I_TIP(s)", "at": "@TE(s)"}
    score = shaped(index, 0.4, 0.8, touch, names=("C", "HS", "TOUCH"))
    q, _ = _touch_key(solver, {**score, "strong_side": side})
    e = ergonomics(solver.model, q)
    arm = e.rula.right if side == "R" else e.rula.left
    assert e.arm(side).elbow_above_shoulder < -ELBOW_RAISED
    assert np.degrees(arm.upper_arm_elevation) < 75.0
    assert np.degrees(e.trunk_angle) <= 10.0 and e.rula.score <= 4


def test_penser_touches_the_temple_with_the_elbow_low_on_either_side(solver):
    # the example as it was written (the index level) held the upper arm horizontal: the
    # elbow 19 mm below the shoulder, 87 degrees from hanging
    score = json.loads((ROOT / "examples" / "penser.json").read_text())
    postures = {}
    for side in "RL":
        q, _ = _touch_key(solver, {**score, "strong_side": side})
        e = ergonomics(solver.model, q)
        arm = e.rula.right if side == "R" else e.rula.left
        assert e.arm(side).elbow_above_shoulder < -ELBOW_RAISED
        assert np.degrees(arm.upper_arm_elevation) < 75.0
        postures[side] = e.arm(side).elbow_above_shoulder
    assert postures["R"] == pytest.approx(postures["L"], abs=1e-3)  # mirrored
