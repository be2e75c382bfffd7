"""Per-frame ARKit blend-shape weights of a realized motion, and the Live Link Face CSV.

**Weights from postures.** A motion is stored as postures (``qpos``), not as the weights
that made them, so the weights are read back from the rig: each of the 52 shapes is a
linear joint change (its catalogue morph, :func:`basis`), and on every frame the weights in
[0, 1] whose changes add up to the face joints' displacement from rest are found by
bounded least squares (each joint's row scaled by the largest change any shape makes to it,
and a small ridge term so that shapes moving the same joints share the displacement
evenly). When the rig's shapes are independent (no shape a combination of others within
[0, 1]) this gives back the weights the realizer used; on the bundled rig each shape alone
is read back within 0.001 (``tests/test_face_export.py``). A shape a signer map lacks
stays at 0.

**Live Link Face CSV** (the app's take export): ``Timecode`` (``HH:MM:SS:FF.mmm``, FF the
frame within the second at the motion's fps), ``BlendShapeCount`` (61: the 52 shapes and 9
rotations), the 52 shapes with their names capitalised, in ARKit's order
(:data:`azee_mj.arkit.ARKIT_SHAPES`), then ``HeadYaw, HeadPitch, HeadRoll``, ``LeftEyeYaw,
LeftEyePitch, LeftEyeRoll``, ``RightEyeYaw, RightEyePitch, RightEyeRoll`` in radians (as
PyLiveLinkFace decodes them). Ours: the head's yaw (positive toward the signer's left),
pitch (positive chin up) and roll (positive toward the signer's right shoulder) from its
orientation in the signer frame; each eye's yaw and pitch from its joints (positive left
and up), roll 0. The app's own sign conventions are not documented; these are unverified
against it.
"""

from __future__ import annotations

import dataclasses
import math
import os

import mujoco
import numpy as np
from scipy.optimize import lsq_linear

from azee_mj import arkit
from azee_mj.export import motion as mo
from azee_mj.sites import DEFAULT_MAP, SignerMap

#: Ridge weight of the least-squares fit (relative to a row's scale).
RIDGE = 1e-6
#: Weight of the fit's row that asks the weights' sum to be small (relative to a row's
#: scale): of the sets of weights that make the same posture, the one with the fewest.
SPARSE = 1e-5
#: Live Link Face's columns after the shapes.
ROTATIONS = (
    "HeadYaw",
    "HeadPitch",
    "HeadRoll",
    "LeftEyeYaw",
    "LeftEyePitch",
    "LeftEyeRoll",
    "RightEyeYaw",
    "RightEyePitch",
    "RightEyeRoll",
)


@dataclasses.dataclass(frozen=True)
class Basis:
    """The joint change of each shape: ``matrix[i, k]`` is the change of qpos address
    ``qadr[i]`` at weight 1 of shape ``arkit.ARKIT_SHAPES[k]`` [rad or m]; ``source[k]`` is
    ``catalogue``, or ``none`` for a shape the signer map lacks."""

    qadr: np.ndarray
    matrix: np.ndarray
    source: tuple[str, ...]


def _changes(name: str, smap: SignerMap) -> dict[str, float]:
    base, side = arkit.split(name)
    if name in smap.morphs:
        return smap.morphs[name].joint_changes(None)
    if side is not None and base in smap.morphs and smap.morphs[base].sided:
        return smap.morphs[base].joint_changes(side)
    return {}


def basis(model: mujoco.MjModel, signer_map: SignerMap = DEFAULT_MAP) -> Basis:
    """The shapes' joint changes on ``model`` (joints the model lacks are left out)."""
    cols, source = [], []
    for name in arkit.ARKIT_SHAPES:
        ch = _changes(name, signer_map)
        ids = {j: mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in ch}
        ch = {j: v for j, v in ch.items() if ids[j] >= 0}
        cols.append({int(model.jnt_qposadr[ids[j]]): v for j, v in ch.items()})
        source.append("catalogue" if ch else "none")
    qadr = np.array(sorted({a for c in cols for a in c}), int)
    row = {a: i for i, a in enumerate(qadr)}
    m = np.zeros((len(qadr), len(arkit.ARKIT_SHAPES)))
    for k, c in enumerate(cols):
        for a, v in c.items():
            m[row[a], k] = v
    return Basis(qadr, m, tuple(source))


def weights(
    model: mujoco.MjModel, qpos: np.ndarray, signer_map: SignerMap = DEFAULT_MAP
) -> np.ndarray:
    """(T, 52) ARKit weights in [0, 1] of every frame, in :data:`azee_mj.arkit.ARKIT_SHAPES` order
    (module docstring)."""
    b = basis(model, signer_map)
    qpos = np.atleast_2d(np.asarray(qpos, float))
    out = np.zeros((len(qpos), len(arkit.ARKIT_SHAPES)))
    used = np.flatnonzero(np.abs(b.matrix).sum(axis=0) > 0)
    if not len(used):
        return out
    scale = np.abs(b.matrix).max(axis=1)
    a = b.matrix[:, used] / scale[:, None]
    a = np.vstack(
        [a, math.sqrt(RIDGE) * np.eye(len(used)), math.sqrt(SPARSE) * np.ones((1, len(used)))]
    )
    disp = (qpos[:, b.qadr] - model.qpos0[b.qadr]) / scale
    zeros = np.zeros(len(used) + 1)
    for k, d in enumerate(disp):
        if not d.any():
            continue
        res = lsq_linear(a, np.concatenate([d, zeros]), bounds=(0.0, 1.0), method="bvls")
        out[k, used] = res.x
    return np.clip(out, 0.0, 1.0)


def _head_angles(model: mujoco.MjModel, qpos: np.ndarray, body: str) -> np.ndarray:
    """(T, 3) yaw, pitch, roll [rad] of ``body``'s frame in the signer frame (ZYX)."""
    data = mujoco.MjData(model)
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
    out = np.zeros((len(qpos), 3))
    for k, q in enumerate(qpos):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        r = data.xmat[bid].reshape(3, 3)
        yaw = math.atan2(r[1, 0], r[0, 0])
        pitch = math.asin(float(np.clip(r[2, 0], -1.0, 1.0)))  # chin up: forward axis up
        roll = math.atan2(r[2, 1], r[2, 2])
        out[k] = (yaw, pitch, roll)
    return out


def _joint(model: mujoco.MjModel, qpos: np.ndarray, name: str) -> np.ndarray:
    j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
    return qpos[:, model.jnt_qposadr[j]] if j >= 0 else np.zeros(len(qpos))


def timecode(t: float, fps: float) -> str:
    """``HH:MM:SS:FF.mmm`` of time ``t`` [s]: FF the frame in the second at ``fps``,
    ``mmm`` the thousandths of a frame."""
    whole = math.floor(t + 1e-9)
    frame = (t - whole) * fps
    ff = math.floor(frame + 1e-6)
    sub = min(999, round((frame - ff) * 1000))
    return f"{whole // 3600:02d}:{whole // 60 % 60:02d}:{whole % 60:02d}:{ff:02d}.{sub:03d}"


def livelink_header() -> list[str]:
    """The Live Link Face CSV header."""
    names = [n[0].upper() + n[1:] for n in arkit.ARKIT_SHAPES]
    return ["Timecode", "BlendShapeCount", *names, *ROTATIONS]


def write_livelink(
    path: str | os.PathLike,
    model: mujoco.MjModel,
    qpos: np.ndarray,
    fps: float,
    *,
    signer_map: SignerMap = DEFAULT_MAP,
) -> None:
    """Write the motion's face as a Live Link Face CSV (the caller makes it atomic)."""
    import csv

    mo.check_qpos(model, qpos, fps)
    qpos = np.asarray(qpos, float)
    w = weights(model, qpos, signer_map)
    head = _head_angles(model, qpos, signer_map.bones["head"].body)
    eyes = np.zeros((len(qpos), 6))
    for i, s in enumerate(("L", "R")):
        eyes[:, 3 * i] = _joint(model, qpos, f"eye_{s}_yaw")
        eyes[:, 3 * i + 1] = -_joint(model, qpos, f"eye_{s}_pitch")
    with open(path, "w", newline="") as f:
        out = csv.writer(f)
        out.writerow(livelink_header())
        for k in range(len(qpos)):
            row = [*(f"{v:.6g}" for v in w[k]), *(f"{v:.6g}" for v in (*head[k], *eyes[k]))]
            out.writerow([timecode(k / fps, fps), len(arkit.ARKIT_SHAPES) + len(ROTATIONS), *row])
