"""BVH: the signer's bodies as a joint hierarchy, with the motion as Euler channels.

- Joints are the model's bodies below the world, each named as the AZee bone it carries
  (``palm_R``), or as the body where no bone maps to it (``pelvis``, ``jaw``, ``lid_L``...).
  A name is made of letters, digits, ``_``, ``.`` and ``-`` only (any other character,
  such as a space or a brace that the BVH grammar would read as a token, becomes ``_``)
  and is unique (``_2``, ``_3``... appended).
- Axes are Y-up (x to the signer's left, y up, z the signer's facing), units metres.
  Offsets are the bodies' positions in their parents at the model's rest (``body_pos``).
- Every joint has three rotation channels; the root and the bodies that slide (the face
  articulators) also have three position channels (the offset plus the slide).
  Each joint's Euler order is the one of the six whose middle angle stays farthest from
  +-90 degrees over the motion (no gimbal lock in the written angles).
- ``Frame Time`` is ``1 / fps``; one frame per rollout frame. Numbers have 10 significant
  digits.

Written a chunk of frames at a time (bounded memory for any length: a first pass picks
the Euler orders, a second writes the frames); read with ``bvhio``
(``pip install azee_mj[export]``), which the tests use.
"""

from __future__ import annotations

import itertools
import os
import re
import warnings
from collections.abc import Mapping

import mujoco
import numpy as np

from azee_mj.export import motion as mo
from azee_mj.sites import DEFAULT_MAP, SignerMap

#: Significant digits written.
DIGITS = 10
#: Length of the end site of a leaf joint that has no tip site [m].
END_LENGTH = 0.02

_AXES = "XYZ"


def joint_names(model: mujoco.MjModel, signer_map: SignerMap = DEFAULT_MAP) -> list[str]:
    """Per body id, the BVH joint name: its AZee bone, else the body's name, made a token
    of the BVH grammar and unique (see the module docstring)."""
    bone_of = {b.body: bone for bone, b in signer_map.bones.items()}
    out: list[str] = []
    taken = {"world"}  # the still root joint's name when several bodies hang from the world
    for b, n in enumerate(mo.body_names(model)):
        name = _NOT_NAME.sub("_", bone_of.get(n, n) or f"body{b}")
        base, k = name, 1
        while name in taken and b > 0:
            k += 1
            name = f"{base}_{k}"
        taken.add(name)
        out.append(name)
    return out


_NOT_NAME = re.compile(r"[^A-Za-z0-9_.\-]")


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


_ORDERS = ("ZXY", *("".join(p) for p in itertools.permutations(_AXES)))


def _worst_middle(R: np.ndarray) -> dict[str, np.ndarray]:
    """Per Euler order, the largest ``|sin(middle angle)|`` over rotation matrices
    ``R`` (T, ..., 3, 3) (``R[a, c]`` for R = R_a R_b R_c), per trailing index."""
    return {
        o: np.abs(R[..., _AXES.index(o[0]), _AXES.index(o[2])]).max(axis=0, initial=0.0)
        for o in _ORDERS
    }


def _pick(worst: dict[str, float]) -> str:
    """The order whose middle angle stays farthest from +-90 degrees (ZXY on ties)."""
    best, order = np.inf, "ZXY"
    for o in _ORDERS:
        if worst[o] < best - 1e-9:
            best, order = float(worst[o]), o
    return order


def euler_order(quats: np.ndarray) -> str:
    """The intrinsic Euler order (e.g. ``"ZXY"``) whose middle angle keeps farthest from
    +-90 degrees for rotations ``quats`` (T, 4) ``wxyz``: for R = R_a R_b R_c the middle
    angle's sine is +-R[a, c]."""
    return _pick(_worst_middle(_quat_mats(np.asarray(quats, float))))


def _local_yup(model: mujoco.MjModel, qpos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each body's position (T, nbody, 3) [m] and rotation (T, nbody, 4) ``wxyz`` in its
    parent's frame, in the Y-up frame."""
    pos, quat = mo.body_frames(model, qpos)
    lpos, lquat = mo.local_frames(model, pos, quat)
    return lpos @ mo.YUP.T, mo.quat_to_yup(lquat)


def _orders(model: mujoco.MjModel, qpos: np.ndarray) -> list[str]:
    """Per body, its Euler order over the whole motion (a pass over chunks of frames)."""
    worst = {o: np.zeros(model.nbody) for o in _ORDERS}
    for _, q in mo.chunks(qpos):
        _, lquat = _local_yup(model, q)
        for o, w in _worst_middle(_quat_mats(lquat)).items():
            np.maximum(worst[o], w, out=worst[o])
    return [_pick({o: float(worst[o][b]) for o in _ORDERS}) for b in range(model.nbody)]


def _joint_lines(model, b, depth, ctx) -> None:
    """Append body ``b``'s joint (and its children's) to ``ctx["lines"]``, and its
    channels to ``ctx["columns"]``: ``(body, moves)`` in channel order."""
    names, orders, slide, tips, children, smap = ctx["info"]
    pad = "  " * depth
    is_root = depth == 0
    lines = ctx["lines"]
    off = mo.YUP @ model.body_pos[b]
    lines.append(f"{pad}{'ROOT' if is_root else 'JOINT'} {names[b]}")
    lines.append(f"{pad}{{")
    lines.append(f"{pad}  OFFSET {_numbers(off)}")
    moves = is_root or bool(slide[b])
    channels = ["Xposition", "Yposition", "Zposition"] if moves else []
    channels += [f"{a}rotation" for a in orders[b]]
    lines.append(f"{pad}  CHANNELS {len(channels)} {' '.join(channels)}")
    ctx["columns"].append((b, moves))
    kids = children.get(b, [])
    for c in kids:
        _joint_lines(model, c, depth + 1, ctx)
    if not kids:
        tip = tips.get(b, _default_tip(model, b, smap))
        lines += [f"{pad}  End Site", f"{pad}  {{", f"{pad}    OFFSET {_numbers(tip)}"]
        lines.append(f"{pad}  }}")
    lines.append(f"{pad}}}")


def _numbers(v) -> str:
    return mo.float_rows(np.asarray(v, float)[None], DIGITS, " ", "")


def _frame_values(model, qpos, columns, orders) -> np.ndarray:
    """The motion lines' numbers (T, channels) of frames ``qpos``: per joint, its local
    position (if it moves) then its Euler angles [degrees] in its order."""
    from scipy.spatial.transform import Rotation

    lpos, lquat = _local_yup(model, qpos)
    parts = []
    for b, moves in columns:
        if b < 0:  # the still world root
            parts.append(np.zeros((len(qpos), 6)))
            continue
        if moves:
            parts.append(lpos[:, b])
        with warnings.catch_warnings():  # a middle angle at 90 degrees: still exact
            warnings.simplefilter("ignore")
            rot = Rotation.from_quat(lquat[:, b][:, [1, 2, 3, 0]])
            parts.append(rot.as_euler(orders[b], degrees=True))
    return np.concatenate(parts, axis=1)


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
    """Write the motion to ``path`` as BVH (the caller makes it atomic), a chunk of frames
    at a time (see the module docstring)."""
    mo.check_qpos(model, qpos, fps)
    qpos = np.asarray(qpos)
    _, slide = mo.moving_bodies(model)
    children: dict[int, list[int]] = {}
    for b in range(1, model.nbody):
        children.setdefault(int(model.body_parentid[b]), []).append(b)
    orders = _orders(model, qpos)
    info = (joint_names(model, signer_map), orders, slide, _tip_offsets(model, signer_map))
    ctx = {"info": (*info, children, signer_map), "lines": ["HIERARCHY"], "columns": []}
    roots = children.get(0, [])
    if len(roots) == 1:
        _joint_lines(model, roots[0], 0, ctx)
    else:  # several bodies hang from the world: a still root joint holds them
        ctx["lines"] += [
            "ROOT world",
            "{",
            "  OFFSET 0.0 0.0 0.0",
            "  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation",
        ]
        ctx["columns"].append((-1, True))
        for c in roots:
            _joint_lines(model, c, 1, ctx)
        ctx["lines"].append("}")
    ctx["lines"] += ["MOTION", f"Frames: {len(qpos)}", f"Frame Time: {1.0 / fps!r}", ""]
    with open(path, "w", encoding="ascii") as f:
        f.write("\n".join(ctx["lines"]))
        for _, q in mo.chunks(qpos):
            f.write(mo.float_rows(_frame_values(model, q, ctx["columns"], orders), DIGITS, " "))
