"""BVH: the signer's bodies as a joint hierarchy, with the motion as Euler channels.

- Joints are the model's bodies below the world, each named as the AZee bone it carries
  (``palm_R``), or as the body where no bone maps to it (``pelvis``, ``jaw``, ``lid_L``...).
- Axes are Y-up (x to the signer's left, y up, z the signer's facing), units metres.
  Offsets are the bodies' positions in their parents at the model's rest (``body_pos``).
- Every joint has three rotation channels; the root and the bodies that slide (the face
  articulators) also have three position channels (the offset plus the slide).
  Each joint's Euler order is the one of the six whose middle angle stays farthest from
  +-90 degrees over the motion (no gimbal lock in the written angles).
- ``Frame Time`` is ``1 / fps``; one frame per rollout frame.

Written and read with ``bvhio`` (``pip install azee_mj[export]``).
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Mapping

import mujoco
import numpy as np

from azee_mj.export import motion as mo
from azee_mj.sites import DEFAULT_MAP, SignerMap

#: Decimals written (bvhio rounds each number): 1e-9 m and 1e-9 degrees.
PRECISION = 9
#: Length of the end site of a leaf joint that has no tip site [m].
END_LENGTH = 0.02

_AXES = "XYZ"


def joint_names(model: mujoco.MjModel, signer_map: SignerMap = DEFAULT_MAP) -> list[str]:
    """Per body id, the BVH joint name: its AZee bone, else the body's name."""
    bone_of = {b.body: bone for bone, b in signer_map.bones.items()}
    return [bone_of.get(n, n) for n in mo.body_names(model)]


def _quat_mats(q: np.ndarray) -> np.ndarray:
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )


def euler_order(quats: np.ndarray) -> str:
    """The intrinsic Euler order (e.g. ``"ZXY"``) whose middle angle keeps farthest from
    +-90 degrees for rotations ``quats`` (T, 4) ``wxyz``: for R = R_a R_b R_c the middle
    angle's sine is +-R[a, c]."""
    R = _quat_mats(np.asarray(quats, float))
    best, order = np.inf, "ZXY"
    for perm in ["ZXY", *("".join(p) for p in itertools.permutations(_AXES))]:
        a, c = _AXES.index(perm[0]), _AXES.index(perm[2])
        worst = float(np.max(np.abs(R[:, a, c]))) if len(R) else 0.0
        if worst < best - 1e-9:
            best, order = worst, perm
    return order


def build_bvh(
    model: mujoco.MjModel, qpos: np.ndarray, fps: float, *, signer_map: SignerMap = DEFAULT_MAP
):
    """The motion as a ``bvhio.BvhContainer`` (see the module docstring)."""
    bvhio = mo.require("bvhio", "BVH")
    glm = mo.require("glm", "BVH")  # PyGLM, which bvhio uses
    st = mo.require("SpatialTransform", "BVH")
    mo.check_qpos(model, qpos, fps)
    qpos = np.asarray(qpos, float)
    names = joint_names(model, signer_map)
    _, slide = mo.moving_bodies(model)
    pos, quat = mo.body_frames(model, qpos)
    lpos, lquat = mo.local_frames(model, pos, quat)
    lpos_y = lpos @ mo.YUP.T
    lquat_y = mo.quat_to_yup(lquat)
    tips = _tip_offsets(model, signer_map)

    children: dict[int, list[int]] = {}
    for b in range(1, model.nbody):
        children.setdefault(int(model.body_parentid[b]), []).append(b)
    roots = children.get(0, [])

    def joint(b: int, is_root: bool):
        j = bvhio.BvhJoint(names[b])
        j.Offset = glm.dvec3(*(mo.YUP @ model.body_pos[b]))  # dvec3: written as given
        order = euler_order(lquat_y[:, b])
        if is_root or slide[b]:
            j.Channels = ["Xposition", "Yposition", "Zposition"]
        j.Channels += [f"{a}rotation" for a in order]
        j.Keyframes = [
            st.Pose(glm.vec3(*lpos_y[k, b]), glm.quat(*lquat_y[k, b])) for k in range(len(qpos))
        ]
        for c in children.get(b, []):
            j.Children.append(joint(c, False))
        if not j.Children:
            j.EndSite = glm.dvec3(*tips.get(b, _default_tip(model, b, signer_map)))
        return j

    if len(roots) == 1:
        root = joint(roots[0], True)
    else:  # several bodies hang from the world: a still root joint holds them
        root = bvhio.BvhJoint("world", glm.vec3(0, 0, 0))
        root.Channels = [
            "Xposition",
            "Yposition",
            "Zposition",
            "Zrotation",
            "Xrotation",
            "Yrotation",
        ]
        root.Keyframes = [
            st.Pose(glm.vec3(0, 0, 0), glm.quat(1, 0, 0, 0)) for _ in range(len(qpos))
        ]
        root.Children = [joint(c, False) for c in roots]
    return bvhio.BvhContainer(root, len(qpos), 1.0 / fps)


def _tip_offsets(model: mujoco.MjModel, signer_map: SignerMap) -> Mapping[int, np.ndarray]:
    """Per distal finger body, its tip site (``X_TIP_side``) in the Y-up body frame."""
    out = {}
    for name, site in signer_map.sites.items():
        if "_TIP_" not in name:
            continue
        s = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site)
        if s >= 0:
            out[int(model.site_bodyid[s])] = mo.YUP @ model.site_pos[s]
    return out


def _default_tip(model: mujoco.MjModel, b: int, signer_map: SignerMap) -> np.ndarray:
    body = mo.body_names(model)[b]
    for bone in signer_map.bones.values():
        if bone.body == body:
            return mo.YUP @ (END_LENGTH * np.asarray(bone.dir))
    return mo.YUP @ np.array([END_LENGTH, 0.0, 0.0])  # forward, out of the face


def write_bvh(
    path: str | os.PathLike,
    model: mujoco.MjModel,
    qpos: np.ndarray,
    fps: float,
    *,
    signer_map: SignerMap = DEFAULT_MAP,
) -> None:
    """Write the motion to ``path`` as BVH (the caller makes it atomic)."""
    bvhio = mo.require("bvhio", "BVH")
    bvhio.writeBvh(str(path), build_bvh(model, qpos, fps, signer_map=signer_map), PRECISION)
