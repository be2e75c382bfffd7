"""Exports written in bounded memory, frame chunk by frame chunk (issue 27): the same
content (CSV: the sites and the face's ARKit weights) as the whole motion at once, whatever
its length; CSV coordinates always floats; BVH names that any reader's grammar takes; the
player page's size limit."""

from __future__ import annotations

import csv
import io
import os
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

from azee_mj.arkit import ARKIT_SHAPES
from azee_mj.errors import AzeeError
from azee_mj.export import Motion, export
from azee_mj.export import arkit as face
from azee_mj.export import motion as mo
from azee_mj.model import MODEL_PATH, load_model
from azee_mj.sites import DEFAULT_MAP

ROOT = Path(__file__).resolve().parent.parent
ENV = dict(os.environ, PYTHONPATH=str(ROOT))


@pytest.fixture(scope="module")
def model():
    return load_model()


def _wave(model, frames: int, seed: int = 0) -> np.ndarray:
    """``frames`` postures swinging every hinge within its range (a smooth motion)."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames)[:, None] / 50.0
    q = np.repeat(model.qpos0[None], frames, axis=0)
    for j in range(model.njnt):
        if model.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE:
            continue
        lo, hi = model.jnt_range[j] if model.jnt_limited[j] else (-1.0, 1.0)
        mid, amp = 0.5 * (lo + hi), 0.4 * (hi - lo)
        a = model.jnt_qposadr[j]
        q[:, a] = mid + amp * np.sin(
            2 * np.pi * rng.uniform(0.2, 1.0) * t[:, 0] + rng.uniform(0, 6)
        )
    return q


@pytest.fixture(scope="module")
def long_motion(model) -> Motion:
    # longer than a chunk, not a multiple of one: every chunk boundary is crossed
    from azee_mj.export.motion import CHUNK

    return Motion(_wave(model, 2 * CHUNK + 37), 50.0, {}, "wave")


def test_csv_streams_the_sites_and_every_coordinate_is_a_float(model, long_motion, tmp_path):
    out = export(long_motion, tmp_path / "m.csv")
    rows = list(csv.reader(io.StringIO(out.read_text())))
    header, body = rows[0], rows[1:]
    assert len(body) == len(long_motion.qpos)
    names = [*DEFAULT_MAP.sites, *DEFAULT_MAP.loci]
    want = mo.site_positions(
        model, long_motion.qpos, [{**DEFAULT_MAP.sites, **DEFAULT_MAP.loci}[n] for n in names]
    )
    got = np.array(body, float)
    sites = 1 + want[0].size
    np.testing.assert_allclose(got[:, 0], long_motion.time, atol=1e-9)
    np.testing.assert_allclose(got[:, 1:sites].reshape(want.shape), want, atol=1e-8)
    # the face's ARKit weights, read chunk by chunk, are those of the whole motion at once
    shapes = face.weights(model, long_motion.qpos, DEFAULT_MAP)
    np.testing.assert_allclose(got[:, sites:], shapes, atol=1e-8)
    # a reader infers floats for every column: no cell is written as an integer
    ints = [(k, c) for row in body for k, c in enumerate(row) if c.lstrip("-").isdigit()]
    assert ints == []
    assert header[0] == "time" and len(header) == 1 + 3 * len(names) + len(ARKIT_SHAPES)
    assert header[1 + 3 * len(names) :] == list(ARKIT_SHAPES)


def test_pose_streams_the_bytes_pose_format_writes(model, long_motion, tmp_path):
    pytest.importorskip("pose_format", reason="the .pose export needs azee_mj[export]")
    from azee_mj.export.pose import build_pose

    out = export(long_motion, tmp_path / "m.pose")
    whole = io.BytesIO()
    build_pose(model, long_motion.qpos, long_motion.fps).write(whole)
    assert out.read_bytes() == whole.getvalue()


def test_bvh_streams_motion_that_bvhio_reads_back(model, long_motion, tmp_path):
    bvhio = pytest.importorskip("bvhio", reason="the BVH export needs azee_mj[export]")
    from azee_mj.export import bvh as bvh_mod

    out = export(long_motion, tmp_path / "m.bvh")
    root = bvhio.readAsHierarchy(str(out))
    joints = {j.Name: j for j, _, _ in root.layout()}
    names = bvh_mod.joint_names(model)
    pos, _ = mo.body_frames(model, long_motion.qpos)
    worst = 0.0
    for k in (0, 1, mo.CHUNK - 1, mo.CHUNK, len(long_motion.qpos) - 1):
        root.loadPose(k, recursive=True)
        for b in range(1, model.nbody):
            p = np.array(joints[names[b]].PositionWorld, float)
            worst = max(worst, np.abs(p - mo.YUP @ pos[k, b]).max())
    assert worst < 1e-4, worst


def test_bvh_needs_no_extra(model, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "bvhio", None)  # makes `import bvhio` fail
    out = export(Motion(model.qpos0[None], 50.0), tmp_path / "m.bvh")
    assert out.read_text().startswith("HIERARCHY\nROOT pelvis\n")


def test_bvh_names_are_sanitized_for_the_grammar(tmp_path):
    bvhio = pytest.importorskip("bvhio", reason="the BVH export needs azee_mj[export]")
    from azee_mj.export import bvh as bvh_mod

    spec = mujoco.MjSpec.from_file(str(MODEL_PATH))
    renames = {"jaw": "my jaw {L}", "lid_L": "lid}{", "lid_R": "lid  }{", "pelvis": "#"}
    for b in spec.bodies:
        b.name = renames.get(b.name, b.name)
    for ex in spec.excludes:
        ex.bodyname1 = renames.get(ex.bodyname1, ex.bodyname1)
        ex.bodyname2 = renames.get(ex.bodyname2, ex.bodyname2)
    model = spec.compile()
    names = bvh_mod.joint_names(model)
    assert [names[model.body(n).id] for n in renames.values()] == [
        "my_jaw__L_",
        "lid__",
        "lid____",
        "_",
    ]
    assert len(set(names)) == len(names)
    out = tmp_path / "m.bvh"
    export(Motion(np.repeat(model.qpos0[None], 3, axis=0), 50.0), out, model=model)
    layout = {j.Name for j, _, _ in bvhio.readAsBvh(str(out)).Root.layout()}
    assert {"my_jaw__L_", "lid__", "lid____", "_"} <= layout


_PEAK = """
import sys, tracemalloc
import numpy as np
from azee_mj.export import Motion, export
from azee_mj.export import arkit as face
from azee_mj.model import load_model
model = load_model()
frames = int(sys.argv[2])
q = np.repeat(model.qpos0[None], frames, axis=0)
q += 0.01 * np.sin(np.arange(frames))[:, None]
import azee_mj.export.bvh, azee_mj.export.csv, azee_mj.export.pose, bvhio, pose_format
tracemalloc.start()  # numpy's arrays and Python objects; an inherited RSS is not counted
export(Motion(q, 50.0), sys.argv[1])
print(tracemalloc.get_traced_memory()[1] // 2**20)
"""


_PEAK_GLTF = _PEAK.replace(
    "import azee_mj.export.bvh, azee_mj.export.csv, azee_mj.export.pose, bvhio, pose_format",
    "import azee_mj.export.gltf, pygltflib",
)
assert _PEAK_GLTF != _PEAK


@pytest.mark.parametrize("suffix", [".bvh", ".csv", ".pose", ".glb", ".gltf"])
def test_exports_take_bounded_memory(tmp_path, suffix):
    needs = ("pygltflib",) if suffix in (".glb", ".gltf") else ("bvhio", "pose_format")
    for module in needs:
        pytest.importorskip(module, reason="the exports need azee_mj[export]")
    script = _PEAK_GLTF if suffix in (".glb", ".gltf") else _PEAK
    out = tmp_path / f"m{suffix}"
    p = subprocess.run(
        [sys.executable, "-c", script, str(out), "20000"],
        capture_output=True,
        text=True,
        env=ENV,
        check=False,
    )
    assert p.returncode == 0, p.stderr
    grown_mb = int(p.stdout)
    # 20,000 frames; whole-motion writers grew by hundreds (glTF by 340 MB)
    assert grown_mb < 64, grown_mb


def _glb_accessor(g, blob: bytes, i: int) -> np.ndarray:
    acc = g.accessors[i]
    view = g.bufferViews[acc.bufferView]
    width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4}[acc.type]
    raw = blob[view.byteOffset : view.byteOffset + view.byteLength]
    assert view.byteLength == 4 * width * acc.count
    return np.frombuffer(raw, np.float32).reshape(acc.count, width)


def test_gltf_streams_the_bytes_of_the_whole_motion_at_once(model, long_motion, tmp_path):
    gl = pytest.importorskip("pygltflib", reason="the glTF export needs azee_mj[export]")
    from azee_mj.export import gltf

    q, fps = long_motion.qpos, long_motion.fps
    whole = gltf.glb_bytes(model, q, fps, chunk=len(q))
    assert gltf.glb_bytes(model, q, fps, chunk=7) == whole  # any chunking, the same file
    assert export(long_motion, tmp_path / "m.glb").read_bytes() == whole
    g = gl.GLTF2.load_from_bytes(whole)
    blob = g.binary_blob()
    assert len(whole) % 4 == 0 and len(blob) == g.buffers[0].byteLength
    # the key times, and quaternion signs continuous across every chunk boundary
    sampler = g.animations[0].samplers[0]
    times = _glb_accessor(g, blob, sampler.input)[:, 0]
    np.testing.assert_array_equal(times, (np.arange(len(q)) / fps).astype(np.float32))
    assert g.accessors[sampler.input].max == [float(times[-1])]
    for ch in g.animations[0].channels:
        if ch.target.path == "rotation":
            r = _glb_accessor(g, blob, g.animations[0].samplers[ch.sampler].output)
            assert np.all(np.sum(r[1:] * r[:-1], axis=1) > 0), ch.target.node
    # the .gltf holds the same buffer, base64 in its JSON, and the same JSON otherwise
    text = export(long_motion, tmp_path / "m.gltf").read_text()
    g2 = gl.GLTF2.from_json(text)
    assert g2.get_data_from_buffer_uri(g2.buffers[0].uri) == blob
    g2.buffers[0].uri = None
    assert g2.to_json() == g.to_json()


def test_a_player_page_too_large_to_open_is_refused(model, tmp_path):
    pytest.importorskip("pygltflib", reason="the player needs azee_mj[export]")
    from azee_mj.export.player import MAX_PLAYER_FRAMES

    q = np.repeat(model.qpos0[None], MAX_PLAYER_FRAMES + 1, axis=0)
    with pytest.raises(AzeeError) as e:
        export(Motion(q, 50.0, {}, "long"), tmp_path / "p.html")
    assert str(e.value) == (
        f"{tmp_path / 'p.html'}: {MAX_PLAYER_FRAMES + 1} frames; a player page holds at most "
        f"{MAX_PLAYER_FRAMES} (a larger page takes minutes to open in a browser, or never "
        "opens): export a part, a lower --fps, or .glb for a viewer"
    )
    assert list(tmp_path.iterdir()) == []
