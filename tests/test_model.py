"""The bundled signer model (azee_mj/mjcf/signer.xml) against its contract (signer.md)."""

from __future__ import annotations

import re

import mujoco
import numpy as np
import pytest

from azee_mj.face import face_bodies
from azee_mj.model import MODEL_PATH, SCENE_PATH, check_map
from azee_mj.sites import (
    ARM_R_ORIGIN,
    CLAV_R_ORIGIN,
    DEFAULT_MAP,
    DIGITS,
    FACE_JOINTS,
    FINGERS,
    LOCI,
    PHALANGES,
    azee_bone_names,
    azee_site_names,
)

HINGE, SLIDE = mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE
#: Morphs whose weight -1 is meaningful (and must stay inside the ranges too).
NEGATABLE = ("spine_extended", "smile", "mouth_down", "eyes_wide")
#: Morphs that undo part of another (morphs add, clipped to the ranges: score-format.md);
#: they stay inside the ranges on top of it.
ON_TOP_OF = {"thumb_extended": "fist"}


def _forward(model, data, qpos=None):
    if qpos is not None:
        data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    return data


def _home(model) -> np.ndarray:
    return model.key("home").qpos.copy()


def _twin(name: str) -> str | None:
    """The left twin of a right-side name (``EB_R`` -> ``EB_L``, ``R_KN_R_1`` -> ``R_KN_L_1``)."""
    if name == "Rssp":
        return "Lssp"
    m = re.search(r"_R(_\d)?$", name)
    if not m:
        return None
    return name[: m.start()] + "_L" + (m.group(1) or "")


def _random_posture(model, rng) -> np.ndarray:
    lo, hi = model.jnt_range[:, 0], model.jnt_range[:, 1]
    return lo + rng.random(model.njnt) * (hi - lo)  # every joint has one qpos entry


def _body(data, name):
    return data.body(name)


def _site(data, name):
    return data.site(name).xpos.copy()


def _unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


# --------------------------------------------------------------------------- compile, step


@pytest.mark.parametrize("path", [MODEL_PATH, SCENE_PATH], ids=["signer", "scene"])
@pytest.mark.parametrize("gravcomp", [True, False], ids=["gravcomp", "falling"])
@pytest.mark.parametrize("start", ["qpos0", "home"])
def test_compiles_and_steps_one_second_without_warnings(path, gravcomp, start):
    model = mujoco.MjModel.from_xml_path(str(path))
    assert model.opt.timestep == pytest.approx(0.002)
    assert np.linalg.norm(model.opt.gravity) > 9
    if not gravcomp:  # let the signer slump onto its joint limits and itself
        model.body_gravcomp[:] = 0
    data = mujoco.MjData(model)
    if start == "home":
        mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    for _ in range(round(1.0 / model.opt.timestep)):
        mujoco.mj_step(model, data)
    assert [w.number for w in data.warning] == [0] * len(data.warning)
    assert np.all(np.isfinite(data.qpos))


def test_counts(model):
    assert (model.nq, model.nv, model.njnt) == (120, 120, 120)
    # world + pelvis + 44 bones + the face rig: jaw, tongue and 9 pairs (upper and lower lids,
    # inner and outer brows, cheeks, nostrils, upper and lower lips, mouth corners)
    assert model.nbody == 1 + 1 + 44 + 2 + 2 * 9
    assert model.nu == 0
    assert model.nkey == 1


def test_gravity_compensated_rest_pose_holds_still(model, data):
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    q0 = data.qpos.copy()
    for _ in range(250):
        mujoco.mj_step(model, data)
    np.testing.assert_allclose(data.qpos, q0, atol=1e-6)


# --------------------------------------------------------------------------- names, joints


def test_every_name_of_the_default_map_exists(model):
    check_map(model, DEFAULT_MAP)
    for name in [*azee_site_names(), *LOCI]:
        assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name) >= 0, name
    bones = azee_bone_names()
    assert len(bones) == 44
    for name in bones:
        assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name) >= 0, name
    joints = {model.joint(j).name for j in range(model.njnt)}
    tracked = [j for t in DEFAULT_MAP.tracks.values() for j in t]
    assert sorted(tracked) == sorted(joints), "every joint belongs to exactly one track"


def test_root_is_fixed_pelvis_and_frames_are_world_aligned(model, data):
    _forward(model, data)
    pelvis = model.body("pelvis")
    assert pelvis.parentid[0] == 0 and pelvis.jntnum[0] == 0
    np.testing.assert_allclose(data.body("pelvis").xpos, 0, atol=1e-12)
    for b in range(1, model.nbody):
        np.testing.assert_allclose(model.body_quat[b], [1, 0, 0, 0], atol=1e-12)
        np.testing.assert_allclose(data.xmat[b].reshape(3, 3), np.eye(3), atol=1e-12)


def test_joints_are_limited_hinges_or_face_slides(model):
    for j in range(model.njnt):
        jnt = model.joint(j)
        assert model.jnt_limited[j], jnt.name
        lo, hi = model.jnt_range[j]
        assert lo < hi, jnt.name
        if jnt.name in FACE_JOINTS:  # the face rig slides and turns
            assert model.jnt_type[j] == SLIDE or model.jnt_type[j] == HINGE, jnt.name
        else:
            assert model.jnt_type[j] == HINGE, jnt.name
        # joint origin at the body origin (the bone's joint centre)
        np.testing.assert_allclose(model.jnt_pos[j], 0, atol=1e-12, err_msg=jnt.name)


@pytest.mark.parametrize(
    "joint, deg",
    [
        ("back_1_flex", (-15, 30)),
        ("back_2_lat", (-15, 15)),
        ("back_2_rot", (-18, 18)),
        ("neck_flex", (-40, 35)),
        ("neck_lat", (-25, 25)),
        ("neck_rot", (-45, 45)),
        ("head_flex", (-30, 25)),
        ("head_lat", (-20, 20)),
        ("head_rot", (-25, 25)),
        ("eye_R_yaw", (-46, 47)),
        ("eye_L_yaw", (-47, 46)),
        ("eye_L_pitch", (-32, 48)),
        ("clav_L_elev", (-10, 40)),
        ("clav_R_prot", (-25, 25)),
        ("arm_R_flex", (-60, 180)),
        ("arm_L_abd", (-45, 180)),
        ("arm_R_rot", (-90, 70)),
        ("f_arm_L_flex", (0, 150)),
        ("f_arm_R_pron", (-80, 80)),
        ("palm_R_flex", (-70, 80)),
        ("palm_L_dev", (-30, 20)),
        ("index_R_1_flex", (-30, 90)),
        ("index_L_1_spread", (-15, 25)),
        ("middle_R_1_spread", (-15, 15)),
        ("ring_L_1_spread", (-20, 10)),
        ("little_R_1_spread", (-30, 10)),
        ("ring_R_2_flex", (0, 100)),
        ("little_L_3_flex", (0, 90)),
        ("thumb_R_1_flex", (-25, 35)),
        ("thumb_L_1_abd", (0, 70)),
        ("thumb_R_2_flex", (0, 60)),
        ("thumb_L_3_flex", (-20, 80)),
    ],
)
def test_joint_ranges(model, joint, deg):
    np.testing.assert_allclose(model.joint(joint).range, np.radians(deg), atol=1e-9)


def test_face_ranges(model):
    np.testing.assert_allclose(model.joint("lid_R_close").range, np.radians([-25, 75]))
    np.testing.assert_allclose(model.joint("lid_low_L_raise").range, np.radians([-10, 40]))
    np.testing.assert_allclose(model.joint("tongue_out").range, [0.0, 0.030])
    np.testing.assert_allclose(model.joint("cheek_R_puff").range, [0.0, 0.010])
    np.testing.assert_allclose(model.joint("brow_L_raise").range, [-0.006, 0.012])
    np.testing.assert_allclose(model.joint("brow_R_knit").range, [0.0, 0.008])
    np.testing.assert_allclose(model.joint("mouth_L_up").range, [-0.008, 0.008])
    assert model.joint("jaw_open").range[1] >= 0.3


def test_rest_and_home_are_inside_every_range(model):
    lo, hi = model.jnt_range.T
    for q in (model.qpos0, _home(model)):
        assert np.all(q >= lo) and np.all(q <= hi)
    home = _home(model)
    assert home[model.joint("f_arm_R_flex").qposadr[0]] == pytest.approx(0.15, abs=0.05)
    assert home[model.joint("arm_L_abd").qposadr[0]] > 0.05


@pytest.mark.parametrize("morph", sorted(DEFAULT_MAP.morphs))
def test_morphs_stay_inside_the_ranges(model, morph):
    changes = DEFAULT_MAP.morphs[morph].joint_changes(None)
    weights = (1.0, -1.0) if morph in NEGATABLE else (1.0,)
    for w in weights:
        q = model.qpos0.copy()
        if morph in ON_TOP_OF:
            for joint, v in DEFAULT_MAP.morphs[ON_TOP_OF[morph]].joint_changes(None).items():
                q[model.joint(joint).qposadr[0]] += v
        for joint, v in changes.items():
            q[model.joint(joint).qposadr[0]] += w * v
        for joint in changes:
            j = model.joint(joint).id
            lo, hi = model.jnt_range[j]
            assert lo <= q[model.jnt_qposadr[j]] <= hi, (morph, w, joint)


# --------------------------------------------------------------------------- geometry


def test_dimensions(model, data):
    _forward(model, data)
    x = lambda b: data.body(b).xpos
    np.testing.assert_allclose(x("clav_R"), CLAV_R_ORIGIN, atol=1e-12)
    np.testing.assert_allclose(x("arm_R"), ARM_R_ORIGIN, atol=1e-12)
    assert x("arm_L")[1] - x("arm_R")[1] == pytest.approx(0.36)
    assert x("arm_R")[2] == pytest.approx(0.48)
    assert np.linalg.norm(x("f_arm_R") - x("arm_R")) == pytest.approx(0.316)
    assert np.linalg.norm(x("palm_R") - x("f_arm_R")) == pytest.approx(0.248)
    assert np.linalg.norm(_site(data, "M_TIP_R") - x("palm_R")) == pytest.approx(0.184, abs=1e-5)
    assert 0.78 <= _site(data, "HEAD")[2] <= 0.82
    # Buchholz (1992) phalanx lengths as fractions of the hand length
    for f, fr in {"index": (0.265, 0.143), "middle": (0.277, 0.170)}.items():
        for n, frac in zip((1, 2), fr):
            seg = np.linalg.norm(x(f"{f}_R_{n + 1}") - x(f"{f}_R_{n}"))
            assert seg == pytest.approx(frac * 0.184, abs=1e-5)
    thumb_distal = np.linalg.norm(_site(data, "T_TIP_R") - x("thumb_R_3"))
    assert thumb_distal == pytest.approx(0.158 * 0.184, abs=1e-5)


def _bone_checks(data):
    """Pairs (bone, kind, geometric direction) with kind 'dir' or 'nrm'."""
    x = lambda b: data.body(b).xpos
    s = lambda n: _site(data, n)
    out = [
        ("back_1", "dir", x("back_2") - x("back_1")),
        ("back_2", "dir", x("neck") - x("back_2")),
        ("neck", "dir", x("head") - x("neck")),
    ]
    for side in "LR":
        out += [
            (f"clav_{side}", "dir", x(f"arm_{side}") - x(f"clav_{side}")),
            (f"arm_{side}", "dir", x(f"f_arm_{side}") - x(f"arm_{side}")),
            (f"f_arm_{side}", "dir", x(f"palm_{side}") - x(f"f_arm_{side}")),
            (f"f_arm_{side}", "nrm", s(f"F_ARMi_{side}") - s(f"F_ARM_{side}")),
            (f"palm_{side}", "dir", x(f"middle_{side}_1") - x(f"palm_{side}")),
            (f"palm_{side}", "nrm", s(f"PA_{side}") - s(f"H_BACK_{side}")),
        ]
        for letter, digit in DIGITS.items():
            for n in PHALANGES:
                bone = f"{digit}_{side}_{n}"
                nxt = x(f"{digit}_{side}_{n + 1}") if n < 3 else s(f"{letter}_TIP_{side}")
                out.append((bone, "dir", nxt - x(bone)))
                knuckle = s(f"{letter}_KN_{side}_{n}")
                out.append((bone, "nrm", s(f"{letter}_KNi_{side}_{n}") - knuckle))
    return out


@pytest.mark.parametrize("posture", ["qpos0", "random0", "random1", "random2"])
def test_dir_and_nrm_agree_with_the_geometry(model, data, posture):
    q = model.qpos0.copy()
    if posture != "qpos0":
        q = _random_posture(model, np.random.default_rng(int(posture[-1])))
    _forward(model, data, q)
    checked = set()
    for bone, kind, geo in _bone_checks(data):
        b = DEFAULT_MAP.bones[bone]
        vec = np.asarray(b.dir if kind == "dir" else b.nrm)
        world = data.body(b.body).xmat.reshape(3, 3) @ vec
        np.testing.assert_allclose(world, _unit(geo), atol=1e-3, err_msg=f"{bone} {kind}")
        checked.add(bone)
    assert len(checked) == 41  # all bones but head and the eyes (checked below)
    for bone, b in DEFAULT_MAP.bones.items():
        if not bone.startswith("clav"):  # the clavicle runs back; its NRM is plain forward
            assert abs(np.dot(b.dir, b.nrm)) < 1e-6, bone
        assert np.linalg.norm(b.dir) == pytest.approx(1, abs=1e-5)


def test_head_and_eyes_face_forward(model, data):
    _forward(model, data)
    for eye in ("eye_L", "eye_R"):
        b = DEFAULT_MAP.bones[eye]
        world = data.body(eye).xmat.reshape(3, 3) @ b.dir
        np.testing.assert_allclose(world, [1, 0, 0], atol=1e-9)
        site = _site(data, "EYE_" + eye[-1])
        d = site - data.body(eye).xpos
        assert d[0] > 0.01 and np.linalg.norm(d[1:]) < 1e-3
    np.testing.assert_allclose(DEFAULT_MAP.bones["head"].nrm, [1, 0, 0])
    assert _site(data, "NO")[0] > _site(data, "BEB")[0] + 0.15


def _sites_on(model, body):
    bid = model.body(body).id
    return [model.site(i).name for i in range(model.nsite) if model.site_bodyid[i] == bid]


@pytest.mark.parametrize("posture", ["qpos0", "home"])
def test_left_right_mirror_symmetry(model, data, posture):
    _forward(model, data, model.qpos0 if posture == "qpos0" else _home(model))
    names = [model.site(i).name for i in range(model.nsite)]
    pairs = 0
    for n in names:
        t = _twin(n)
        p = _site(data, n)
        if t is not None:
            q = _site(data, t)
            np.testing.assert_allclose(q, p * [1, -1, 1], atol=1e-3, err_msg=n)
            pairs += 1
        elif not re.search(r"_L(_\d)?$", n) and n != "Lssp":
            assert abs(p[1]) < 1e-9, n  # midline
    assert pairs == (len(names) - 13 - 1) // 2  # 13 midline sites, ssp
    for b in range(model.nbody):
        t = _twin(model.body(b).name)
        if t:
            np.testing.assert_allclose(data.body(t).xpos, data.xpos[b] * [1, -1, 1], atol=1e-9)


def test_mirrored_joints_give_mirrored_motion(model, data):
    """Equal angles on both sides (and a sagittal spine) give an exactly mirrored signer."""
    rng = np.random.default_rng(7)
    q = _random_posture(model, rng)
    for j in range(model.njnt):
        name = model.joint(j).name
        if re.fullmatch(r"(back_\d|neck|head)_(lat|rot)|eye_._yaw", name):
            q[model.jnt_qposadr[j]] = 0.0  # non-sagittal midline motions
    for j in range(model.njnt):
        name = model.joint(j).name
        if re.match(r"(.*)_L(_.*)?$", name):
            right = name.replace("_L", "_R", 1)
            q[model.jnt_qposadr[j]] = q[model.joint(right).qposadr[0]]
    _forward(model, data, q)
    for i in range(model.nsite):
        t = _twin(model.site(i).name)
        if t:
            np.testing.assert_allclose(_site(data, t), data.site_xpos[i] * [1, -1, 1], atol=1e-9)


def test_sites_sit_on_their_body_part(model):
    expect = {
        "head": ["HEAD", "FH", "NO", "NSP", "MO", "BEB", "EB_R", "EYE_R", "EAR_L", "MO_L"],
        "jaw": ["CH", "TO"],
        "neck": ["NK", "NK_R"],
        "back_2": ["ST", "ST_L", "ssp", "Rssp"],
        "back_1": ["AB", "AB_R"],
        "pelvis": ["ABST", "ABST_L"],
        "clav_R": ["SH_R"],
        "arm_R": ["ARM_R", "ARMsh_R", "ELi_R", "ARMpit_R"],
        "f_arm_L": ["EL_L", "F_ARM_L", "F_ARMi_L", "WR_L", "WRt_L", "WRi_L"],
        "palm_R": ["PA_R", "H_BACK_R", "H_EDGE_R", "viande_R"],
        "index_R_3": ["I_TIP_R", "I_PAD_R", "I_NA_R", "I_KN_R_3"],
        "thumb_L_1": ["T_KNi_L_1"],
    }
    for body, sites in expect.items():
        on = set(_sites_on(model, body))
        assert set(sites) <= on, (body, set(sites) - on)


def test_site_placement(model, data):
    _forward(model, data)
    s = lambda n: _site(data, n)
    np.testing.assert_allclose(s("WR_R"), data.body("palm_R").xpos, atol=1e-12)
    np.testing.assert_allclose(s("ssp"), [0.32, 0, 0.33], atol=0.02)
    np.testing.assert_allclose(s("Lssp") - s("ssp"), [0, 0.2, 0], atol=1e-9)
    elbow = data.body("f_arm_R").xpos
    assert s("EL_R")[0] < elbow[0] - 0.02 and s("EL_R")[2] > elbow[2]  # olecranon: behind, above
    assert s("ELi_R")[0] > elbow[0] + 0.02
    assert s("PA_R")[1] > s("H_BACK_R")[1]  # the right palm faces +y (the midline)
    assert s("H_EDGE_R")[0] < s("PA_R")[0] - 0.03  # little-finger edge is at the back
    for f in "IMRL":
        tip, pad, na = s(f"{f}_TIP_R"), s(f"{f}_PAD_R"), s(f"{f}_NA_R")
        assert pad[1] > na[1] and tip[2] < pad[2]
    assert s("ST")[0] > 0.05 and s("NK")[2] < s("CH")[2] < s("MO")[2] < s("NO")[2] < s("FH")[2]


# --------------------------------------------------------------------------- sign conventions


def _delta(model, data, joint, site=None, body=None, amount=0.3, base=None):
    q = model.qpos0.copy() if base is None else base.copy()
    get = (lambda: _site(data, site)) if site else (lambda: data.body(body).xpos.copy())
    _forward(model, data, q)
    p0 = get()
    q[model.joint(joint).qposadr[0]] += amount
    _forward(model, data, q)
    return get() - p0


@pytest.mark.parametrize("side", "LR")
def test_arm_sign_conventions(model, data, side):
    out = 1 if side == "L" else -1  # lateral direction (+y for the left side)
    d = lambda j, **k: _delta(model, data, j.format(X=side), **k)
    assert d("clav_{X}_elev", body=f"arm_{side}")[2] > 0.005
    assert d("clav_{X}_prot", body=f"arm_{side}")[0] > 0.005
    assert d("arm_{X}_flex", body=f"f_arm_{side}")[0] > 0.05
    assert out * d("arm_{X}_abd", body=f"f_arm_{side}")[1] > 0.05
    bent = model.qpos0.copy()
    bent[model.joint(f"f_arm_{side}_flex").qposadr[0]] = np.pi / 2
    assert out * d("arm_{X}_rot", body=f"palm_{side}", base=bent)[1] < -0.05  # internal: inward
    assert d("f_arm_{X}_flex", body=f"palm_{side}")[0] > 0.05
    # pronation turns the palm (facing the midline at rest) backward
    q = model.qpos0.copy()
    q[model.joint(f"f_arm_{side}_pron").qposadr[0]] = 1.0
    _forward(model, data, q)
    nrm = _site(data, f"PA_{side}") - _site(data, f"H_BACK_{side}")
    assert nrm[0] < 0
    assert -out * d("palm_{X}_flex", site=f"M_TIP_{side}")[1] > 0.01  # toward the palm side
    assert d("palm_{X}_dev", site=f"M_TIP_{side}")[0] > 0.01  # toward the thumb (+x)


@pytest.mark.parametrize("side", "LR")
def test_hand_sign_conventions(model, data, side):
    out = 1 if side == "L" else -1
    d = lambda j, **k: _delta(model, data, j.format(X=side), **k)
    for f, letter in zip(FINGERS, "IMRL"):
        tip = f"{letter}_TIP_{side}"
        for n in PHALANGES:
            assert -out * d(f"{f}_{{X}}_{n}_flex", site=tip)[1] > 0.002, (f, n)
        assert d(f"{f}_{{X}}_1_spread", site=tip, amount=0.1)[0] > 0.002, f
    tip = f"T_TIP_{side}"
    assert d("thumb_{X}_1_flex", site=tip)[0] < -0.01  # across the palm, toward the little finger
    assert -out * d("thumb_{X}_1_abd", site=tip)[1] > 0.01  # away from the palm, palmar side
    nrm_world = np.array(DEFAULT_MAP.bones[f"thumb_{side}_3"].nrm)
    for n in (2, 3):
        assert np.dot(d(f"thumb_{{X}}_{n}_flex", site=tip), nrm_world) > 0.003  # toward the pad


def test_midline_and_face_sign_conventions(model, data):
    d = lambda j, **k: _delta(model, data, j, **k)
    for stem in ("back_1", "back_2", "neck", "head"):
        assert d(f"{stem}_flex", site="HEAD")[0] > 0.005, stem
        assert d(f"{stem}_lat", site="HEAD")[1] > 0.005, stem
        assert d(f"{stem}_rot", site="NO")[1] > 0.005, stem
    assert d("jaw_open", site="CH")[2] < -0.005
    for side in "LR":
        eye = data.body(f"eye_{side}")
        for joint, axis, sign in (("yaw", 1, 1), ("pitch", 2, -1)):
            q = model.qpos0.copy()
            q[model.joint(f"eye_{side}_{joint}").qposadr[0]] = 0.3
            _forward(model, data, q)
            gaze = eye.xmat.reshape(3, 3) @ DEFAULT_MAP.bones[f"eye_{side}"].dir
            assert sign * gaze[axis] > 0.2, (side, joint)
        toward_mid = -1 if side == "L" else 1
        assert d(f"brow_{side}_raise", body=f"brow_{side}", amount=0.005)[2] > 0.004
        assert toward_mid * d(f"brow_{side}_knit", body=f"brow_{side}", amount=0.005)[1] > 0.004
        assert d(f"mouth_{side}_up", body=f"mouth_{side}", amount=0.005)[2] > 0.004
        # closing the lid brings its margin (the lash line) down over the eye
        lid = model.body(f"lid_{side}")
        g = max(i for i in range(model.ngeom) if model.geom_bodyid[i] == lid.id)
        _forward(model, data)
        p0 = data.geom_xpos[g].copy()
        q = model.qpos0.copy()
        q[model.joint(f"lid_{side}_close").qposadr[0]] = 1.0
        _forward(model, data, q)
        assert data.geom_xpos[g][2] < p0[2] - 0.008


# --------------------------------------------------------------------------- collisions


def _penetrations(model, data):
    bn = lambda g: model.body(model.geom_bodyid[g]).name
    return [
        (bn(c.geom1), bn(c.geom2), round(float(c.dist), 5))
        for c in data.contact[: data.ncon]
        if c.dist < -1e-4
    ]


@pytest.mark.parametrize("posture", ["qpos0", "home"])
def test_no_penetration_at_rest(model, data, posture):
    _forward(model, data, model.qpos0 if posture == "qpos0" else _home(model))
    assert _penetrations(model, data) == []


def test_collision_and_visual_geoms(model):
    collide = lambda g: model.geom_contype[g] or model.geom_conaffinity[g]
    for g in range(model.ngeom):
        if collide(g):
            assert model.geom_group[g] == 3
        else:
            assert model.geom_group[g] == 2
    bodies_with = {model.geom_bodyid[g] for g in range(model.ngeom) if collide(g)}
    face = {model.body(b).name for b in face_bodies(model)} - {"jaw"}
    for b in range(1, model.nbody):
        name = model.body(b).name
        assert (b in bodies_with) == (name not in face), name


def test_excludes_are_between_close_relatives(model):
    parent = model.body_parentid
    for i in range(model.nexclude):
        b1, b2 = divmod(int(model.exclude_signature[i]), 1 << 16)
        assert (
            parent[b1] == b2
            or parent[b2] == b1
            or parent[parent[b2]] == b1
            or (parent[parent[b1]] == b2)
        )
    assert model.nexclude <= 4


@pytest.mark.parametrize(
    "pair, joints",
    [
        (
            ("palm_R", "head"),
            {"arm_R_flex": 1.5, "arm_R_abd": -0.3, "arm_R_rot": 1.0, "f_arm_R_flex": 2.3},
        ),
        (
            ("palm_R", "jaw"),
            {"arm_R_flex": 1.2, "arm_R_abd": -0.3, "arm_R_rot": 1.0, "f_arm_R_flex": 2.3},
        ),
        (("palm_R", "back_2"), {"arm_R_rot": 1.2, "f_arm_R_flex": 2.0}),
        (
            ("palm_L", "palm_R"),
            {
                "arm_R_flex": 1.0,
                "arm_L_flex": 1.0,
                "arm_R_rot": 0.75,
                "arm_L_rot": 0.75,
                "f_arm_R_flex": 0.8,
                "f_arm_L_flex": 0.8,
            },
        ),
        (("arm_R", "back_2"), {"arm_R_abd": -0.4}),
    ],
)
def test_body_contacts_are_detected(model, data, pair, joints):
    q = model.qpos0.copy()
    for j, v in joints.items():
        q[model.joint(j).qposadr[0]] = v
    _forward(model, data, q)
    bodies = {frozenset(p[:2]) for p in _penetrations(model, data)}
    bodies |= {
        frozenset(
            (
                model.body(model.geom_bodyid[c.geom1]).name,
                model.body(model.geom_bodyid[c.geom2]).name,
            )
        )
        for c in data.contact[: data.ncon]
    }
    assert frozenset(pair) in bodies, sorted(tuple(sorted(b)) for b in bodies)


@pytest.mark.parametrize(
    "morph",
    [
        "fist",
        "flat",
        "thumb_opposed",
        "thumb_bend",
        "index_hook",
        "fingers_spread",
        "jaw_open",
        "shoulder_shrug",
    ],
)
def test_hand_and_face_morphs_are_free_of_penetration(model, data, morph):
    """Each morph's full change, as target values from the rest pose, keeps the body whole."""
    q = model.qpos0.copy()
    for joint, v in DEFAULT_MAP.morphs[morph].joint_changes(None).items():
        q[model.joint(joint).qposadr[0]] = v
    _forward(model, data, q)
    assert _penetrations(model, data) == []


@pytest.mark.parametrize("morph", ["fingers_spread", "flat"])
def test_open_hand_morphs_from_home_at_any_weight_are_free_of_penetration(model, data, morph):
    """A morph's targets at weights 0.1 to 1 from ``home``, the posture a key starts from
    (the joints the morph does not name stay there): the body stays whole. The spread
    hand's thumb, abducted 0.24 to 0.32 rad from home's 0.05 rad of base flexion, sank its
    proximal phalanx up to 0.19 mm into the palm's edge; it now spreads in the palm plane."""
    for w in np.linspace(0.1, 1.0, 10):
        q = _home(model)
        for joint, v in DEFAULT_MAP.morphs[morph].joint_changes("R").items():
            jid = model.joint(joint).id
            adr = model.jnt_qposadr[jid]
            q[adr] = np.clip(model.qpos0[adr] + w * v, *model.jnt_range[jid])
        _forward(model, data, q)
        assert _penetrations(model, data) == [], f"weight {w:.1f}"
