"""The face in the exports: ARKit weights read back from the rig, the Live Link Face CSV,
and the .pose face points that follow the brows, lids, mouth corners and jaw."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from azee_mj import arkit
from azee_mj.cli import main
from azee_mj.export import Motion, export
from azee_mj.export import arkit as face
from azee_mj.export import pose as pose_mod
from azee_mj.sites import DEFAULT_MAP

ARKIT_READY = all(n in DEFAULT_MAP.morphs for n in (*arkit.ARKIT_SHAPES, *arkit.PAIRS))
needs_arkit = pytest.mark.skipif(not ARKIT_READY, reason="ARKit morphs not in the catalogue yet")


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
    with pytest.raises(ValueError, match="did you mean 'jawOpen'"):
        arkit.check_weights({"jawopen": 0.5}, "x")
    with pytest.raises(ValueError, match=r"must be in \[0, 1\], got 1.5"):
        arkit.check_weights({"jawOpen": 1.5}, "x")


@pytest.mark.skipif(ARKIT_READY, reason="the catalogue has ARKit morphs: see the next test")
def test_weights_are_read_back_from_the_older_face(model):
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
        "jawOpen": 0.5,
    }
    assert set(w) == set(want)
    for n, v in want.items():
        assert w[n] == pytest.approx(v, abs=1e-4)


@needs_arkit
@pytest.mark.parametrize("name", arkit.ARKIT_SHAPES)
def test_each_shape_alone_is_read_back(model, name):
    q = model.qpos0.copy()
    for j, v in DEFAULT_MAP.morphs[name].joint_changes(None).items():
        a = model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j)]
        lo, hi = model.jnt_range[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j)]
        q[a] = np.clip(q[a] + 0.6 * v, lo, hi)
    w = _w(face.weights(model, q)[0])
    assert w.get(name) == pytest.approx(0.6, abs=0.02), w


def test_eyes_without_look_shapes_are_read_from_the_eye_joints(model):
    b = face.basis(model)
    if b.source[arkit.ARKIT_SHAPES.index("eyeLookOutLeft")] != "eyes":
        pytest.skip("the catalogue has its own eye shapes")
    q = model.qpos0.copy()
    q[model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "eye_L_yaw")]] = 0.3
    q[model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "eye_R_pitch")]] = 0.2
    w = _w(face.weights(model, q)[0])
    assert w == pytest.approx(
        {"eyeLookOutLeft": 0.3 / math.radians(45), "eyeLookDownRight": 0.2 / math.radians(45)},
        abs=1e-4,
    )


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
    q = posture(model, {("blink", "L"): 1.0, ("jaw_open", None): 0.4})
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
    assert len(rows) == 1 + 61 and {r[1] for r in rows[1:]} == {"61"}  # 2.4 s at 25 fps
    brows = [float(r[rows[0].index("BrowOuterUpLeft")]) for r in rows[1:]]
    blink = [float(r[rows[0].index("EyeBlinkRight")]) for r in rows[1:]]
    assert blink[-1] == pytest.approx(1.0, abs=1e-3)  # BLINK over [2.0, 2.2] (held after)
    if not ARKIT_READY:  # brows_raise 0.8 over the topic, read back as the outer brows
        assert max(brows) == pytest.approx(0.8, abs=1e-3)


def _face_point(model, q, index: str) -> np.ndarray:
    names = pose_mod.POINTS["FACE_LANDMARKS"][0]
    return pose_mod.keypoints(model, q[None])["FACE_LANDMARKS"][0, names.index(index)]


def test_pose_face_points_follow_the_rig(model):
    """The catalogue's older morphs (kept by the ARKit rig as compositions) move the points
    with the face's parts: 8 mm brow lift and 6 mm smile on the current signer."""
    rest = model.qpos0

    def moved(morph, index):
        q = posture(model, {(morph, None): 1.0})
        return _face_point(model, q, index) - _face_point(model, rest, index)

    assert moved("brows_raise", "105")[2] > 0.003 and moved("brows_raise", "334")[2] > 0.003
    assert moved("smile", "61")[2] > 0.002 and moved("smile", "291")[2] > 0.002
    assert moved("jaw_open", "14")[2] < -0.005  # the lower lip drops with the jaw
    # the upper lid's margin comes down onto the lower one's on a blink (aperture about 0)
    blink = posture(model, {("blink", None): 1.0})
    for upper, lower in (("159", "145"), ("386", "374")):
        gap = _face_point(model, rest, upper)[2] - _face_point(model, rest, lower)[2]
        closed = _face_point(model, blink, upper)[2] - _face_point(model, blink, lower)[2]
        assert gap > 0.008 and abs(closed) < 0.0015, (gap, closed)


def test_pose_face_points_at_rest_are_their_sites_plus_offsets(model):
    d = mujoco.MjData(model)
    mujoco.mj_kinematics(model, d)
    for index, (site, _, offset) in pose_mod.FACE_RIG.items():
        want = d.site(DEFAULT_MAP.sites[site]).xpos + np.asarray(offset)
        np.testing.assert_allclose(_face_point(model, model.qpos0, index), want, atol=1e-12)
