"""The signer's skin: surface sites on the collision surface with outward normals, a flat hand
whose thumb lies in the palm plane, and palm contacts that meet face to face (signer.md,
"Surface normals"; issue: a hand that can touch)."""

from __future__ import annotations

import json

import mujoco
import numpy as np
import pytest

from azee_mj import constraints as cn
from azee_mj import ik
from azee_mj import kinematics as kin
from azee_mj.sites import DEFAULT_MAP, azee_site_names
from azee_mj.surface import collision_geoms, local_distance, skin_distance

#: How far a surface site may be from its body's collision surface [m] (signer.md: 0.1 mm).
ON_SKIN = 1e-4


def _posture(model, name):
    if name == "home":
        return model.key("home").qpos.copy()
    lo, hi = model.jnt_range.T
    return lo + np.random.default_rng(3).random(model.njnt) * (hi - lo)


def _with_morphs(model, *morphs, side=None):
    """qpos0 plus the morphs' changes, added and clipped to the ranges (score-format.md)."""
    q = model.qpos0.copy()
    for morph in morphs:
        for j, v in DEFAULT_MAP.morphs[morph].joint_changes(side).items():
            q[model.joint(j).qposadr[0]] += v
    return np.clip(q, *model.jnt_range.T)


def _angle_deg(a, b) -> float:
    return float(np.degrees(np.arccos(np.clip(np.dot(a, b), -1.0, 1.0))))


# --------------------------------------------------------------------------- the catalogue


def test_every_site_is_on_the_skin_or_listed_as_interior():
    names = set(azee_site_names())
    surface, interior = set(DEFAULT_MAP.normals), set(DEFAULT_MAP.interior)
    assert surface | interior == names and not surface & interior
    assert interior == {"TO", "WR_L", "WR_R"}
    for name, n in DEFAULT_MAP.normals.items():
        assert np.linalg.norm(n) == pytest.approx(1.0, abs=1e-5), name


def test_catalogue_json_lists_normals_and_interior_sites():
    cat = json.loads(json.dumps(DEFAULT_MAP.to_json()))
    assert cat["normals"]["PA_R"] == [0.0, 1.0, 0.0]
    assert cat["normals"]["PA_L"] == [0.0, -1.0, 0.0]
    assert cat["interior"] == ["TO", "WR_L", "WR_R"]
    assert len(cat["normals"]) + len(cat["interior"]) == len(cat["sites"])


def test_left_normals_mirror_the_right():
    for name, n in DEFAULT_MAP.normals.items():
        if name.endswith("_R") or "_R_" in name:
            twin = name[:-2] + "_L" if name.endswith("_R") else name.replace("_R_", "_L_")
            np.testing.assert_allclose(
                DEFAULT_MAP.normals[twin], [n[0], -n[1], n[2]], atol=1e-9, err_msg=name
            )
        elif "_L" not in name:
            assert n[1] == 0.0, name  # midline


# --------------------------------------------------------------------------- on the skin


@pytest.mark.parametrize("posture", ["home", "random"])
def test_surface_sites_lie_on_their_collision_surface_with_their_normal(model, data, posture):
    data.qpos[:] = _posture(model, posture)
    mujoco.mj_kinematics(model, data)
    off, turned = [], []
    for name, normal in DEFAULT_MAP.normals.items():
        s = model.site(DEFAULT_MAP.sites[name])
        body = s.bodyid[0]
        dist, grad, _ = skin_distance(model, data, body, data.site_xpos[s.id])
        if abs(dist) > ON_SKIN:
            off.append((name, round(dist * 1000, 2)))
        world = data.xmat[body].reshape(3, 3) @ normal
        if _angle_deg(world, grad) > 1.0:
            turned.append((name, round(_angle_deg(world, grad), 1)))
    assert off == [] and turned == []


def test_skin_sites_outside_the_rest_of_the_body_at_rest(model, data):
    """At qpos0 a surface site is inside no other body, but where two parts meet: the base
    of a digit (its knuckle sites under the end of the bone before, or the palm) and the
    olecranon (EL), in the end of the upper arm while the elbow is straight."""
    mujoco.mj_kinematics(model, data)
    geoms = [g for b in range(model.nbody) for g in collision_geoms(model, b)]
    inside = []
    for name in DEFAULT_MAP.normals:
        s = model.site(DEFAULT_MAP.sites[name])
        for g in geoms:
            if model.geom_bodyid[g] != s.bodyid[0]:
                d = local_distance(
                    model.geom_type[g],
                    model.geom_size[g],
                    data.geom_xmat[g].reshape(3, 3).T @ (data.site_xpos[s.id] - data.geom_xpos[g]),
                )[0]
                if d < -ON_SKIN:
                    inside.append(name)
    joint_sites = {n for n in inside if n.split("_")[1] in ("KN", "KNi", "INT")}
    assert set(inside) == joint_sites | {"EL_L", "EL_R"}
    assert {"PA_R", "H_BACK_L", "MO", "CK_R", "ST_R", "I_TIP_R", "T_PAD_L"}.isdisjoint(inside)


@pytest.mark.parametrize("side", ["R", "L"])
def test_shoulder_and_ear_sites_face_the_front_where_a_hand_meets_them(model, data, side):
    """``SH`` is on the front of the shoulder's cap (the acromion's sphere), ``EAR`` on the
    front rim of the ear: a fingertip meets them coming from the front, the elbow low
    (mjcf/README.md, "Sites"); on the top of the cap or the side of the ear it had to point
    down or across from beside the head, the elbow at or above the shoulder."""
    mujoco.mj_kinematics(model, data)
    lateral = -1.0 if side == "R" else 1.0
    for name, shape in (
        ("SH", mujoco.mjtGeom.mjGEOM_SPHERE),
        ("EAR", mujoco.mjtGeom.mjGEOM_ELLIPSOID),
    ):
        s = model.site(DEFAULT_MAP.sites[f"{name}_{side}"])
        dist, n, g = skin_distance(model, data, s.bodyid[0], data.site_xpos[s.id])
        assert abs(dist) <= ON_SKIN and model.geom_type[g] == shape, name
        elevation = np.degrees(np.arcsin(n[2]))
        forward = np.degrees(np.arctan2(n[0], lateral * n[1]))  # from the side toward the front
        if name == "SH":
            assert n[0] > abs(n[1]) and 15.0 <= elevation <= 45.0, (name, n)
        else:
            assert forward >= 45.0 and -30.0 <= elevation <= 0.0, (name, n)


def test_distance_helpers_against_known_shapes():
    sph, cap = mujoco.mjtGeom.mjGEOM_SPHERE, mujoco.mjtGeom.mjGEOM_CAPSULE
    ell, box = mujoco.mjtGeom.mjGEOM_ELLIPSOID, mujoco.mjtGeom.mjGEOM_BOX
    assert local_distance(sph, [0.02], [0.05, 0, 0])[0] == pytest.approx(0.03)
    d, n = local_distance(cap, [0.01, 0.05], [0.0, 0.03, 0.07])
    assert d == pytest.approx(np.hypot(0.03, 0.02) - 0.01)
    np.testing.assert_allclose(n, np.array([0, 0.03, 0.02]) / np.hypot(0.03, 0.02))
    d, n = local_distance(ell, [0.1, 0.05, 0.02], [0.0, 0.0, 0.05])
    assert d == pytest.approx(0.03) and n == pytest.approx([0, 0, 1])
    d, n = local_distance(ell, [0.1, 0.05, 0.02], [0.13, 0.0, 0.0])
    assert d == pytest.approx(0.03) and n == pytest.approx([1, 0, 0])
    assert local_distance(box, [0.01, 0.02, 0.03], [0.0, 0.0, 0.01])[0] == pytest.approx(-0.01)
    assert local_distance(box, [0.01, 0.02, 0.03], [0.04, 0.0, 0.0])[0] == pytest.approx(0.03)


# --------------------------------------------------------------------------- the hand


def _palm_frame(data, side):
    """(palm face centre PA, outward palm normal) in world coordinates."""
    body = data.body(f"palm_{side}")
    return data.site(f"PA_{side}").xpos.copy(), body.xmat.reshape(3, 3) @ np.array(
        DEFAULT_MAP.bones[f"palm_{side}"].nrm
    )


def _extent_along(model, data, g, origin, n) -> float:
    """How far the collision geom ``g`` reaches along ``n`` beyond the plane through
    ``origin`` [m] (capsules and spheres)."""
    c, r = data.geom_xpos[g], model.geom_size[g][0]
    if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE:
        return float((c - origin) @ n) + r
    ax = data.geom_xmat[g].reshape(3, 3)[:, 2] * model.geom_size[g][1]
    return max(float((c + s * ax - origin) @ n) for s in (-1, 1)) + r


@pytest.mark.parametrize("side", "LR")
def test_flat_thumb_lies_in_the_palm_plane(model, data, side):
    data.qpos[:] = _with_morphs(model, "flat")
    mujoco.mj_kinematics(model, data)
    pa, n = _palm_frame(data, side)
    for k in (1, 2, 3):
        for g in collision_geoms(model, model.body(f"thumb_{side}_{k}").id):
            reach = _extent_along(model, data, g, pa, n)
            assert -1e-3 <= reach <= 0.0, (k, reach)  # flush with the palm's face, not proud
    # along the radial edge: the tip beside the index finger's proximal phalanx, in the plane
    tip = data.site(f"T_TIP_{side}").xpos
    index = data.body(f"index_{side}_1").xpos
    along = data.body(f"palm_{side}").xmat.reshape(3, 3) @ np.array(
        DEFAULT_MAP.bones[f"palm_{side}"].dir
    )
    assert 0.02 < (tip - index) @ along < 0.05  # beside the proximal phalanx
    assert abs((tip - pa) @ n) < 0.012
    assert np.linalg.norm(np.cross(tip - index, along)) < 0.03


def test_fist_with_thumb_extended_has_a_straight_thumb(model, data):
    q = _with_morphs(model, "fist", "thumb_extended", side="R")
    for k in (2, 3):
        assert q[model.joint(f"thumb_R_{k}_flex").qposadr[0]] == pytest.approx(0.0, abs=1e-12)
    data.qpos[:] = q
    mujoco.mj_forward(model, data)
    base, tip = data.body("thumb_R_1").xpos, data.site("T_TIP_R").xpos
    mcp, ip = data.body("thumb_R_2").xpos, data.body("thumb_R_3").xpos
    for p in (mcp, ip):  # all on one line
        assert np.linalg.norm(np.cross(p - base, tip - base)) / np.linalg.norm(tip - base) < 1e-6
    assert all(c.dist >= -1e-4 for c in data.contact[: data.ncon])


@pytest.mark.parametrize("shape", ["hs_f", "hs_pinch"])
@pytest.mark.parametrize("side", "LR")
def test_pinch_handshapes_join_thumb_and_index_tips(model, data, shape, side):
    """The F and pinch hand shapes put the thumb's tip on the index's tip: within the
    default 1 mm, the two skins touching (within 0.1 mm) without penetrating."""
    data.qpos[:] = _with_morphs(model, shape, side=side)
    mujoco.mj_kinematics(model, data)
    gap = np.linalg.norm(data.site(f"T_TIP_{side}").xpos - data.site(f"I_TIP_{side}").xpos)
    assert gap < 1e-3
    thumb, index = (
        collision_geoms(model, model.body(f"{d}_{side}_3").id) for d in ("thumb", "index")
    )
    skin = min(mujoco.mj_geomDistance(model, data, a, b, 0.01, None) for a in thumb for b in index)
    assert 0.0 <= skin < 1e-4
    mujoco.mj_collision(model, data)
    assert all(c.dist >= 0.0 for c in data.contact[: data.ncon])


# --------------------------------------------------------------------------- contacts


def _hand_targets(shape: str, sides: str) -> list[cn.JointTarget]:
    return [
        cn.JointTarget(j, v)
        for s in sides
        for j, v in DEFAULT_MAP.morphs[shape].joint_changes(s).items()
    ]


def _free(sides: str) -> tuple[str, ...]:
    return tuple(j for s in sides for t in (f"arm_{s}", f"hand_{s}") for j in DEFAULT_MAP.tracks[t])


def _face_to_face(site: str, target: str) -> list:
    """``site`` on ``target`` with their outward normals opposed."""
    m = DEFAULT_MAP
    body = {
        "PA_R": "palm_R",
        "PA_L": "palm_L",
        "H_BACK_L": "palm_L",
        "CK_R": "head",
        "ST_R": "back_2",
        "ARM_L": "arm_L",
    }
    return [
        cn.Place(site, kin.SitePos(target)),
        cn.Orient(
            body[site], m.normals[site], cn.Rel.OPP, kin.BodyAxis(body[target], m.normals[target])
        ),
    ]


#: On the cheek the fingers point up (within 40 degrees), as signers place them: the palm's
#: heel then clears the eye.
FINGERS_UP = cn.Orient(
    "palm_R",
    DEFAULT_MAP.bones["palm_R"].dir,
    cn.Rel.ALONG,
    kin.Const((0.0, 0.0, 1.0)),
    tol=np.radians(40),
)


@pytest.mark.parametrize(
    "site, target, sides, extra",
    [
        ("PA_R", "PA_L", "RL", ()),
        ("PA_R", "H_BACK_L", "RL", ()),
        ("PA_R", "CK_R", "R", (FINGERS_UP,)),
        ("PA_R", "ST_R", "R", ()),
        ("PA_R", "ARM_L", "R", ()),
    ],
    ids=["palm-palm", "palm-back", "palm-cheek", "palm-chest", "palm-other-upper-arm"],
)
def test_flat_palm_contacts_meet_face_to_face(solver, site, target, sides, extra):
    """Flat hands, the body still (only the arms and hands move): the palm reaches the
    partner site face to face, with no penetration beyond the contact allowance."""
    cons = _face_to_face(site, target) + _hand_targets("flat", sides) + list(extra)
    res = solver.solve(ik.IKProblem(tuple(cons), free_joints=_free(sides)))
    assert res.converged, [(r.label, r.kind, r.value) for r in res.residuals if not r.ok]
    assert res.residuals[0].value < 1e-3 and res.residuals[1].value < np.radians(1)
    m, d = solver.model, solver.data
    d.qpos[:] = res.qpos
    mujoco.mj_forward(m, d)
    deepest = min([c.dist for c in d.contact[: d.ncon]] + [0.0])
    assert deepest >= -cn.CONTACT_ALLOWANCE - 1e-5
