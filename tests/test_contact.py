"""Round ends (fingertips) touching with any point of the end: the catalogue of round-end
sites on the real signer, the placement rows against finite differences and against the
geometry of the capsules."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from azee_mj import constraints as cn
from azee_mj import contact
from azee_mj import kinematics as kin
from azee_mj.kinematics import Kinematics
from azee_mj.sites import DEFAULT_MAP

TIPS = [f"{d}_TIP_{s}" for s in "LR" for d in "TIMRL"]


def test_the_round_ends_are_the_ten_fingertips(model):
    ends = {s for s in DEFAULT_MAP.sites.values() if contact.round_end(model, DEFAULT_MAP, s)}
    assert ends == {DEFAULT_MAP.sites[t] for t in TIPS}


@pytest.mark.parametrize("tip", TIPS)
def test_a_round_end_is_its_capsule_end_and_radius(model, tip):
    site = DEFAULT_MAP.sites[tip]
    end = contact.round_end(model, DEFAULT_MAP, site)
    d = mujoco.MjData(model)
    mujoco.mj_kinematics(model, d)
    body = model.body(end.body).id
    centre = d.site_xpos[model.site(site).id] - end.radius * (
        d.xmat[body].reshape(3, 3) @ np.asarray(end.normal)
    )
    # the centre is on the axis of one of the body's capsules, at its end, that radius wide
    capsules = [
        g
        for g in range(model.ngeom)
        if model.geom_bodyid[g] == body and model.geom_type[g] == mujoco.mjtGeom.mjGEOM_CAPSULE
    ]
    ends = [
        d.geom_xpos[g] + s * model.geom_size[g][1] * d.geom_xmat[g].reshape(3, 3)[:, 2]
        for g in capsules
        for s in (1.0, -1.0)
    ]
    k = int(np.argmin([np.linalg.norm(e - centre) for e in ends]))
    assert np.linalg.norm(ends[k] - centre) < 5e-4
    assert model.geom_size[capsules[k // 2]][0] == pytest.approx(end.radius)


def test_rolling_pairs_a_tip_with_a_flat_site_or_another_tip(model):
    m, sites = model, DEFAULT_MAP.sites
    shift, gap = contact.rolling(m, DEFAULT_MAP, sites["I_TIP_R"], sites["PA_L"])
    assert gap == 0.0 and len(shift.terms) == 2
    shift, gap = contact.rolling(m, DEFAULT_MAP, sites["I_TIP_R"], sites["T_TIP_R"])
    assert gap == pytest.approx(0.0068 + 0.0085)
    assert contact.rolling(m, DEFAULT_MAP, sites["PA_R"], sites["PA_L"]) is None


def _pose(model, seed):
    rng = np.random.default_rng(seed)
    d = mujoco.MjData(model)
    d.qpos[:] = model.key("home").qpos
    for j in DEFAULT_MAP.tracks["arm_R"] + DEFAULT_MAP.tracks["hand_R"]:
        jid = model.joint(j).id
        lo, hi = model.jnt_range[jid]
        d.qpos[model.jnt_qposadr[jid]] = rng.uniform(lo + 0.2 * (hi - lo), hi - 0.2 * (hi - lo))
    return d


def _fk(model, d):
    mujoco.mj_kinematics(model, d)
    mujoco.mj_comPos(model, d)
    return Kinematics(model, d)


@pytest.mark.parametrize("target", ["PA_L", "T_TIP_R"])
def test_round_end_rows_match_finite_differences(model, target):
    """Rows of the round end's branch (the target put where the end, not the site, meets
    it): Jacobian against finite differences, residual against the rolled geometry."""
    sites = DEFAULT_MAP.sites
    site, at = sites["I_TIP_R"], sites[target]
    shift, gap = contact.rolling(model, DEFAULT_MAP, site, at)
    d = _pose(model, 5)
    k = _fk(model, d)
    s = k.value(shift)
    p = d.site_xpos[model.site(site).id]
    if gap:  # the other tip at the gap beyond the end's centre, plus a little
        c = cn.Place(site, kin.SitePos(at), 1e-3, shift=shift, gap=gap)
    else:  # a fixed point where the end touches, 0.3 mm off
        goal = p + s + np.array([3e-4, 0.0, 0.0])
        c = cn.Place(site, kin.Const(tuple(goal)), 1e-3, shift=shift)
    r0, J = c.rows(k)
    target = k.value(kin.SitePos(at)) if gap else goal
    rolled = abs(np.linalg.norm(p + s - target) - gap)
    assert rolled < np.linalg.norm(p - target)  # the round end's branch is the one taken
    assert c.residual(k) == pytest.approx(rolled)
    assert np.linalg.norm(r0) * 1e-3 == pytest.approx(rolled)
    eps = 1e-7
    fd = np.zeros_like(J)
    q = d.qpos.copy()
    for i in range(model.nv):
        d.qpos[:] = q
        d.qpos[i] += eps
        fd[:, i] = (c.rows(_fk(model, d))[0] - r0) / eps
    np.testing.assert_allclose(J, fd, atol=1e-4 * max(1.0, np.abs(J).max()))


def test_head_on_makes_round_end_placements_plain(model):
    sites = DEFAULT_MAP.sites
    shift, gap = contact.rolling(model, DEFAULT_MAP, sites["I_TIP_R"], sites["T_TIP_R"])
    rolled = cn.Place(sites["I_TIP_R"], kin.SitePos(sites["T_TIP_R"]), shift=shift, gap=gap)
    other = cn.Place(sites["PA_R"], kin.SitePos(sites["PA_L"]))
    assert contact.head_on((other,)) is None
    plain = contact.head_on((rolled, other))
    assert plain == (cn.Place(sites["I_TIP_R"], kin.SitePos(sites["T_TIP_R"])), other)


def test_widened_opens_only_the_facing_rule_of_a_round_end_placement(model):
    sites = DEFAULT_MAP.sites
    shift, _ = contact.rolling(model, DEFAULT_MAP, sites["I_TIP_R"], sites["CH"])
    tip = cn.Place(sites["I_TIP_R"], kin.SitePos(sites["CH"]), label="K#0", shift=shift)
    palm = cn.Place(sites["PA_R"], kin.SitePos(sites["PA_L"]), label="K#1")
    up = kin.Const((0.0, 0.0, 1.0))
    facing = [
        cn.Orient(
            body, (1.0, 0.0, 0.0), cn.Rel.OPP, up, np.radians(20.0), f"{p.label}:facing", False
        )
        for body, p in (("index_R_3", tip), ("palm_R", palm))
    ]
    out = contact.widened((tip, palm, *facing))
    assert out[:2] == (tip, palm)
    assert out[2].tol == pytest.approx(np.radians(contact.ROLLED_FACING_DEG))
    assert out[2].ranged  # any point of the end's dome may touch
    assert out[3] == facing[1]
