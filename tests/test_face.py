"""The face rig on the real model: the 52 ARKit shapes, their mirror symmetry, no part of the
face through another, and what a viewer sees (eyelid and lip apertures, the cheek's bulge)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from azee_mj import arkit, face
from azee_mj.model import load_model
from azee_mj.schedule import make_solver
from azee_mj.score import load_score
from azee_mj.sites import DEFAULT_MAP, FACE_JOINTS, azee_site_names


@pytest.fixture(scope="module")
def model() -> mujoco.MjModel:
    return load_model()


def _at(model, weights) -> mujoco.MjData:
    d = mujoco.MjData(model)
    d.qpos[:] = face.morph_posture(model, weights)
    mujoco.mj_kinematics(model, d)
    return d


def _rest(model):
    return face.morph_posture(model, {})


#: What each shape must do at weight 1, measured on the model: (measure, lower bound) [m].
#: ``"lids_R"``: the right eyelid aperture at most the bound; ``"lips"``: the lip aperture
#: at least; ``"cheek_R"``: the cheek bulge at least; otherwise the body that must move
#: at least the bound.
EXPECTED = {
    "eyeBlink": ("lids", 0.0),
    "eyeLookDown": ("eye", 0.003),
    "eyeLookIn": ("eye", 0.003),
    "eyeLookOut": ("eye", 0.003),
    "eyeLookUp": ("eye", 0.003),
    "eyeSquint": ("lid_low", 0.002),
    "eyeWide": ("lid", 0.002),
    "jaw": ("jaw", 0.005),
    "mouth": ("mouth", 0.005),
    "mouthSmile": ("mouth", 0.008),
    "mouthFrown": ("mouth", 0.005),
    "mouthDimple": ("mouth", 0.004),
    "mouthStretch": ("mouth", 0.006),
    "mouthPress": ("lip_up", 0.0015),
    "mouthLowerDown": ("lip_low", 0.005),
    "mouthUpperUp": ("lip_up", 0.004),
    "browDown": ("brow", 0.004),
    "browOuterUp": ("brow_out", 0.004),
    "cheekSquint": ("cheek", 0.004),
    "noseSneer": ("nose", 0.003),
}
BOTH_EXPECTED = {
    "browInnerUp": ("brow", 0.006),
    "cheekPuff": ("cheek_R", 0.005),
    "jawOpen": ("lips", 0.015),
    "jawForward": ("jaw", 0.004),
    "mouthClose": ("lip_low", 0.0015),
    "mouthFunnel": ("lips", 0.008),
    "mouthPucker": ("mouth", 0.010),
    "mouthRollLower": ("lip_low", 0.004),
    "mouthRollUpper": ("lip_up", 0.004),
    "mouthShrugLower": ("lip_low", 0.003),
    "mouthShrugUpper": ("lip_up", 0.002),
    "tongueOut": ("tongue", 0.02),
}


def test_the_52_shapes_are_morphs_with_sided_bases():
    assert len(arkit.ARKIT_SHAPES) == len(set(arkit.ARKIT_SHAPES)) == 52
    for name in arkit.ARKIT_SHAPES:
        assert name in DEFAULT_MAP.morphs and not DEFAULT_MAP.morphs[name].sided, name
        for side, suffix in (("L", "Left"), ("R", "Right")):
            if name.endswith(suffix):
                base = DEFAULT_MAP.morphs[name[: -len(suffix)]]
                assert base.sided
                assert base.joint_changes(side) == DEFAULT_MAP.morphs[name].joint_changes(None)
    assert set(EXPECTED) == set(arkit.SIDED) and set(BOTH_EXPECTED) == set(arkit.BOTH)


def test_face_joints_are_the_face_track_and_only_morphs_move_them(model):
    names = {model.joint(j).name for j in range(model.njnt)}
    assert set(FACE_JOINTS) <= names
    tracked = {j for t in DEFAULT_MAP.tracks.values() for j in t}
    assert names == tracked  # every joint belongs to a track
    # a placement of the hand on the mouth frees no face joint
    solver = make_solver()
    score = load_score(
        {
            "format": "azee-score",
            "version": 1,
            "strong_side": "R",
            "root": {
                "name": "K",
                "kind": "cstr",
                "start": 0,
                "end": 0.5,
                "constraints": [{"type": "place", "site": "@I_TIP(s)", "at": "@MO"}],
            },
        }
    )
    from azee_mj.schedule import Schedule

    sched = Schedule(score, solver)
    for dc in sched.block_constraints(score.root):
        assert "face" not in dc.tracks


def _measure(model, what, weights, rest_depth):
    d = _at(model, weights)
    if what == "lids":
        return max(face.eyelid_aperture(model, d, s) for s in "LR")
    if what == "lips":
        return face.lip_aperture(model, d)
    if what.startswith("cheek_"):
        return face.cheek_bulge(model, d, what[-1], rest_depth[what[-1]])
    return None


@pytest.mark.parametrize("name", arkit.ARKIT_SHAPES)
def test_each_shape_moves_its_geometry_by_the_stated_amount(model, name):
    base, side = name, None
    for s, suffix in (("L", "Left"), ("R", "Right")):
        if name.endswith(suffix) and name[: -len(suffix)] in arkit.SIDED:
            base, side = name[: -len(suffix)], s
    what, bound = (EXPECTED if side else BOTH_EXPECTED)[base]
    d0 = _at(model, {})
    rest_depth = {s: face.skin_depth(model, d0, s) for s in "LR"}
    if what in ("lids", "lips") or what.startswith("cheek_"):
        if what == "lids":  # the blinking eye shuts, the other stays open
            d = _at(model, {name: 1.0})
            assert face.eyelid_aperture(model, d, side) == 0.0
            assert face.eyelid_aperture(model, d, "L" if side == "R" else "R") > 0.009
        else:
            assert _measure(model, what, {name: 1.0}, rest_depth) >= bound
        return
    moved = face.displacement(model, _rest(model), face.morph_posture(model, {name: 1.0}))
    body = what if what in ("jaw", "tongue") else f"{what}_{side or 'R'}"
    assert moved.by_body[body] >= bound, (body, moved.by_body[body])


def test_rest_face_is_open_eyed_with_closed_lips(model):
    d = _at(model, {})
    for s in "LR":
        assert 0.009 < face.eyelid_aperture(model, d, s) < 0.013
    assert face.lip_aperture(model, d) < 0.0025  # a thin mouth line
    assert face.lip_aperture(model, _at(model, {"mouthClose": 1.0})) == 0.0
    assert face.eyelid_aperture(model, _at(model, {"eyeWideRight": 1.0}), "R") > 0.014


def _mirror_geom(model) -> np.ndarray:
    """Each geom's mirror twin: the geom of the same type and size whose place at rest is
    its mirror image."""
    d = _at(model, {})
    mirrored = d.geom_xpos * np.array([1.0, -1.0, 1.0])
    out = np.empty(model.ngeom, int)
    for g in range(model.ngeom):
        same = (model.geom_type == model.geom_type[g]) & np.all(
            np.isclose(model.geom_size, model.geom_size[g]), axis=1
        )
        dist = np.where(same, np.linalg.norm(d.geom_xpos - mirrored[g], axis=1), np.inf)
        out[g] = int(np.argmin(dist))
        assert dist[out[g]] < 1e-9, model.body(model.geom_bodyid[g]).name
    return out


@pytest.mark.parametrize("base", sorted(arkit.SIDED))
def test_left_is_the_mirror_of_right(model, base):
    twin = _mirror_geom(model)
    left, right = _at(model, {base + "Left": 1.0}), _at(model, {base + "Right": 1.0})
    mirrored = right.geom_xpos[twin] * np.array([1.0, -1.0, 1.0])
    np.testing.assert_allclose(left.geom_xpos, mirrored, atol=1e-9)


#: Pairs of face parts that move against each other and must not pass through each other.
def _pairs(model):
    body = lambda n: model.body(n).id
    pairs = []
    for a in ("L", "R"):
        for b in ("L", "R"):
            pairs.append((f"lip_up_{a}", f"lip_low_{b}"))
        pairs += [("tongue", f"lip_up_{a}"), ("tongue", f"lip_low_{a}")]
        pairs += [(f"brow_{a}", f"lid_{a}"), (f"brow_out_{a}", f"lid_{a}")]
        pairs += [(f"mouth_{a}", f"cheek_{a}"), (f"lip_up_{a}", f"nose_{a}")]
    geoms = lambda n: [g for g in range(model.ngeom) if model.geom_bodyid[g] == body(n)]
    return [(ga, gb) for a, b in pairs for ga in geoms(a) for gb in geoms(b)]


#: Combinations a face makes (expressions, mouthing): no part through another either.
COMBINED = [
    {"jawOpen": 1.0, "mouthClose": 1.0},
    {"mouthSmileLeft": 1.0, "mouthSmileRight": 1.0, "cheekSquintLeft": 1.0, "eyeSquintLeft": 1.0},
    {"browInnerUp": 1.0, "eyeWideLeft": 1.0, "eyeWideRight": 1.0, "jawOpen": 0.6},
    {"browDownLeft": 1.0, "browDownRight": 1.0, "mouthPressLeft": 1.0, "noseSneerRight": 1.0},
    {"mouthPucker": 1.0, "cheekPuff": 1.0},
    {"mouthFunnel": 1.0, "jawOpen": 0.5},
    {"tongueOut": 1.0, "jawOpen": 0.5},
    {"eyeBlinkLeft": 1.0, "eyeBlinkRight": 1.0, "browDownLeft": 1.0},
    {"mouthFrownLeft": 1.0, "mouthFrownRight": 1.0, "browInnerUp": 1.0},
    {"mouthLeft": 1.0, "jawLeft": 1.0},
    {"mouthRollLower": 1.0, "mouthRollUpper": 1.0},
    {"mouthShrugLower": 1.0, "mouthShrugUpper": 1.0},
]


@pytest.mark.parametrize(
    "weights", [{n: 1.0} for n in arkit.ARKIT_SHAPES] + COMBINED, ids=lambda w: "+".join(w)
)
def test_no_face_part_passes_through_another(model, weights):
    """Parts that overlap at rest (the lips where they meet at the corners) overlap no more
    than at rest; the others stay apart."""
    rest, d = _at(model, {}), _at(model, weights)
    for ga, gb in _pairs(model):
        at_rest = mujoco.mj_geomDistance(model, rest, ga, gb, 0.01, None)
        dist = mujoco.mj_geomDistance(model, d, ga, gb, 0.01, None)
        names = [model.body(model.geom_bodyid[g]).name for g in (ga, gb)]
        if names[0].startswith("lip_up") and names[1].startswith("lip_low"):
            continue  # lips meet: see test_lips_meet_but_never_cross
        assert dist > min(at_rest, 0.0) - 2e-4, (names, dist, at_rest)


#: How far the rigid lip capsules may overlap where soft lips press together [m].
LIP_CONTACT = 0.0075


@pytest.mark.parametrize(
    "weights", [{n: 1.0} for n in arkit.ARKIT_SHAPES] + COMBINED, ids=lambda w: "+".join(w)
)
def test_lips_meet_but_never_cross(model, weights):
    """Pressed lips flatten against each other (the capsules standing for them overlap by
    at most LIP_CONTACT); the upper lip's middle stays above the lower lip's."""
    d = _at(model, weights)
    for a in "LR":
        for b in "LR":
            for ga in np.flatnonzero(model.geom_bodyid == model.body(f"lip_up_{a}").id):
                for gb in np.flatnonzero(model.geom_bodyid == model.body(f"lip_low_{b}").id):
                    assert mujoco.mj_geomDistance(model, d, ga, gb, 0.01, None) > -LIP_CONTACT
        up, low = (model.body(f"lip_{w}_{a}").id for w in ("up", "low"))
        assert d.xpos[up][2] > d.xpos[low][2] + 0.002


def test_face_parts_do_not_collide_and_sites_stay_put(model):
    """The moving face shows only (no contacts of its own); the skin sites of the face keep
    their places on the head and jaw."""
    for b in face.face_bodies(model):
        name = model.body(b).name
        if name == "jaw":
            continue
        gs = np.flatnonzero(model.geom_bodyid == b)
        assert not np.any(model.geom_contype[gs] | model.geom_conaffinity[gs]), name
    sites = {model.site(s).name for s in range(model.nsite)}
    assert set(azee_site_names()) <= sites


def test_morph_posture_sums_and_clips(model):
    q = face.morph_posture(model, {"jawOpen": 0.5, "tongueOut": 1.0})
    adr = model.joint("jaw_open").qposadr[0]
    assert q[adr] == pytest.approx(
        0.5 * arkit.BOTH["jawOpen"]["jaw_open"] + arkit.BOTH["tongueOut"]["jaw_open"]
    )
    q = face.morph_posture(model, {"eyeBlinkRight": 3.0})
    assert q[model.joint("lid_R_close").qposadr[0]] == pytest.approx(
        model.joint("lid_R_close").range[1]
    )
    q = face.morph_posture(model, {"eyeBlink:R": 1.0})
    assert q[model.joint("lid_R_close").qposadr[0]] == arkit.SIDED["eyeBlink"]["lid_{X}_close"]
    assert q[model.joint("lid_L_close").qposadr[0]] == 0.0


# --------------------------------------------------------------------------- rendered


def _segmented(model, fr, weights, geoms) -> tuple[int, np.ndarray]:
    """Pixels of the face camera showing one of ``geoms`` (segmentation), and the colour
    image, for the face at ``weights``."""
    q = face.morph_posture(model, weights)
    image = fr.render(q)
    fr.r.enable_segmentation_rendering()
    try:
        seg = fr.draw(q)
    finally:
        fr.r.disable_segmentation_rendering()
    # segmentation ids are the scene model's geom ids: the signer's come first
    mask = np.isin(seg[..., 0], list(geoms)) & (seg[..., 1] == int(mujoco.mjtObj.mjOBJ_GEOM))
    return int(mask.sum()), image, mask


def test_a_blink_hides_the_iris_and_an_open_mouth_shows_a_dark_opening(model, gl):
    from azee_mj.render import FrameRenderer

    with FrameRenderer(camera="face", size=(640, 480), antialias=False) as fr:
        scene = fr.model  # segmentation gives the scene's geom ids (the floor comes first)
        iris_mat = mujoco.mj_name2id(scene, mujoco.mjtObj.mjOBJ_MATERIAL, "iris")
        iris = {g for g in range(scene.ngeom) if scene.geom_matid[g] == iris_mat}
        inside = face.mouth_geoms(scene)
        assert len(iris) == 2 and len(inside) == 3
        seen, _, _ = _segmented(model, fr, {}, iris)
        assert seen > 1000  # both irises show at rest
        for side in ("Left", "Right"):
            one, _, _ = _segmented(model, fr, {f"eyeBlink{side}": 1.0}, iris)
            assert 0.3 * seen < one < 0.7 * seen  # one eye shut
        shut, _, _ = _segmented(model, fr, {"eyeBlinkLeft": 1.0, "eyeBlinkRight": 1.0}, iris)
        assert shut == 0
        closed, _, _ = _segmented(model, fr, {}, inside)
        opened, image, mask = _segmented(model, fr, {"jawOpen": 1.0}, inside)
        assert opened > 10 * max(closed, 1) and opened > 1500
        luminance = image[mask] @ np.array([0.2126, 0.7152, 0.0722])
        assert np.median(luminance) < 60  # dark
