"""Which arm, hand or limb carries a site, on the real signer."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from azee_mj.anatomy import ACROSS, SignerAnatomy, across, descends
from azee_mj.sites import DEFAULT_MAP


@pytest.fixture(scope="module")
def anatomy(solver) -> SignerAnatomy:
    return SignerAnatomy(solver.model, DEFAULT_MAP)


def _body(m, name: str) -> int:
    return mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, name)


def _arm(anatomy, side: str):
    return next(a for a in anatomy.arms if a.hand == f"palm_{side}")


def test_descends_walks_the_body_tree(model):
    assert descends(model, _body(model, "index_R_3"), _body(model, "palm_R"))
    assert descends(model, _body(model, "palm_R"), _body(model, "palm_R"))
    assert not descends(model, _body(model, "palm_R"), _body(model, "index_R_3"))
    assert not descends(model, _body(model, "palm_L"), _body(model, "f_arm_R"))


def test_the_hand_of_a_site_is_the_arm_whose_hand_carries_it(anatomy):
    right, left = _arm(anatomy, "R"), _arm(anatomy, "L")
    assert [a.out for a in anatomy.arms] == [-1.0, 1.0]  # right, then left
    assert anatomy.hand_of("I_TIP_R") is right
    assert anatomy.hand_of("PA_L") is left
    assert anatomy.hand_of("WRt_R") is None  # on the forearm, not the hand
    assert anatomy.hand_of("HEAD") is None
    assert anatomy.arm_carrying("WRt_R", "fore") is right
    assert anatomy.arm_carrying("ARM_L", "upper") is left
    assert anatomy.arm_carrying("SH_R", "upper") is None  # the clavicle is above the arm


def test_a_site_on_an_arm_is_carried_to_that_arms_palm_across_the_body(anatomy, solver):
    left = _arm(anatomy, "L")
    carrier = anatomy.carried_by("EL_L")
    assert carrier.arm is left and carrier.palm == "PA_L"
    assert anatomy.carried_by("PA_L") is None  # on the hand itself
    assert anatomy.carried_by("NK") is None
    k = solver.at(solver.natural)
    shoulder = k.d.xpos[solver.body_id("arm_L")].copy()
    fwd, inward, up = ACROSS
    np.testing.assert_allclose(k.value(carrier.rest), shoulder + [fwd, -inward, up])
    np.testing.assert_allclose(
        k.value(across(_arm(anatomy, "R"))) - k.d.xpos[solver.body_id("arm_R")], [fwd, inward, up]
    )


def test_limb_root_is_the_clavicle_the_arm_hangs_from(anatomy, model):
    assert anatomy.limb_root("I_TIP_R") == _body(model, "clav_R")
    assert anatomy.limb_root("EL_L") == _body(model, "clav_L")
    assert anatomy.limb_root("HEAD") is None


def test_forearm_and_hand_parts(anatomy, model):
    assert anatomy.on_forearm("WRt_R") and anatomy.on_forearm("I_TIP_L")
    assert not anatomy.on_forearm("ARM_R") and not anatomy.on_forearm("NK")
    hand = anatomy.part(_body(model, "index_R_3"))
    assert hand == anatomy.part(_body(model, "palm_R"))
    assert set(hand) == {
        b for b in range(model.nbody) if descends(model, b, _body(model, "palm_R"))
    }
    assert len(hand) > 10  # the palm and every digit's bones
    assert anatomy.part(_body(model, "head")) == (_body(model, "head"),)


def test_joins_hands_and_palms(anatomy):
    assert anatomy.joins_hands("I_TIP_R", "PA_L")
    assert not anatomy.joins_hands("I_TIP_R", "PA_R")  # a pinch on one hand
    assert not anatomy.joins_hands("I_TIP_R", "HEAD")
    assert anatomy.palms == {_arm(anatomy, "R"): "PA_R", _arm(anatomy, "L"): "PA_L"}
