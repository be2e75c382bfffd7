"""Natural postures for fingertips at rounded sites and for a hand on the other arm
(``bench/natural.py`` contacts, right-handed, held 0.4 s), and the elbow-low preference row.
"""

import mujoco
import numpy as np
import pytest
from scores import shaped
from test_natural_contacts import DEG, FLAT, INDEX, contact_score, held_posture

from azee_mj import constraints as cn
from azee_mj import natural
from azee_mj.ergonomics import ergonomics
from azee_mj.kinematics import Kinematics
from azee_mj.timeline import realize


def upright_ergonomics(model, q):
    """The ergonomics of posture ``q``, checked: RULA 4 or less, trunk and head upright."""
    e = ergonomics(model, q)
    assert e.rula.score <= 4, f"RULA {e.rula.score}"
    assert e.trunk_angle < 10 * DEG and e.head_angle < 15 * DEG
    return e


def test_an_index_on_the_forehead_comes_from_the_front_with_the_elbow_forward(solver, model):
    e = upright_ergonomics(model, held_posture(solver, "@I_TIP(s)", "@FH", INDEX))
    # the elbow no higher than 5 cm above the shoulder (it rose 10 cm with a 20-degree rule)
    assert e.arm("R").elbow_above_shoulder < 0.05


def test_an_index_on_the_temple_keeps_the_elbow_below_the_shoulder(solver, model):
    # With the 20-degree fingertip rule the finger pointed straight into the side of the
    # head and the elbow rose 43 mm above the shoulder (RULA 5).
    e = upright_ergonomics(model, held_posture(solver, "@I_TIP(s)", "@TE(s)", INDEX))
    assert e.arm("R").elbow_above_shoulder < 0.0


@pytest.mark.parametrize(
    "site, strong",
    [("@PA(s)", FLAT), ("@I_TIP(s)", INDEX)],
    ids=["palm-elbow-R", "index-tip-elbow-R"],
)
def test_the_touched_arm_raises_its_forearm_in_front(solver, model, site, strong):
    q = held_posture(solver, site, "@EL(w)", strong)
    e = ergonomics(model, q)
    assert e.rula.score <= 4, f"RULA {e.rula.score}"
    weak = e.rula.left
    assert weak.elbow_flexion > 60 * DEG, f"weak elbow bent {weak.elbow_flexion / DEG:.0f} deg"
    d = mujoco.MjData(model)
    d.qpos[:] = q
    mujoco.mj_kinematics(model, d)
    palm, elbow = d.body("palm_L").xpos, d.body("f_arm_L").xpos
    assert palm[0] > 0.15, f"weak palm {palm[0] * 1e3:.0f} mm in front"  # in front of the body
    assert palm[2] > elbow[2] + 0.1  # the forearm raised, not hanging or held out sideways
    for side in "RL":
        assert e.arm(side).elbow_above_shoulder < 0.0


def test_the_elbow_low_row_is_zero_below_and_its_jacobian_matches_finite_differences(model):
    d = mujoco.MjData(model)
    row = natural.Below("f_arm_R", "arm_R", margin=0.02, tol=0.05)
    d.qpos[:] = model.key("home").qpos
    mujoco.mj_kinematics(model, d)
    mujoco.mj_comPos(model, d)
    r, J = row.rows(Kinematics(model, d))
    assert r.shape == (1,) and r[0] == 0.0 and not J.any()
    # the upper arm raised past the horizontal: the elbow above the shoulder
    flex = model.jnt_qposadr[model.joint("arm_R_flex").id]
    d.qpos[flex] = 2.0
    mujoco.mj_kinematics(model, d)
    mujoco.mj_comPos(model, d)
    r, J = row.rows(Kinematics(model, d))
    h = d.body("f_arm_R").xpos[2] - d.body("arm_R").xpos[2] + 0.02
    assert h > 0 and r[0] == pytest.approx(h / 0.05)
    eps = 1e-6
    d.qpos[flex] += eps
    mujoco.mj_kinematics(model, d)
    r2, _ = row.rows(Kinematics(model, d))
    dof = model.jnt_dofadr[model.joint("arm_R_flex").id]
    assert J[0, dof] == pytest.approx((r2[0] - r[0]) / eps, rel=1e-4)


def test_a_missed_fingertip_contact_keeps_the_posture_natural(solver, model):
    """The flat hand's fingertips on the nape: the straight fingers meet the neck before
    the tips reach it. Rolled onto the side of its end the fingertip came 2.8 mm short
    with the elbow 164 mm over the shoulder; a miss keeps the posture limits instead
    (the head-on miss, the elbow under the shoulder: ``ik.head_on_first``)."""
    ro = realize(contact_score("@M_TIP(s)", "@NAPE", FLAT), fps=50, solver=solver)
    held = ro.qpos[int(np.flatnonzero(ro.time - ro.score_start >= 0.6 - 1e-9)[0])]
    e = upright_ergonomics(model, held)
    assert e.arm("R").elbow_above_shoulder < 0.0


def test_two_palms_on_the_chest_keep_their_fingers_apart(solver, model):
    """Both palms on the chest, fingers meeting at the sternum: over every frame the two
    hands stay out of each other (their hand shape's posture, a milliradian off the
    contact's, put the little fingers 0.14 mm into each other over the hold) and no joint
    turns faster than 25 rad/s (the lead-in jumped 34.9 rad/s into the key)."""
    shape = [{"type": "morph", "id": "flat", "weight": 1.0, "side": s} for s in ("s", "w")]
    places = [{"type": "place", "site": f"@PA({s})", "at": f"@ST({s})"} for s in ("s", "w")]
    ro = realize(shaped(shape, 0.4, 0.8, *places), fps=50, solver=solver)
    assert all(t.ok for t in ro.traces if t.block == "K"), [t.describe() for t in ro.traces]
    hands = [_subtree(model, model.body(f"palm_{s}").id) for s in "RL"]
    d = mujoco.MjData(model)
    for q in ro.qpos:
        d.qpos[:] = q
        mujoco.mj_forward(model, d)
        for c in d.contact[: d.ncon]:
            b = {int(model.geom_bodyid[c.geom1]), int(model.geom_bodyid[c.geom2])}
            if b & hands[0] and b & hands[1]:
                assert c.dist > -cn.COLLISION_TOL
    hinge = model.jnt_qposadr[model.jnt_type == mujoco.mjtJoint.mjJNT_HINGE]
    assert np.abs(np.diff(ro.qpos[:, hinge], axis=0)).max() * 50 <= 25.0


def _subtree(model, root: int) -> set[int]:
    """Body ``root`` and every body below it."""
    out = {root}
    for b in range(root + 1, model.nbody):  # a parent is numbered before its children
        if int(model.body_parentid[b]) in out:
            out.add(b)
    return out
