"""glTF 2.0 / GLB: the signer's visual geometry on a node per body, and one animation.

Layout of the file:

- node ``world`` (MuJoCo's world body) is the scene root; its rotation turns the signer
  frame (x forward, y left, z up) into glTF's (y up, the signer facing +z). Below it, one
  node per body, named as the MuJoCo body, nested as the bodies are; each body node's
  transform relative to ``world`` is the body's ``xpos`` / ``xquat``.
- Each body with visual geoms (those of ``groups``, default 2, the bundled signer's
  visual class) has one mesh, one primitive per geom (MuJoCo's primitives tessellated),
  with one material per MuJoCo material (its ``rgba``, made linear as glTF wants) or per
  distinct geom colour.
- One animation, ``motion``: a rotation channel per body that has a hinge, a translation
  channel per body that has a slide (the face articulators), sampled at the rollout's
  frames (LINEAR, times ``k / fps``).

Needs ``pygltflib`` (``pip install azee_mj[export]``).
"""

from __future__ import annotations

import base64
import io
import json
import os
import struct
import tempfile

import mujoco
import numpy as np

from azee_mj.export import motion as mo
from azee_mj.export.tessellate import SEGMENTS, geom_mesh

#: Geom groups drawn by default (the bundled signer's visual geoms).
VISUAL_GROUPS = (2,)
#: The root node's rotation, quaternion ``xyzw`` (glTF order), from :data:`motion.YUP`.
_R = mo.YUP


def srgb_to_linear(rgba) -> list[float]:
    """MuJoCo's display colour (sRGB) as glTF's linear ``baseColorFactor``; alpha kept."""
    c = np.asarray(rgba[:3], float)
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    return [*(float(x) for x in lin), float(rgba[3])]


def _yup_quat_xyzw() -> list[float]:
    q = np.empty(4)
    mujoco.mju_mat2Quat(q, _R.flatten())
    return [float(q[1]), float(q[2]), float(q[3]), float(q[0])]


class _Builder:
    """A ``GLTF2`` under construction: its static binary data (the meshes) in ``blob``, and
    views reserved after it (``reserved`` bytes) for the animation, written later."""

    def __init__(self, gl, model: mujoco.MjModel):
        self.gl, self.model = gl, model
        self.blob = bytearray()
        self.reserved = 0
        self.g = gl.GLTF2(asset=gl.Asset(generator="azee_mj", version="2.0"))
        # one material per MuJoCo material, or per distinct rgba of an unmaterialed geom
        self.mat_index: dict[object, int] = {}

    @property
    def size(self) -> int:
        """The buffer's length in bytes (static data and reserved views)."""
        return len(self.blob) + self.reserved

    def _view(self, offset: int, length: int, target) -> int:
        self.g.bufferViews.append(
            self.gl.BufferView(buffer=0, byteOffset=offset, byteLength=length, target=target)
        )
        return len(self.g.bufferViews) - 1

    def add_view(self, arr: np.ndarray, target=None) -> int:
        if self.reserved:
            raise RuntimeError("static views come before the reserved ones")
        blob = self.blob
        while len(blob) % 4:
            blob.append(0)
        data = np.ascontiguousarray(arr).tobytes()
        view = self._view(len(blob), len(data), target)
        blob.extend(data)
        return view

    def reserve_accessor(self, count: int, type_: str, minmax=None) -> int:
        """A float accessor of ``count`` items whose data is written later into a view
        reserved after the static data; ``minmax``: its ``(min, max)`` lists."""
        while len(self.blob) % 4:
            self.blob.append(0)
        width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4}[type_]
        nbytes = 4 * width * count
        view = self._view(self.size, nbytes, None)
        self.reserved += nbytes
        acc = self.gl.Accessor(
            bufferView=view, componentType=self.gl.FLOAT, count=count, type=type_
        )
        if minmax is not None:
            acc.min, acc.max = minmax
        self.g.accessors.append(acc)
        return len(self.g.accessors) - 1

    def add_accessor(self, arr: np.ndarray, type_: str, target=None, minmax=False) -> int:
        gl = self.gl
        ctype = gl.FLOAT if arr.dtype == np.float32 else gl.UNSIGNED_INT
        acc = gl.Accessor(
            bufferView=self.add_view(arr, target), componentType=ctype, count=len(arr), type=type_
        )
        if minmax:
            a = arr.reshape(len(arr), -1)
            acc.min, acc.max = a.min(0).tolist(), a.max(0).tolist()
        self.g.accessors.append(acc)
        return len(self.g.accessors) - 1

    def material(self, geom: int) -> int:
        gl, model, g = self.gl, self.model, self.g
        mid = model.geom_matid[geom]
        if mid >= 0:
            key = ("mat", int(mid))
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_MATERIAL, mid)
            rgba, shin = model.mat_rgba[mid], float(model.mat_shininess[mid])
        else:
            rgba, shin = model.geom_rgba[geom], 0.5
            key = ("rgba", tuple(np.round(rgba, 4)))
            name = "rgba_" + "_".join(f"{x:.2f}" for x in rgba)
        if key not in self.mat_index:
            g.materials.append(
                gl.Material(
                    name=name,
                    pbrMetallicRoughness=gl.PbrMetallicRoughness(
                        baseColorFactor=srgb_to_linear(rgba),
                        metallicFactor=0.0,
                        roughnessFactor=float(np.clip(1.0 - 0.6 * shin, 0.2, 1.0)),
                    ),
                    alphaMode="BLEND" if rgba[3] < 1 else "OPAQUE",
                    doubleSided=False,
                )
            )
            self.mat_index[key] = len(g.materials) - 1
        return self.mat_index[key]


def _add_meshes(bld: _Builder, names, groups, segments: int) -> dict[int, int]:
    """One mesh per body with visual geoms; returns body id -> mesh index."""
    gl, model, g = bld.gl, bld.model, bld.g
    body_mesh: dict[int, int] = {}
    for b in range(model.nbody):
        prims = []
        for geom in range(model.body_geomadr[b], model.body_geomadr[b] + model.body_geomnum[b]):
            if model.geom_group[geom] not in groups:
                continue
            m = geom_mesh(model, geom, segments)
            if m is None:
                continue
            p, n, tri = m
            prims.append(
                gl.Primitive(
                    attributes=gl.Attributes(
                        POSITION=bld.add_accessor(
                            p.astype(np.float32), gl.VEC3, gl.ARRAY_BUFFER, True
                        ),
                        NORMAL=bld.add_accessor(n.astype(np.float32), gl.VEC3, gl.ARRAY_BUFFER),
                    ),
                    indices=bld.add_accessor(
                        tri.astype(np.uint32).reshape(-1), gl.SCALAR, gl.ELEMENT_ARRAY_BUFFER
                    ),
                    material=bld.material(geom),
                )
            )
        if prims:
            g.meshes.append(gl.Mesh(name=names[b], primitives=prims))
            body_mesh[b] = len(g.meshes) - 1
    return body_mesh


def _add_nodes(bld: _Builder, names, body_mesh, lpos, lquat) -> None:
    """The node tree (node index == body id) at the first frame, and the scene."""
    gl, model, g = bld.gl, bld.model, bld.g
    for b in range(model.nbody):
        node = gl.Node(name=names[b], mesh=body_mesh.get(b))
        if b == 0:
            node.rotation = _yup_quat_xyzw()
        else:
            t, q = lpos[0, b], lquat[0, b]
            node.translation = [float(x) for x in t]
            node.rotation = [float(q[1]), float(q[2]), float(q[3]), float(q[0])]
        g.nodes.append(node)
    for b in range(1, model.nbody):
        g.nodes[model.body_parentid[b]].children.append(b)
    g.scenes = [gl.Scene(name="signer", nodes=[0])]
    g.scene = 0


def _add_animation(bld: _Builder, T: int, fps: float, rot, slide) -> list[tuple[int, str, int]]:
    """One linear sampler per moving body's rotation and translation, their key times and
    values in views reserved for :func:`_write_animation`; returns the channels as
    ``(body, path, view)``, the key times' view first as ``(-1, "time", view)``."""
    gl, model, g = bld.gl, bld.model, bld.g
    samplers, channels, plan = [], [], []
    for b in range(1, model.nbody):
        for path, flag in (("rotation", rot[b]), ("translation", slide[b])):
            if not flag:
                continue
            if not plan:
                last = float(np.float32((T - 1) / fps))
                t_acc = bld.reserve_accessor(T, gl.SCALAR, ([0.0], [last]))
                plan.append((-1, "time", g.accessors[t_acc].bufferView))
            out = bld.reserve_accessor(T, gl.VEC4 if path == "rotation" else gl.VEC3)
            plan.append((b, path, g.accessors[out].bufferView))
            samplers.append(gl.AnimationSampler(input=t_acc, output=out, interpolation="LINEAR"))
            channels.append(
                gl.AnimationChannel(
                    sampler=len(samplers) - 1, target=gl.AnimationChannelTarget(node=b, path=path)
                )
            )
    if channels:
        g.animations = [gl.Animation(name="motion", samplers=samplers, channels=channels)]
    return plan


def _write_animation(f, base: int, bld: _Builder, qpos, fps: float, plan, chunk: int) -> None:
    """Write the key times and values of ``plan`` (see :func:`_add_animation`) into the
    seekable file ``f``, whose buffer starts at ``base``, ``chunk`` frames at a time: the
    memory used does not grow with the number of frames."""
    views = bld.g.bufferViews
    prev = None
    for k0, q in mo.chunks(qpos, chunk):
        pos, quat = mo.body_frames(bld.model, q)
        lpos, lquat = mo.local_frames(bld.model, pos, quat, prev)
        prev = lquat[-1]
        for b, path, view in plan:
            if path == "time":
                values = np.arange(k0, k0 + len(q)) / fps
            elif path == "rotation":
                values = lquat[:, b][:, [1, 2, 3, 0]]
            else:
                values = lpos[:, b]
            data = np.ascontiguousarray(values, np.float32)
            f.seek(base + views[view].byteOffset + k0 * data[0].nbytes)
            f.write(data.tobytes())
    f.seek(base + bld.size)


def _prepare(model: mujoco.MjModel, qpos, fps: float, groups, segments: int):
    """The glTF's JSON part (buffer length set), its static binary data, and the animation
    plan (see :func:`_add_animation`); the animation data itself is not computed yet."""
    gl = mo.require("pygltflib", "glTF")
    mo.check_qpos(model, qpos, fps)
    names = mo.body_names(model)
    rot, slide = mo.moving_bodies(model)
    pos, quat = mo.body_frames(model, np.asarray(qpos[:1], float))
    lpos, lquat = mo.local_frames(model, pos, quat)

    bld = _Builder(gl, model)
    body_mesh = _add_meshes(bld, names, groups, segments)
    _add_nodes(bld, names, body_mesh, lpos, lquat)
    plan = _add_animation(bld, len(qpos), fps, rot, slide)
    bld.g.buffers = [gl.Buffer(byteLength=bld.size)]
    return bld, plan


def write_glb(
    f,
    model: mujoco.MjModel,
    qpos: np.ndarray,
    fps: float,
    *,
    groups=VISUAL_GROUPS,
    segments: int = SEGMENTS,
    chunk: int = mo.CHUNK,
) -> None:
    """Write the GLB of the signer and its motion to the seekable binary file ``f`` (the
    motion ``chunk`` frames at a time, in bounded memory); arguments as
    :func:`build_gltf`."""
    bld, plan = _prepare(model, qpos, fps, groups, segments)
    text = bld.g.to_json(separators=(",", ":")).encode("utf-8")
    text += b" " * (-len(text) % 4)
    start = f.tell()
    f.write(struct.pack("<4sII", b"glTF", 2, 12 + 8 + len(text) + 8 + bld.size))
    f.write(struct.pack("<I4s", len(text), b"JSON") + text)
    f.write(struct.pack("<I4s", bld.size, b"BIN\0"))
    base = f.tell()
    f.write(bld.blob)
    _write_animation(f, base, bld, qpos, fps, plan, chunk)
    assert f.tell() - start == 12 + 8 + len(text) + 8 + bld.size


def write_gltf_json(
    f,
    model: mujoco.MjModel,
    qpos: np.ndarray,
    fps: float,
    *,
    groups=VISUAL_GROUPS,
    segments: int = SEGMENTS,
    chunk: int = mo.CHUNK,
) -> None:
    """Write the ``.gltf`` (JSON, the buffer embedded as a base64 data URI) to the text
    file ``f``: the buffer goes to an anonymous temporary file first, then is encoded a
    piece at a time (bounded memory); arguments as :func:`build_gltf`."""
    bld, plan = _prepare(model, qpos, fps, groups, segments)
    head = json.loads(bld.g.to_json())
    del head["buffers"]
    # the JSON without its buffers, which close it: no user string is ever scanned
    f.write(json.dumps(head)[:-1])
    f.write(f', "buffers": [{{"byteLength": {bld.size}, "uri": "{_DATA_URI}')
    with tempfile.TemporaryFile() as tmp:
        tmp.write(bld.blob)
        _write_animation(tmp, 0, bld, qpos, fps, plan, chunk)
        tmp.seek(0)
        while piece := tmp.read(3 * 2**16):  # whole groups of 3 bytes: no padding inside
            f.write(base64.b64encode(piece).decode("ascii"))
    f.write('"}]}')


_DATA_URI = "data:application/octet-stream;base64,"


def glb_bytes(model: mujoco.MjModel, qpos: np.ndarray, fps: float, **kw) -> bytes:
    """The GLB file's bytes (see :func:`build_gltf`)."""
    f = io.BytesIO()
    write_glb(f, model, qpos, fps, **kw)
    return f.getvalue()


def build_gltf(
    model: mujoco.MjModel,
    qpos: np.ndarray,
    fps: float,
    *,
    groups=VISUAL_GROUPS,
    segments: int = SEGMENTS,
):
    """The signer and its motion as a ``pygltflib.GLTF2`` with one binary blob, in memory
    (:func:`write_gltf` writes a file in bounded memory instead).

    Args:
      model: the signer.
      qpos: (T, nq) postures.
      fps: frames per second of ``qpos``.
      groups: geom groups to draw.
      segments: tessellation resolution around a primitive's axis.
    """
    gl = mo.require("pygltflib", "glTF")
    return gl.GLTF2.load_from_bytes(glb_bytes(model, qpos, fps, groups=groups, segments=segments))


def write_gltf(
    path: str | os.PathLike, model: mujoco.MjModel, qpos: np.ndarray, fps: float, **kw
) -> None:
    """Write ``.glb`` (binary) or ``.gltf`` (JSON with the buffer embedded as a data URI)
    to ``path`` as it is (the caller makes it atomic), the motion a chunk of frames at a
    time: memory does not grow with the number of frames."""
    if str(path).lower().endswith(".glb"):
        with open(path, "wb") as f:
            write_glb(f, model, qpos, fps, **kw)
    else:
        with open(path, "w", encoding="ascii") as f:
            write_gltf_json(f, model, qpos, fps, **kw)
