"""The face in the exports: ARKit weights read back from the rig, the Live Link Face CSV,
and the .pose face points that follow the brows, lids, mouth corners and lips."""

from __future__ import annotations

import csv
from pathlib import Path

import mujoco
import numpy as np
import pytest

from azee_mj import arkit
from azee_mj import face as face_mod
from azee_mj.cli import main
from azee_mj.export import Motion, export
from azee_mj.export import arkit as face
from azee_mj.export import pose as pose_mod
from azee_mj.face import morph_posture as face_posture
from azee_mj.score import load_score
from azee_mj.sites import DEFAULT_MAP
from azee_mj.timeline import realize


def posture(model, morphs: dict[tuple[str, str | None], float]) -> np.ndarray:
    """qpos0 with catalogue morphs applied: {(morph id, side or None): weight}."""
    q = model.qpos0.copy()
    for (mid, side), w in morphs.items():
        for j, v in DEFAULT_MAP.morphs[mid].joint_changes(side).items():
            a = model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j)]
            q[a] += w * v
    return q


def _w(row: np.ndarray) -> dict[str, float]:
    return {n: float(v) for n, v in zip(arkit.ARKIT_SHAPES, row) if abs(v) > 1e-6}


def test_arkit_names_are_52_in_live_link_order_with_18_pairs():
    assert len(arkit.ARKIT_SHAPES) == len(set(arkit.ARKIT_SHAPES)) == 52
    # Written out on purpose: the published order of ARKit's list (its first seven, the left
    # eye), which the package's own tuple must keep.
    assert arkit.ARKIT_SHAPES[:7] == (
        "eyeBlinkLeft",
        "eyeLookDownLeft",
        "eyeLookInLeft",
        "eyeLookOutLeft",
        "eyeLookUpLeft",
        "eyeSquintLeft",
        "eyeWideLeft",
    )
    assert arkit.ARKIT_SHAPES[-1] == "tongueOut" and len(arkit.PAIRS) == 18
    assert arkit.split("mouthLeft") == ("mouthLeft", None)
    assert arkit.split("browDownRight") == ("browDown", "R")


def test_equal_pairs_become_base_names_in_scores():
    cons = arkit.constraints({"eyeBlinkLeft": 1, "eyeBlinkRight": 1, "mouthSmileLeft": 0.25})
    assert cons == [
        {"type": "morph", "id": "eyeBlink", "weight": 1.0},
        {"type": "morph", "id": "mouthSmileLeft", "weight": 0.25},
    ]
    assert arkit.constraints({"mouthLeft": 0.5, "mouthRight": 0.5}) == [
        {"type": "morph", "id": "mouthRight", "weight": 0.5},
        {"type": "morph", "id": "mouthLeft", "weight": 0.5},
    ]


def test_the_older_morphs_are_read_back_as_their_compositions(model):
    applied = {
        ("brows_frown", None): 0.6,
        ("blink", "L"): 1.0,
        ("eyes_wide", "R"): 0.5,
        ("smile", "R"): 0.3,
        ("jaw_open", None): 0.5,
    }
    w = _w(face.weights(model, posture(model, applied))[0])
    want = {
        "browDownLeft": 0.6,
        "browDownRight": 0.6,
        "eyeBlinkLeft": 1.0,
        "eyeWideRight": 0.5,
        "mouthSmileRight": 0.3,
        "jawOpen": 0.5 * 0.85,  # jaw_open is jawOpen at 0.85
    }
    assert set(w) == set(want)
    for n, v in want.items():
        assert w[n] == pytest.approx(v, abs=1e-3)


@pytest.mark.parametrize("weight", [0.3, 0.6, 1.0])
@pytest.mark.parametrize("name", arkit.ARKIT_SHAPES)
def test_each_shape_alone_is_read_back(model, name, weight):
    """The rig's shapes are not independent (cheekSquint's lower lid and cheek also come
    from eyeSquint with the eye shapes' lids), so the fit must prefer the fewest shapes."""
    b = face.basis(model)
    assert b.source[arkit.ARKIT_SHAPES.index(name)] == "catalogue"
    w = _w(face.weights(model, face_posture(model, {name: weight}, base=model.qpos0))[0])
    assert set(w) <= {name} | {n for n, v in w.items() if v < 1e-3}, w
    assert w[name] == pytest.approx(weight, abs=1e-3), w


def test_weights_stay_in_range_on_random_postures(model):
    rng = np.random.default_rng(3)
    lo, hi = model.jnt_range[:, 0], model.jnt_range[:, 1]
    q = lo + (hi - lo) * rng.random((20, model.nq))
    w = face.weights(model, q)
    assert w.shape == (20, 52) and w.min() >= 0 and w.max() <= 1


def test_timecodes_count_frames_within_the_second():
    assert face.timecode(0.0, 50) == "00:00:00:00.000"
    assert face.timecode(61.5, 50) == "00:01:01:25.000"
    assert face.timecode(3723 + 2 / 25, 25) == "01:02:03:02.000"
    assert face.timecode(1 / 60 * 7, 60) == "00:00:00:07.000"


def test_live_link_face_csv_layout(model, tmp_path):
    q = posture(model, {("eyeBlinkLeft", None): 1.0, ("jawOpen", None): 0.4})
    for j, v in (("head_rot", 0.2), ("eye_R_yaw", -0.1)):
        q[model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j)]] = v
    out = export(Motion(np.stack([model.qpos0, q]), 50.0), tmp_path / "face.livelink.csv")
    with open(out, newline="") as f:
        rows = list(csv.reader(f))
    header = rows[0]
    assert len(header) == 63
    assert header[:4] == ["Timecode", "BlendShapeCount", "EyeBlinkLeft", "EyeLookDownLeft"]
    assert header[2:54] == [n[0].upper() + n[1:] for n in arkit.ARKIT_SHAPES]
    assert header[54:] == list(face.ROTATIONS)
    assert [r[:2] for r in rows[1:]] == [["00:00:00:00.000", "61"], ["00:00:00:01.000", "61"]]
    vals = dict(zip(header, rows[2]))
    assert float(vals["EyeBlinkLeft"]) == pytest.approx(1.0, abs=1e-4)
    assert float(vals["JawOpen"]) == pytest.approx(0.4, abs=1e-4)
    assert float(vals["HeadYaw"]) == pytest.approx(0.2, abs=1e-6)  # toward the signer's left
    assert float(vals["HeadPitch"]) == pytest.approx(0.0, abs=1e-6)
    assert float(vals["RightEyeYaw"]) == pytest.approx(-0.1, abs=1e-6)
    assert all(float(v) == 0.0 for v in rows[1][2:])


def test_cli_exports_live_link_face(tmp_path, capsys):
    out = tmp_path / "ia.livelink.csv"
    src = Path(__file__).resolve().parent.parent / "examples" / "info-about.json"
    assert main(["export", str(src), "-o", str(out), "--fps", "25"]) == 0
    rows = list(csv.reader(out.open()))
    rollout = realize(load_score(src), fps=25)
    assert len(rows) == 1 + len(rollout.time)  # a row a frame, lead-in and return included
    assert {r[1] for r in rows[1:]} == {"61"}  # 52 shapes and 9 rotations
    brows = [float(r[rows[0].index("BrowOuterUpLeft")]) for r in rows[1:]]
    blink = np.array([float(r[rows[0].index("EyeBlinkRight")]) for r in rows[1:]])
    # BLINK closes the eyes over [2.0, 2.2] s of the score, held after; the return to rest
    # opens them again once the score ends
    held = round((rollout.score_start + 2.2) * 25)
    assert blink[held] == pytest.approx(1.0, abs=1e-3)
    assert blink[-1] == pytest.approx(0.0, abs=1e-3)
    # brows_raise 0.8 over the topic: browInnerUp and browOuterUp at 0.8 x 0.8
    assert max(brows) == pytest.approx(0.64, abs=1e-3)


def _face_point(model, q, index: str) -> np.ndarray:
    names = pose_mod.POINTS["FACE_LANDMARKS"][0]
    return pose_mod.keypoints(model, q[None])["FACE_LANDMARKS"][0, names.index(index)]


def _apertures(model, q) -> tuple[float, float]:
    """The right eyelid's and the lips' apertures [m] measured on the rig's geometry."""
    d = mujoco.MjData(model)
    d.qpos[:] = q
    mujoco.mj_kinematics(model, d)
    return face_mod.eyelid_aperture(model, d, "R"), face_mod.lip_aperture(model, d)


def _on_lip(model, q, index: str, bodies: tuple[str, ...]) -> float:
    """Distance [m] from face point ``index`` to the surface of the nearest lip capsule of
    ``bodies`` at posture ``q``."""
    d = mujoco.MjData(model)
    d.qpos[:] = q
    mujoco.mj_kinematics(model, d)
    p = _face_point(model, q, index)
    out = np.inf
    for b in bodies:
        for g in np.flatnonzero(model.geom_bodyid == model.body(b).id):
            if model.geom_type[g] != mujoco.mjtGeom.mjGEOM_CAPSULE:
                continue
            c, axis = d.geom_xpos[g], d.geom_xmat[g].reshape(3, 3)[:, 2]
            half = model.geom_size[g][1]
            t = np.clip(np.dot(p - c, axis), -half, half)
            out = min(out, abs(np.linalg.norm(p - c - t * axis) - model.geom_size[g][0]))
    return out


POSTURES = [{}, {"eyeBlink": 1.0}, {"eyeWide": 1.0}, {"jawOpen": 1.0}, {"mouthClose": 1.0}]


@pytest.mark.parametrize("weights", POSTURES + [{"jawOpen": 0.4}, {"mouthShrugLower": 1.0}])
def test_pose_lip_points_stay_on_the_lips(model, weights):
    """(Shapes that slide the lip's halves sideways, like a pucker, put the midline point
    between the halves' ends, inside the lip.)"""
    q = face_posture(model, weights, base=model.qpos0)
    assert _on_lip(model, q, "13", ("lip_up_R", "lip_up_L")) < 1e-6
    assert _on_lip(model, q, "14", ("lip_low_R", "lip_low_L")) < 1e-6


@pytest.mark.parametrize("weights", POSTURES)
def test_pose_lid_and_lip_points_open_as_the_rig_does(model, weights):
    """The gaps between the eyelid margins' points and between the lips' points are the
    apertures measured by casting rays at the rig from straight ahead (within 0.5 mm; a
    negative gap is a closed, pressed eye or mouth; at
    the jaw's partial openings the rays also see the mouth past the lower lip's curve, up
    to 2 mm more than the lips' gap)."""
    q = face_posture(model, weights, base=model.qpos0)
    eye, lips = _apertures(model, q)
    lid_gap = _face_point(model, q, "159")[2] - _face_point(model, q, "145")[2]
    lip_gap = _face_point(model, q, "13")[2] - _face_point(model, q, "14")[2]
    assert max(lid_gap, 0.0) == pytest.approx(eye, abs=5e-4)
    assert max(lip_gap, 0.0) == pytest.approx(lips, abs=5e-4)
    left = _face_point(model, q, "386")[2] - _face_point(model, q, "374")[2]
    assert left == pytest.approx(lid_gap, abs=1e-9)


def test_pose_brow_and_corner_points_ride_on_their_parts(model):
    rest = model.qpos0

    def moved(weights, index):
        q = face_posture(model, weights, base=rest)
        return _face_point(model, q, index) - _face_point(model, rest, index)

    inner = arkit.BOTH["browInnerUp"]
    raised = moved({"browInnerUp": 1.0}, "105")
    # the brow's tilt turns about an axis through 105's body (not through the point)
    assert raised[2] == pytest.approx(inner["brow_{X}_raise"], abs=1e-4)
    assert moved({"browInnerUp": 1.0}, "107")[2] > raised[2] + 0.003  # the inner end tilts up
    assert moved({"browOuterUpLeft": 1.0}, "300")[2] > 0.003  # the outer brow
    assert moved({"browOuterUpLeft": 1.0}, "70")[2] == 0.0  # the other side's stays
    smile = arkit.SIDED["mouthSmile"]
    np.testing.assert_allclose(
        moved({"mouthSmileRight": 1.0}, "61"),  # the corner's slides: forward, out (-y), up
        [smile["mouth_{X}_fwd"], -smile["mouth_{X}_out"], smile["mouth_{X}_up"]],
        atol=1e-9,
    )
    assert moved({"mouthSmileRight": 1.0}, "291")[2] == 0.0


def test_pose_carriers_are_bodies_of_the_rig(model):
    for index, (_, carriers, _) in pose_mod.FACE_RIG.items():
        for c in carriers:
            assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, c) >= 0, (index, c)


def test_pose_face_points_at_rest_are_their_sites_plus_offsets(model):
    d = mujoco.MjData(model)
    mujoco.mj_kinematics(model, d)
    for index, (site, _, offset) in pose_mod.FACE_RIG.items():
        want = d.site(DEFAULT_MAP.sites[site]).xpos + np.asarray(offset)
        np.testing.assert_allclose(_face_point(model, model.qpos0, index), want, atol=1e-12)
