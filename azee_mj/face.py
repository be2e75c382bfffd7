"""The face rig measured: postures of face morphs and what a viewer sees of them.

Measures are taken by casting rays at the visual geometry (what a camera sees), in the
model's world frame at the posture given: the eyelid aperture (how much of the eye shows
on the vertical line through its centre), the lip aperture (how much of the inside of the
mouth shows on the midline), the cheek's bulge, and each face body's displacement.
Units: metres.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import mujoco
import numpy as np

from azee_mj.sites import DEFAULT_MAP, SignerMap

#: Ray sampling step [m] of the apertures.
STEP = 0.0001
_VISUAL = np.array([0, 0, 1, 0, 0, 0], np.uint8)  # geom group 2: what renders


def morph_posture(
    model: mujoco.MjModel,
    weights: Mapping[str, float],
    signer_map: SignerMap = DEFAULT_MAP,
    base: np.ndarray | None = None,
) -> np.ndarray:
    """(nq,) ``base`` (default the ``home`` keyframe) plus the morphs ``weights`` (id ->
    weight; a sided morph as ``"id:R"`` / ``"id:L"`` for one side), clipped to the ranges
    as scores apply them."""
    q = (model.key("home").qpos if base is None else base).copy()
    for key, w in weights.items():
        mid, _, side = key.partition(":")
        for j, v in signer_map.morphs[mid].joint_changes(side or None).items():
            jnt = model.joint(j)
            q[jnt.qposadr[0]] += w * v
    lo, hi = model.jnt_range[:, 0], model.jnt_range[:, 1]
    adr = model.jnt_qposadr
    limited = model.jnt_limited.astype(bool)
    q[adr[limited]] = np.clip(q[adr[limited]], lo[limited], hi[limited])
    return q


def _first_hit(model, data, pnt, vec) -> int:
    gid = np.array([-1], np.int32)
    mujoco.mj_ray(model, data, pnt, vec, _VISUAL, 1, -1, gid)
    return int(gid[0])


def _open_run(model, data, start, vec, along, n, shows) -> float:
    """Length [m] of the samples ``start + k STEP along`` (k < n) whose ray along ``vec``
    first meets a geom for which ``shows(geom)`` holds."""
    hits = [shows(_first_hit(model, data, start + k * STEP * along, vec)) for k in range(n)]
    return float(np.sum(hits)) * STEP


def eyelid_aperture(model: mujoco.MjModel, data: mujoco.MjData, side: str) -> float:
    """How much of eye ``side`` shows [m] on the vertical line through its centre, seen
    from straight ahead of the head (kinematics of ``data`` computed)."""
    eye = model.body(f"eye_{side}").id
    head = data.xmat[model.body("head").id].reshape(3, 3)
    fwd, up = head[:, 0], head[:, 2]
    centre = data.xpos[eye]
    start = centre + 0.05 * fwd - 0.015 * up
    return _open_run(
        model, data, start, -fwd, up, 300, lambda g: g >= 0 and model.geom_bodyid[g] == eye
    )


def mouth_geoms(model: mujoco.MjModel) -> set[int]:
    """The geoms of the inside of the mouth (the dark cavity and the tongue)."""
    mats = {mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_MATERIAL, n) for n in ("mouth", "tongue")}
    return {g for g in range(model.ngeom) if model.geom_matid[g] in mats}


def lip_aperture(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    """How much of the inside of the mouth shows [m] on the midline, seen from straight
    ahead of the head."""
    head = model.body("head").id
    rot = data.xmat[head].reshape(3, 3)
    fwd, up = rot[:, 0], rot[:, 2]
    # from 45 mm below to 35 mm above the mouth's middle at rest
    mouth = data.xpos[head] + rot @ np.array([0.2, 0.0, -0.019 - 0.045])
    inside = mouth_geoms(model)
    return _open_run(model, data, mouth, -fwd, up, 800, lambda g: g in inside)


def cheek_bulge(model: mujoco.MjModel, data: mujoco.MjData, side: str, rest: float) -> float:
    """How far [m] the skin of cheek ``side`` stands out of its rest place (``rest``:
    :func:`skin_depth` at the rest posture)."""
    return rest - skin_depth(model, data, side)


def skin_depth(model: mujoco.MjModel, data: mujoco.MjData, side: str) -> float:
    """Distance [m] to the skin from 50 mm out of the face along the cheek's puff axis,
    through the cheek body's rest place (fixed to the head)."""
    cheek = model.body(f"cheek_{side}").id
    head = model.body_parentid[cheek]
    axis = model.jnt_axis[model.joint(f"cheek_{side}_puff").id]
    R = data.xmat[head].reshape(3, 3)
    pnt = data.xpos[head] + R @ (model.body_pos[cheek] + 0.05 * axis)
    gid = np.array([-1], np.int32)
    return float(mujoco.mj_ray(model, data, pnt, -(R @ axis), _VISUAL, 1, -1, gid))


def face_bodies(model: mujoco.MjModel, signer_map: SignerMap = DEFAULT_MAP) -> list[int]:
    """The bodies the ``face`` track's joints move (and the eyes), in model order."""
    joints = set(signer_map.tracks.get("face", ())) | set(signer_map.tracks.get("eyes", ()))
    return sorted({int(model.joint(j).bodyid[0]) for j in joints})


@dataclasses.dataclass(frozen=True)
class Displacement:
    """How a posture moves the face: per body, the largest displacement [m] of a point of
    its visual geoms (their centres and the ends of their axes)."""

    by_body: Mapping[str, float]

    def moved(self, threshold: float = 0.0005) -> list[str]:
        """The bodies moved more than ``threshold`` [m], largest first."""
        items = sorted(self.by_body.items(), key=lambda kv: -kv[1])
        return [b for b, v in items if v > threshold]

    @property
    def largest(self) -> float:
        return max(self.by_body.values(), default=0.0)


def _extent(model: mujoco.MjModel, g: int) -> np.ndarray:
    """Half-extents of geom ``g`` along its own axes [m]."""
    s = model.geom_size[g]
    t = model.geom_type[g]
    if t == mujoco.mjtGeom.mjGEOM_SPHERE:
        return np.array([s[0], s[0], s[0]])
    if t in (mujoco.mjtGeom.mjGEOM_CAPSULE, mujoco.mjtGeom.mjGEOM_CYLINDER):
        return np.array([s[0], s[0], s[1] + s[0]])
    return np.array(s[:3])


def probe_points(model: mujoco.MjModel, data: mujoco.MjData, g: int) -> np.ndarray:
    """(7, 3) geom ``g``'s centre and the ends of its three axes, in the world [m]."""
    c, R = data.geom_xpos[g], data.geom_xmat[g].reshape(3, 3)
    e = _extent(model, g)
    axes = np.vstack([np.zeros(3), np.diag(e), -np.diag(e)])
    return c + axes @ R.T


def displacement(model: mujoco.MjModel, q0: np.ndarray, q1: np.ndarray) -> Displacement:
    """How posture ``q1`` moves each face body's visual geoms from posture ``q0``."""
    d = mujoco.MjData(model)
    bodies = face_bodies(model)
    geoms = {b: np.flatnonzero((model.geom_bodyid == b) & (model.geom_group == 2)) for b in bodies}
    pts = []
    for q in (q0, q1):
        d.qpos[:] = q
        mujoco.mj_kinematics(model, d)
        pts.append({g: probe_points(model, d, g) for gs in geoms.values() for g in gs})
    out = {}
    for b, gs in geoms.items():
        moved = [np.linalg.norm(pts[1][g] - pts[0][g], axis=1).max() for g in gs]
        out[model.body(b).name] = float(max(moved, default=0.0))
    return Displacement(out)
