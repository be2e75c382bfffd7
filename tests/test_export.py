"""Exports: every file read back with its own library and compared with MuJoCo on every
frame; bad input; the web player in headless Chromium."""

from __future__ import annotations

import csv
import io
import json
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest
from headless_chromium import READY, launched

from azee_mj import arkit
from azee_mj.azee import compile_text
from azee_mj.cli import main
from azee_mj.errors import OutputError
from azee_mj.export import Motion, export, load_motion
from azee_mj.export import arkit as face
from azee_mj.export import bvh as bvh_mod
from azee_mj.export import motion as mo
from azee_mj.export import pose as pose_mod
from azee_mj.export.csv import columns
from azee_mj.export.gltf import srgb_to_linear
from azee_mj.export.player import camera_pose
from azee_mj.model import SCENE_PATH
from azee_mj.schedule import schedule, shifted
from azee_mj.score import load_score
from azee_mj.sites import DEFAULT_MAP, FACE_JOINTS
from azee_mj.timeline import realize

ROOT = Path(__file__).resolve().parent.parent
DATA = Path(__file__).parent / "data"
EXAMPLE = ROOT / "examples" / "info-about.json"  # both hands, gaze, face, holds


@pytest.fixture(scope="module")
def rollout():
    return realize(load_score(EXAMPLE), fps=25.0)


@pytest.fixture(scope="module")
def realized(rollout) -> Motion:
    return Motion(rollout.qpos, rollout.fps, mo.schedule_tuples(rollout.schedule), "info-about")


@pytest.fixture(scope="module")
def random_motion(model) -> Motion:
    """Postures drawn inside every joint's range (slides and all), 12 frames at 30 fps."""
    rng = np.random.default_rng(12)
    lo, hi = model.jnt_range[:, 0], model.jnt_range[:, 1]
    q = lo + (hi - lo) * rng.random((12, model.nq))
    return Motion(q, 30.0, {}, "random")


@pytest.fixture(scope="module", params=["realized", "random_motion"])
def motion(request) -> Motion:
    return request.getfixturevalue(request.param)


def frames(model, qpos):
    return mo.body_frames(model, qpos)


# ---------------------------------------------------------------------------------------
# glTF / GLB
# ---------------------------------------------------------------------------------------


def _accessor(g, i: int) -> np.ndarray:
    import pygltflib as gl

    acc = g.accessors[i]
    view = g.bufferViews[acc.bufferView]
    blob = (
        g.binary_blob()
        if g.buffers[0].uri is None
        else g.get_data_from_buffer_uri(g.buffers[0].uri)
    )
    dtype = {gl.FLOAT: np.float32, gl.UNSIGNED_INT: np.uint32}[acc.componentType]
    width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4}[acc.type]
    raw = blob[view.byteOffset + (acc.byteOffset or 0) :][: acc.count * width * 4]
    return np.frombuffer(raw, dtype).reshape(acc.count, width).squeeze()


def _quat_mat(xyzw) -> np.ndarray:
    m = np.empty(9)
    x, y, z, w = (float(v) for v in xyzw)
    mujoco.mju_quat2Mat(m, np.array([w, x, y, z]) / np.linalg.norm([w, x, y, z]))
    return m.reshape(3, 3)


def _world_transforms(g, k: int) -> dict[int, np.ndarray]:
    """4x4 world matrix of every node at animation frame ``k`` (the sampled keyframe)."""
    trs = {
        i: [
            np.array(n.translation or [0, 0, 0], float),
            np.array(n.rotation or [0, 0, 0, 1], float),
        ]
        for i, n in enumerate(g.nodes)
    }
    for a in g.animations:
        for ch in a.channels:
            out = _accessor(g, a.samplers[ch.sampler].output)
            trs[ch.target.node][0 if ch.target.path == "translation" else 1] = out[k]
    world = {}

    def visit(i, parent):
        t, r = trs[i]
        local = np.eye(4)
        local[:3, :3], local[:3, 3] = _quat_mat(r), t
        world[i] = parent @ local
        for c in g.nodes[i].children:
            visit(c, world[i])

    for root in g.scenes[g.scene].nodes:
        visit(root, np.eye(4))
    return world


@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
@pytest.mark.extra("export")
def test_gltf_node_world_transforms_match_mujoco_on_every_frame(model, motion, tmp_path, suffix):
    import pygltflib

    out = export(motion, tmp_path / f"m{suffix}")
    g = pygltflib.GLTF2().load(str(out))
    names = mo.body_names(model)
    assert [n.name for n in g.nodes] == names
    times = _accessor(g, g.animations[0].samplers[0].input)
    np.testing.assert_allclose(times, np.arange(len(motion.qpos)) / motion.fps, atol=1e-6)
    pos, quat = frames(model, motion.qpos)
    worst_p = worst_r = 0.0
    for k in range(len(motion.qpos)):
        world = _world_transforms(g, k)
        root_inv = np.linalg.inv(world[0])  # node 'world' turns the signer frame Y-up
        np.testing.assert_allclose(world[0][:3, :3], mo.YUP, atol=1e-7)
        for b in range(1, model.nbody):
            m = root_inv @ world[b]
            R = np.empty(9)
            mujoco.mju_quat2Mat(R, quat[k, b])
            worst_p = max(worst_p, np.abs(m[:3, 3] - pos[k, b]).max())
            worst_r = max(worst_r, np.abs(m[:3, :3] - R.reshape(3, 3)).max())
    assert worst_p < 1e-5 and worst_r < 1e-5, (worst_p, worst_r)


@pytest.mark.extra("export")
def test_gltf_channels_rotate_hinged_bodies_and_translate_sliding_ones(model, realized, tmp_path):
    import pygltflib

    g = pygltflib.GLTF2().load(str(export(realized, tmp_path / "m.glb")))
    names = mo.body_names(model)
    got = {(names[c.target.node], c.target.path) for c in g.animations[0].channels}
    hinge = {
        names[model.jnt_bodyid[j]]
        for j in range(model.njnt)
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE
    }
    slide = {
        names[model.jnt_bodyid[j]]
        for j in range(model.njnt)
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE
    }
    assert got == {(b, "rotation") for b in hinge} | {(b, "translation") for b in slide}
    # the face rig's sliding parts (the jaw, brows, cheeks, nostrils, lips, corners, tongue)
    face = {names[model.joint(j).bodyid[0]] for j in FACE_JOINTS}
    assert slide == face - {"lid_L", "lid_R", "lid_low_L", "lid_low_R"}
    assert all(s.interpolation == "LINEAR" for s in g.animations[0].samplers)


@pytest.mark.extra("export")
def test_gltf_meshes_are_the_visual_geoms_on_their_surfaces_with_their_colours(model, tmp_path):
    import pygltflib

    g = pygltflib.GLTF2().load(str(export(Motion(model.qpos0[None], 50.0), tmp_path / "m.glb")))
    names = mo.body_names(model)
    T = mujoco.mjtGeom
    checked = set()
    for b, node in enumerate(g.nodes):
        geoms = [
            i
            for i in range(model.body_geomadr[b], model.body_geomadr[b] + model.body_geomnum[b])
            if model.geom_group[i] == 2
        ]
        if node.mesh is None:
            assert not geoms, names[b]
            continue
        prims = g.meshes[node.mesh].primitives
        assert g.meshes[node.mesh].name == names[b] and len(prims) == len(geoms)
        for geom, prim in zip(geoms, prims):
            p = _accessor(g, prim.attributes.POSITION).astype(float)
            R = np.empty(9)
            mujoco.mju_quat2Mat(R, model.geom_quat[geom])
            local = (p - model.geom_pos[geom]) @ R.reshape(3, 3)  # into the geom frame
            s, t = model.geom_size[geom], int(model.geom_type[geom])
            if t == T.mjGEOM_SPHERE:
                err = np.linalg.norm(local, axis=1) - s[0]
            elif t == T.mjGEOM_ELLIPSOID:
                err = np.linalg.norm(local / s, axis=1) - 1.0
            elif t == T.mjGEOM_CAPSULE:
                z = np.clip(local[:, 2], -s[1], s[1])
                err = np.linalg.norm(local - np.c_[0 * z, 0 * z, z], axis=1) - s[0]
            elif t == T.mjGEOM_CYLINDER:
                r = np.linalg.norm(local[:, :2], axis=1)
                err = np.minimum(np.abs(r - s[0]), np.abs(np.abs(local[:, 2]) - s[1]))
                assert np.all(r <= s[0] + 1e-6) and np.all(np.abs(local[:, 2]) <= s[1] + 1e-6)
            else:
                assert t == T.mjGEOM_BOX
                err = np.max(np.abs(local) / s[:3], axis=1) - 1.0
            assert np.abs(err).max() < 1e-5 * max(1.0, 1 / s[0]), (names[b], geom, t)
            checked.add(t)
            mat = g.materials[prim.material]
            rgba = model.mat_rgba[model.geom_matid[geom]]
            assert mat.name == mujoco.mj_id2name(
                model, mujoco.mjtObj.mjOBJ_MATERIAL, model.geom_matid[geom]
            )
            np.testing.assert_allclose(
                mat.pbrMetallicRoughness.baseColorFactor, srgb_to_linear(rgba), atol=1e-7
            )
    assert checked == {
        int(x)
        for x in (
            T.mjGEOM_SPHERE,
            T.mjGEOM_ELLIPSOID,
            T.mjGEOM_CAPSULE,
            T.mjGEOM_CYLINDER,
            T.mjGEOM_BOX,
        )
    }


# ---------------------------------------------------------------------------------------
# BVH
# ---------------------------------------------------------------------------------------


@pytest.mark.extra("export")
def test_bvh_forward_kinematics_through_bvhio_matches_the_bodies(model, motion, tmp_path):
    import bvhio

    out = export(motion, tmp_path / "m.bvh")
    container = bvhio.readAsBvh(str(out))
    assert container.FrameCount == len(motion.qpos)
    assert container.FrameTime == pytest.approx(1.0 / motion.fps)
    root = bvhio.readAsHierarchy(str(out))
    joints = {j.Name: j for j, _, _ in root.layout()}
    names = bvh_mod.joint_names(model)
    assert set(joints) == set(names[1:])
    pos, _ = frames(model, motion.qpos)
    worst = 0.0
    for k in range(len(motion.qpos)):
        root.loadPose(k, recursive=True)
        for b in range(1, model.nbody):
            p = np.array(joints[names[b]].PositionWorld, float)
            worst = max(worst, np.abs(p - mo.YUP @ pos[k, b]).max())
    assert worst < 1e-4, worst


@pytest.mark.extra("export")
def test_bvh_joints_are_azee_bones_with_the_model_offsets(model, tmp_path):
    import bvhio

    out = export(Motion(model.qpos0[None], 50.0), tmp_path / "m.bvh")
    layout = {j.Name: j for j, _, _ in bvhio.readAsBvh(str(out)).Root.layout()}
    assert set(DEFAULT_MAP.bones) <= set(layout)
    face = {model.body(model.joint(j).bodyid[0]).name for j in FACE_JOINTS}
    assert set(layout) - set(DEFAULT_MAP.bones) == {"pelvis"} | face
    palm = layout["palm_R"]
    np.testing.assert_allclose(np.array(palm.Offset), mo.YUP @ model.body("palm_R").pos, atol=1e-9)
    assert [c.Name for c in layout["f_arm_R"].Children] == ["palm_R"]
    assert len(palm.Channels) == 3 and all(c.endswith("rotation") for c in palm.Channels)
    assert layout["pelvis"].Channels[:3] == ["Xposition", "Yposition", "Zposition"]
    assert layout["brow_L"].Channels[:3] == ["Xposition", "Yposition", "Zposition"]


def test_bvh_euler_order_keeps_the_middle_angle_away_from_gimbal_lock():
    elbow_90 = np.array([[np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0, 0.0]])  # 90 deg about X
    order = bvh_mod.euler_order(elbow_90)
    assert order[1] != "X" and sorted(order) == ["X", "Y", "Z"]


# ---------------------------------------------------------------------------------------
# .pose
# ---------------------------------------------------------------------------------------


def _term_value(model, data, t: pose_mod.Term) -> np.ndarray:
    if t.carrier is not None:  # the site's rest position (+ offset), carried by the body
        rest = mujoco.MjData(model)
        mujoco.mj_kinematics(model, rest)
        name = (
            t.carrier
            if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, t.carrier) >= 0
            else (model.body(model.site(DEFAULT_MAP.sites[t.site]).bodyid[0]).name)
        )
        p0 = rest.site(DEFAULT_MAP.sites[t.site]).xpos + np.asarray(t.offset)
        local = rest.body(name).xmat.reshape(3, 3).T @ (p0 - rest.body(name).xpos)
        return data.body(name).xpos + data.body(name).xmat.reshape(3, 3) @ local
    if t.site is not None:
        return data.site(DEFAULT_MAP.sites[t.site]).xpos
    body = DEFAULT_MAP.bones[t.bone].body if t.bone else t.body
    R = data.body(body).xmat.reshape(3, 3)
    return data.body(body).xpos + R @ np.asarray(t.offset)


@pytest.mark.extra("export")
def test_pose_keypoints_match_the_sites_on_every_frame(model, motion, tmp_path):
    from pose_format import Pose

    out = export(motion, tmp_path / "m.pose")
    p = Pose.read(out.read_bytes())
    assert p.body.fps == pytest.approx(motion.fps)
    assert p.body.data.shape == (len(motion.qpos), 1, 105, 3)
    assert np.all(p.body.confidence == 1.0)
    pts = pose_mod.pose_to_signer(np.asarray(p.body.data[:, 0]))
    data = mujoco.MjData(model)
    worst = 0.0
    for k in range(len(motion.qpos)):
        data.qpos[:] = motion.qpos[k]
        mujoco.mj_kinematics(model, data)
        i = 0
        for comp in p.header.components:
            _, terms = pose_mod.POINTS[comp.name]
            for pt in terms:
                want = sum(t.weight * _term_value(model, data, t) for t in pt)
                worst = max(worst, np.abs(pts[k, i] - want).max())
                i += 1
    assert worst < 1e-4, worst


@pytest.mark.extra("export")
def test_pose_header_is_mediapipe_holistic_with_the_signers_own_sides(model, tmp_path):
    from pose_format import Pose
    from pose_format.utils.generic import detect_known_pose_format, pose_shoulders

    out = export(Motion(model.qpos0[None], 25.0), tmp_path / "m.pose")
    p = Pose.read(out.read_bytes())
    assert [c.name for c in p.header.components] == [
        "POSE_LANDMARKS",
        "FACE_LANDMARKS",
        "LEFT_HAND_LANDMARKS",
        "RIGHT_HAND_LANDMARKS",
    ]
    assert detect_known_pose_format(p) == "holistic"
    assert len(p.header.components[0].points) == 33
    hand = p.header.components[3].points
    assert hand[0] == "WRIST" and hand[-1] == "PINKY_TIP" and len(hand) == 21
    (c1, right), (c2, left) = pose_shoulders(p.header)
    data = np.asarray(p.body.data[0, 0])
    r = data[p.header.get_point_index(c1, right)]
    lft = data[p.header.get_point_index(c2, left)]
    assert lft[0] > r[0]  # the signer faces the camera: their left on the image's right
    d = mujoco.MjData(model)
    mujoco.mj_kinematics(model, d)
    tip = data[p.header.get_point_index("RIGHT_HAND_LANDMARKS", "INDEX_FINGER_TIP")]
    np.testing.assert_allclose(pose_mod.pose_to_signer(tip), d.site("I_TIP_R").xpos, atol=1e-4)
    nose = data[p.header.get_point_index("FACE_LANDMARKS", "1")]
    np.testing.assert_allclose(pose_mod.pose_to_signer(nose), d.site("NO").xpos, atol=1e-4)
    assert 0 <= data[:, 0].min() and data[:, 0].max() < p.header.dimensions.width
    assert 0 <= data[:, 1].min() and data[:, 1].max() < p.header.dimensions.height


@pytest.mark.extra("export")
def test_pose_visualizer_draws_the_file(model, realized, tmp_path):
    pytest.importorskip("cv2", reason="pose-format's visualizer needs opencv")
    from pose_format import Pose
    from pose_format.pose_visualizer import PoseVisualizer

    p = Pose.read(export(realized, tmp_path / "m.pose").read_bytes())
    frames_ = list(PoseVisualizer(p).draw())
    assert len(frames_) == len(realized.qpos)
    assert frames_[0].shape[:2] == (p.header.dimensions.height, p.header.dimensions.width)
    assert frames_[0].std() > 0


# ---------------------------------------------------------------------------------------
# CSV
# ---------------------------------------------------------------------------------------


def test_csv_rows_are_the_site_positions(model, rollout, realized, tmp_path):
    out = export(realized, tmp_path / "m.csv")
    with open(out, newline="") as f:
        rows = list(csv.reader(f))
    names = columns()
    assert rows[0] == ["time", *(f"{n}_{a}" for n in names for a in "xyz"), *arkit.ARKIT_SHAPES]
    table = np.array(rows[1:], float)
    assert table.shape == (len(rollout.time), 1 + 3 * len(names) + 52)
    np.testing.assert_allclose(table[:, -52:], face.weights(model, rollout.qpos), atol=1e-8)
    table = table[:, :-52]
    np.testing.assert_allclose(table[:, 0], rollout.time, atol=1e-9)
    pos = table[:, 1:].reshape(len(table), len(names), 3)
    S = len(rollout.site_names)
    assert list(names[:S]) == list(rollout.site_names)
    np.testing.assert_allclose(pos[:, :S], rollout.site_pos, atol=1e-8)
    data = mujoco.MjData(model)
    for k in range(len(table)):
        data.qpos[:] = rollout.qpos[k]
        mujoco.mj_kinematics(model, data)
        want = [data.site({**DEFAULT_MAP.sites, **DEFAULT_MAP.loci}[n]).xpos for n in names]
        np.testing.assert_allclose(pos[k], want, atol=1e-8)
    # a Rollout exports as its Motion does
    assert export(rollout, tmp_path / "r.csv").read_bytes() == out.read_bytes()


# ---------------------------------------------------------------------------------------
# Command line, Python API and bad input
# ---------------------------------------------------------------------------------------


@pytest.mark.extra("export")
def test_cli_exports_a_score_and_a_rollout_with_its_score(tmp_path, capsys):
    out = tmp_path / "good.glb"
    assert main(["export", str(DATA / "good.json"), "-o", str(out), "--fps", "25"]) == 0
    assert capsys.readouterr().out == f"{out}: written\n"
    assert out.read_bytes()[:4] == b"glTF"
    npz = tmp_path / "good.npz"
    assert main(["realize", str(DATA / "good.json"), "-o", str(npz), "--fps", "25"]) == 0
    page = tmp_path / "good.html"
    assert main(["export", str(npz), "--score", str(DATA / "good.json"), "-o", str(page)]) == 0
    info = _page_info(page.read_text())
    with np.load(npz) as z:  # the score's schedule on the rollout's clock (after the lead-in)
        frames, start = len(z["time"]), float(z["score_start"])
    assert info["frames"] == frames and info["fps"] == 25.0
    want = mo.schedule_tuples(shifted(schedule(load_score(DATA / "good.json")), start))
    assert {k: [tuple(i) for i in v] for k, v in info["schedule"].items()} == {
        k: list(v) for k, v in want.items()
    }
    assert {b for ivs in want.values() for b, _, _ in ivs} >= {"GOOD.K1", "GOOD.K2"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["good.glb", "good.html", "good.npz"]


def _page_info(text: str) -> dict:
    start = text.index('<script type="application/json" id="azee-info">') + 47
    return json.loads(text[start : text.index("</script>", start)])


def test_load_motion_of_a_rollout_equals_its_realization(tmp_path, rollout):
    from azee_mj.rollout_io import save_rollout

    save_rollout(tmp_path / "r.npz", rollout)
    m = load_motion(tmp_path / "r.npz", score=EXAMPLE)
    np.testing.assert_array_equal(m.qpos, rollout.qpos)
    assert m.fps == 25.0 and m.name == "r"
    assert m.schedule == mo.schedule_tuples(rollout.schedule)


def _exit2(argv, capsys) -> str:
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    return captured.err


def test_unknown_suffix_is_one_message_and_no_file(tmp_path, capsys):
    out = tmp_path / "m.fbx"
    err = _exit2(["export", str(DATA / "good.json"), "-o", str(out)], capsys)
    assert err == (
        f"azee-mj: error: {out}: unknown export suffix '.fbx'; use one of .glb, "
        ".gltf, .bvh, .pose, .livelink.csv, .csv, .html\n"
    )
    assert list(tmp_path.iterdir()) == []


@pytest.mark.extra("export")
def test_an_npz_of_another_model_is_refused(model, tmp_path, capsys):
    bad = tmp_path / "other.npz"
    np.savez(
        bad,
        time=np.arange(3) / 50,
        qpos=np.zeros((3, 7)),
        fps=np.array(50.0),
        site_names=np.array(["a"]),
        site_pos=np.zeros((3, 1, 3)),
    )
    out = tmp_path / "m.glb"
    err = _exit2(["export", str(bad), "-o", str(out)], capsys)
    assert err == (
        f"azee-mj: error: {bad}: qpos has 7 columns; the bundled signer has nq={model.nq}\n"
    )
    wrong_sites = tmp_path / "sites.npz"
    np.savez(
        wrong_sites,
        time=np.arange(3) / 50,
        qpos=np.zeros((3, model.nq)),
        fps=np.array(50.0),
        site_names=np.array(["a"]),
        site_pos=np.zeros((3, 1, 3)),
    )
    err = _exit2(["export", str(wrong_sites), "-o", str(out)], capsys)
    assert err == (
        f"azee-mj: error: {wrong_sites}: not a rollout of this signer: its "
        "site_names are not the catalogue's 223 AZee sites\n"
    )
    notnpz = tmp_path / "x.npz"
    notnpz.write_text("hello")
    err = _exit2(["export", str(notnpz), "-o", str(out)], capsys)
    assert err == (
        f"azee-mj: error: {notnpz}: not a rollout .npz file, or damaged (File is not a zip file)\n"
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["other.npz", "sites.npz", "x.npz"]


@pytest.mark.parametrize(
    "suffix, module, what",
    [
        (".glb", "pygltflib", "glTF"),
        (".html", "pygltflib", "The web player's"),
        (".pose", "pose_format", ".pose"),
    ],
)
def test_a_missing_extra_is_one_message_and_no_file(
    tmp_path, capsys, monkeypatch, suffix, module, what
):
    monkeypatch.setitem(sys.modules, module, None)  # makes `import module` fail
    out = tmp_path / f"m{suffix}"
    err = _exit2(["export", str(DATA / "good.json"), "-o", str(out)], capsys)
    assert err == (
        f"azee-mj: error: {what} export needs the package '{module}': pip install azee_mj[export]\n"
    )
    assert list(tmp_path.iterdir()) == []


def test_a_writer_failing_midway_leaves_no_partial_file(tmp_path, realized, monkeypatch):
    from azee_mj.export import csv as csv_mod

    def failing(path, *a, **k):
        Path(path).write_text("time,half a row")
        raise OSError("disk full")

    monkeypatch.setattr(csv_mod, "write_csv", failing)
    with pytest.raises(OutputError) as e:
        export(realized, tmp_path / "m.csv")
    assert str(e.value) == f"{tmp_path / 'm.csv'}: cannot be written: disk full"
    assert list(tmp_path.iterdir()) == []


@pytest.mark.extra("export")
def test_the_player_page_is_self_contained(realized, tmp_path):
    text = export(realized, tmp_path / "p.html").read_text()
    assert "<script src" not in text and "<link" not in text and "@GLB@" not in text
    assert text.count("<title>info-about</title>") == 1
    info = _page_info(text)
    assert info["camera"] == camera_pose("front")
    assert info["duration"] == pytest.approx((len(realized.qpos) - 1) / realized.fps)


# ---------------------------------------------------------------------------------------
# The web player in headless Chromium
# ---------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def browser():
    yield from launched((640, 480))


@pytest.fixture(scope="module")
def page(realized, tmp_path_factory) -> Path:
    return export(realized, tmp_path_factory.mktemp("player") / "info-about.html")


def _url(page: Path, query: str) -> str:
    return page.resolve().as_uri() + "?" + query


@pytest.mark.extra("export")
def test_player_loads_without_error_and_the_animation_advances(browser, page):
    browser.events.clear()
    # Paused while it loads (a slow load would otherwise loop the 2.4 s clip), then played.
    browser.open(_url(page, "t=0.2&paused=1"), READY)
    t0 = browser.evaluate("azeePlayer.time()")
    assert t0 == pytest.approx(0.2) and browser.evaluate("azeePlayer.playing()") is False
    browser.evaluate("azeePlayer.play()")
    assert browser.evaluate("azeePlayer.playing()") is True
    browser.open_wait(f"azeePlayer.time() > {t0} + 0.2")  # a TimeoutError if it stands still
    assert browser.errors() == []


@pytest.mark.extra("export")
def test_player_controls_pause_play_speed_and_seek(browser, page):
    browser.open(_url(page, "t=0.5&paused=1&speed=2"), READY)
    assert browser.evaluate("azeePlayer.playing()") is False
    assert browser.evaluate("azeePlayer.speed()") == 2
    assert browser.evaluate("document.getElementById('speed').value") == "2"
    options = browser.evaluate("[...document.querySelectorAll('#speed option')].map(o => o.value)")
    assert options == ["0.25", "0.5", "1", "1.5", "2"]
    drawn = browser.evaluate("azeePlayer.frames")
    browser.open_wait(f"azeePlayer.frames > {drawn + 5}")
    assert browser.evaluate("azeePlayer.time()") == 0.5  # paused: frames drawn, time still
    browser.evaluate("document.getElementById('play').click()")
    assert browser.evaluate("azeePlayer.playing()") is True
    browser.open_wait("azeePlayer.time() > 0.6")
    browser.evaluate("document.getElementById('play').click()")
    browser.evaluate(
        "(() => { const s = document.getElementById('slider'); s.value = 1.5;"
        " s.dispatchEvent(new Event('input')); })()"
    )
    assert browser.evaluate("azeePlayer.time()") == 1.5
    assert browser.evaluate("document.getElementById('play').textContent") == "play"
    browser.evaluate(
        "document.getElementById('speed').value = '0.25';"
        "document.getElementById('speed').dispatchEvent(new Event('change'))"
    )
    assert browser.evaluate("azeePlayer.speed()") == 0.25
    assert browser.errors() == []


@pytest.mark.extra("export")
def test_player_shows_the_blocks_of_the_current_time(browser, page, realized, rollout):
    t = round(rollout.score_start + 1.0, 2)  # 1 s into the score, after the lead-in
    browser.open(_url(page, f"t={t}&paused=1"), READY)
    shown = browser.evaluate("document.getElementById('blocks').textContent")
    active = {
        track: [b for b, s, e in ivs if s <= t < e] for track, ivs in realized.schedule.items()
    }
    want = [f"{track.ljust(7)} {', '.join(bs)}" for track, bs in active.items() if bs]
    assert len(want) >= 3 and shown.splitlines() == want
    assert browser.evaluate("document.getElementById('clock').textContent") == (
        f"{t:.2f} / {(len(realized.qpos) - 1) / realized.fps:.2f} s"
    )
    assert browser.errors() == []


def _hand_pixels_mujoco(model_scene, qpos, size) -> np.ndarray:
    from azee_mj.render import gl_backend

    gl_backend()
    data = mujoco.MjData(model_scene)
    data.qpos[:] = qpos
    mujoco.mj_forward(model_scene, data)
    with mujoco.Renderer(model_scene, size[1], size[0]) as r:
        r.enable_segmentation_rendering()
        r.update_scene(data, camera="front")
        seg = r.render()
    palm = model_scene.body("palm_R").id

    def under_palm(b):
        while b > 0 and b != palm:
            b = model_scene.body_parentid[b]
        return b == palm

    geoms = [g for g in range(model_scene.ngeom) if under_palm(model_scene.geom_bodyid[g])]
    return np.isin(seg[..., 0], geoms) & (seg[..., 1] == int(mujoco.mjtObj.mjOBJ_GEOM))


@pytest.mark.parametrize("t", [0.4, 1.2, 2.0])
@pytest.mark.extra("export")
def test_player_screenshot_puts_the_strong_hand_where_mujoco_does(browser, page, realized, t):
    from PIL import Image

    from azee_mj.errors import AzeeError

    browser.open(_url(page, f"t={t}&paused=1&ui=0&highlight=palm_R"), READY)
    img = np.asarray(Image.open(io.BytesIO(browser.screenshot())).convert("RGB")).astype(int)
    assert img.shape == (480, 640, 3)
    seen = (img[..., 0] > 200) & (img[..., 1] < 80) & (img[..., 2] > 200)
    scene = mujoco.MjModel.from_xml_path(str(SCENE_PATH))
    try:
        want = _hand_pixels_mujoco(scene, realized.qpos[round(t * realized.fps)], (640, 480))
    except AzeeError as e:
        pytest.skip(f"no OpenGL backend for MuJoCo's side of the comparison: {e}")
    assert want.sum() > 200 and abs(int(seen.sum()) - int(want.sum())) < 0.15 * want.sum()
    got_c = np.argwhere(seen).mean(0)
    want_c = np.argwhere(want).mean(0)
    assert np.abs(got_c - want_c).max() < 3.0, (got_c, want_c)
    assert browser.errors() == []


@pytest.mark.extra("export")
def test_cli_export_takes_azee(tmp_path, capsys):
    src = tmp_path / "five.azee"
    src.write_text(":nb-5\n")
    out = tmp_path / "five.csv"
    assert main(["export", str(src), "-o", str(out), "--fps", "10"]) == 0
    assert capsys.readouterr().out == f"{out}: written\n"
    want = realize(load_score(compile_text(":nb-5")), fps=10.0)
    assert len(out.read_text().splitlines()) == 1 + len(want.time)
    rollout = tmp_path / "five.npz"
    assert main(["realize", str(src), "-o", str(rollout), "--fps", "10"]) == 0
    page = tmp_path / "five.html"
    assert main(["export", str(rollout), "--score", str(src), "-o", str(page)]) == 0
    with np.load(rollout) as z:
        start = float(z["score_start"])
    want = mo.schedule_tuples(shifted(schedule(load_score(compile_text(":nb-5"))), start))
    assert {
        k: [tuple(i) for i in v] for k, v in _page_info(page.read_text())["schedule"].items()
    } == {k: list(v) for k, v in want.items()}
    assert "NB_5.SHAPE" in {b for ivs in want.values() for b, _, _ in ivs}
