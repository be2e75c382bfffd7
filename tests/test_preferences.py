"""The natural preferences, built on the real signer and checked against its geometry."""

from __future__ import annotations

import numpy as np
import pytest

from azee_mj import constraints as cn
from azee_mj import natural
from azee_mj.anatomy import SignerAnatomy
from azee_mj.kinematics import BodyAxis, Const, SitePos
from azee_mj.preferences import (
    ELBOW_LOW,
    ELBOW_RAISED,
    FACING_TOL_BODY,
    FACING_WIDEN,
    MEET_TOL,
    UPRIGHT_TOL_DEG,
    Preferences,
    facing_tol,
    widened,
)
from azee_mj.sites import DEFAULT_MAP


@pytest.fixture(scope="module")
def prefs(solver) -> Preferences:
    return Preferences(solver, SignerAnatomy(solver.model, DEFAULT_MAP), DEFAULT_MAP)


def test_facing_tolerance_by_hand_part_and_rounded_body():
    assert facing_tol("PA_R", "PA_L") == pytest.approx(np.radians(5.0))
    assert facing_tol("I_TIP_R", "CHEST") == pytest.approx(np.radians(20.0))
    assert facing_tol("T_KN_R_1", "PA_L") == pytest.approx(np.radians(45.0))  # the widest
    assert facing_tol("I_TIP_R", "FH") == pytest.approx(np.radians(40.0))  # rounded forehead
    assert facing_tol("EL_R", "CHEST") == pytest.approx(np.radians(FACING_TOL_BODY))


def test_a_skin_contact_faces_its_surfaces_unless_the_score_orients_one(prefs, solver):
    place = cn.Place("PA_R", SitePos("PA_L"), 1e-3, "C#0")
    (face,) = prefs.facing([place])
    assert (face.body, face.rel, face.label) == ("palm_R", cn.Rel.OPP, "C#0:facing")
    assert face.local == DEFAULT_MAP.normals["PA_R"]
    assert face.vector == BodyAxis("palm_L", DEFAULT_MAP.normals["PA_L"])
    assert face.tol == pytest.approx(np.radians(5.0))
    assert not face.ranged  # head-on as near as the solver gets, not anywhere in its cone
    turned = cn.Orient("palm_L", (0.0, 0.0, 1.0), cn.Rel.ALONG, Const((0.0, 0.0, 1.0)), 0.1, "o")
    assert prefs.facing([place, turned]) == []
    assert prefs.facing([cn.Place("PA_R", Const((0.3, 0.0, 1.0)), 1e-3, "p")]) == []
    (wide,) = widened([face])
    assert wide.tol == pytest.approx(FACING_WIDEN * face.tol) and wide.label == face.label


def test_two_hands_meet_in_the_signing_space(prefs):
    joined = cn.Place("I_TIP_R", SitePos("PA_L"), 1e-3, "j")
    assert prefs.joins_hands(joined)
    assert prefs.meeting_place([joined]) == (cn.Place("I_TIP_R", SitePos("ssp"), MEET_TOL, "meet"),)
    on_arm = cn.Place("I_TIP_R", SitePos("EL_L"), 1e-3, "e")  # the other arm's palm rests
    (rest,) = prefs.meeting_place([on_arm])
    assert rest.site == "PA_L" and rest.tol == MEET_TOL
    assert prefs.meeting_place([cn.Place("I_TIP_R", SitePos("HEAD"), 1e-3, "h")]) == ()
    assert prefs.meeting_place([joined, on_arm]) == ()  # only when nothing else places them


def test_elbows_low_below_the_eyes_only(prefs, solver):
    q = solver.natural
    eye_z = solver.at(q).d.site_xpos[solver.site_id("EYE_R")][2]
    free = DEFAULT_MAP.tracks["arm_R"]
    low = cn.Place("I_TIP_R", Const((0.3, -0.1, eye_z - 0.2)), 1e-3, "low")
    high = cn.Place("I_TIP_R", Const((0.3, -0.1, eye_z + 0.1)), 1e-3, "high")
    margin, tol = ELBOW_LOW
    assert prefs.elbows_low([low], free, q) == (
        natural.Below("f_arm_R", "arm_R", margin, tol, "elbow low"),
    )
    assert prefs.elbows_low([high], free, q) == ()
    assert prefs.elbows_low([low], (), q) == ()  # the arm is not free


def test_elbows_up_names_the_arms_raised_against_the_preference(prefs, solver):
    q = solver.natural.copy()
    eye_z = solver.at(q).d.site_xpos[solver.site_id("EYE_R")][2]
    free = DEFAULT_MAP.tracks["arm_R"]
    low = cn.Place("I_TIP_R", Const((0.3, -0.1, eye_z - 0.2)), 1e-3, "low")
    high = cn.Place("I_TIP_R", Const((0.3, -0.1, eye_z + 0.1)), 1e-3, "high")
    assert prefs.elbows_up([low], free, q) == set()  # hanging: the elbow is low
    q[solver.model.jnt_qposadr[solver.joint_id("arm_R_abd")]] = np.radians(120.0)
    d = solver.at(q).d
    assert d.xpos[solver.body_id("f_arm_R")][2] > d.xpos[solver.body_id("arm_R")][2]
    assert prefs.elbows_up([low], free, q) == {"arm_R"}
    assert prefs.elbows_up([high], free, q) == set()  # a hand above the eyes may raise it


def _flexed(solver, degrees: float) -> np.ndarray:
    """The natural posture with the right upper arm raised forward by ``degrees``."""
    q = solver.natural.copy()
    q[solver.model.jnt_qposadr[solver.joint_id("arm_R_flex")]] = np.radians(degrees)
    return q


def _elbow_height(solver, q) -> float:
    d = solver.at(q).d
    return float(d.xpos[solver.body_id("f_arm_R")][2] - d.xpos[solver.body_id("arm_R")][2])


def test_a_hand_on_the_face_with_the_elbow_at_the_shoulder_is_tried_from_below(prefs, solver):
    q = solver.natural
    d = solver.at(q).d
    eye_z = d.site_xpos[solver.site_id("EYE_R")][2]
    free = DEFAULT_MAP.tracks["arm_R"]
    face = cn.Place("I_TIP_R", Const((0.1, -0.07, eye_z - 0.02)), 1e-3, "temple")
    chest = cn.Place("I_TIP_R", Const((0.3, -0.1, eye_z - 0.4)), 1e-3, "chest")
    level, low, up = _flexed(solver, 85.0), _flexed(solver, 60.0), _flexed(solver, 110.0)
    assert -ELBOW_RAISED < _elbow_height(solver, level) <= 0.0
    assert _elbow_height(solver, low) < -ELBOW_RAISED and _elbow_height(solver, up) > 0.0
    arm = next(a for a in prefs.anatomy.arms if a.upper == "arm_R")
    assert prefs.raised_on_face([face], free, level) == {arm}
    assert prefs.raised_on_face([face], free, low) == set()  # the elbow is low already
    assert prefs.raised_on_face([face], free, up) == {arm}
    # a hand below the shoulder, or an arm that is not free: nothing to try
    assert prefs.raised_on_face([chest], free, level) == set()
    assert prefs.raised_on_face([face], (), level) == set()
    tol = np.radians(30.0)
    fore = DEFAULT_MAP.bones["f_arm_R"]
    under = cn.Orient(
        "f_arm_R", fore.dir, cn.Rel.ALONG, Const((0.0, 0.0, 1.0)), tol, "forearm under"
    )
    assert prefs.forearms_under({arm}, tol) == (under,)


def test_joined_behind_is_the_side_of_the_chest_plane(prefs, solver):
    joined = [cn.Place("I_TIP_R", SitePos("PA_L"), 1e-3, "j")]
    chest = DEFAULT_MAP.bones["back_2"]
    rng = np.random.default_rng(0)
    lo, hi = solver.lower, solver.upper
    seen = set()
    for _ in range(16):
        q = np.where(np.isfinite(lo) & np.isfinite(hi), rng.uniform(lo, hi), solver.natural)
        d = solver.at(q).d
        body = solver.body_id(chest.body)
        forward = d.xmat[body].reshape(3, 3) @ np.asarray(chest.nrm)
        ahead = (d.site_xpos[solver.site_id("I_TIP_R")] - d.xpos[body]) @ forward
        assert prefs.joined_behind(joined, q) == (ahead < 0.0)
        seen.add(bool(ahead < 0.0))
    assert seen == {True, False}  # both sides were tried
    assert not prefs.joined_behind([cn.Place("I_TIP_R", SitePos("HEAD"), 1e-3, "h")], q)


def test_upright_is_the_chest_along_up(prefs):
    (up,) = prefs.upright
    assert (up.body, up.rel, up.vector) == ("back_2", cn.Rel.ALONG, Const((0.0, 0.0, 1.0)))
    assert up.tol == pytest.approx(np.radians(UPRIGHT_TOL_DEG))
