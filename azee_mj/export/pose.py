"""``.pose`` (pose-format): the signer's keypoints in MediaPipe Holistic's layout.

Components, with MediaPipe's names (the signer's own left and right, as MediaPipe uses
them): ``POSE_LANDMARKS`` (the 33 BlazePose points), ``FACE_LANDMARKS`` (the face-mesh
points the signer has an AZee site for, named by their face-mesh index as in
pose-format's holistic files; ``468`` / ``473`` are the refined irises),
``LEFT_HAND_LANDMARKS`` and ``RIGHT_HAND_LANDMARKS`` (21 points, wrist to fingertips).
One person, confidence 1 on every point, the rollout's fps.

Each point is a sum of weighted terms, each an AZee site or an AZee bone's head (the
joint centre at its body's origin), or, for the legs the catalogue has no sites for, a
fixed point of the pelvis (:data:`POINTS`; ``docs/exports.md`` tabulates it).

Coordinates are those of a virtual orthographic camera in front of the signer, in pixels
of a ``WIDTH`` x ``HEIGHT`` image, ``SCALE`` pixels a metre (the visualizer draws them as
they are): ``x = CX + SCALE * y_signer`` (the signer's left to the right of the image,
as a camera facing the signer sees it), ``y = CY - SCALE * z_signer`` (down),
``z = -SCALE * x_signer`` (smaller is nearer the camera, as in MediaPipe).
:func:`pose_to_signer` inverts it.

Needs ``pose-format`` (``pip install azee_mj[export]``).
"""

from __future__ import annotations

import dataclasses
import math
import os
import struct

import mujoco
import numpy as np

from azee_mj.errors import AzeeError
from azee_mj.export import motion as mo
from azee_mj.sites import DEFAULT_MAP, SignerMap

#: Pixels a metre, image size and where the signer frame's origin lands [px].
SCALE = 500.0
WIDTH, HEIGHT = 1000, 1100
CX, CY = 500.0, 600.0


@dataclasses.dataclass(frozen=True)
class Term:
    """``weight`` times one of: AZee ``site``; the head of AZee ``bone``; ``offset`` [m] in
    the frame of model body ``body``; or, with ``carrier``, the point ``offset`` [m, signer
    frame] from AZee ``site`` at rest, carried by the model body ``carrier`` (a face part of
    the rig) or, when the model has no such body, by the site's own body."""

    weight: float = 1.0
    site: str | None = None
    bone: str | None = None
    body: str | None = None
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    carrier: str | None = None


def _s(name: str, w: float = 1.0) -> Term:
    return Term(w, site=name)


def _b(name: str) -> Term:
    return Term(bone=name)


def _eye_corner(side: str, brow_end: str) -> tuple[Term, ...]:
    # the eye plus the brow end's offset from the brow's middle: the corner below it
    return (_s(f"EYE_{side}"), _s(f"{brow_end}_{side}"), _s(f"EB_{side}", -1.0))


#: The bundled signer's legs (visual geoms on the pelvis): hip, knee, ankle, heel, toe
#: in the pelvis frame [m], right side (the left mirrors y).
LEG_POINTS_R = {
    "HIP": (-0.015, -0.085, -0.02),
    "KNEE": (0.0, -0.095, -0.47),
    "ANKLE": (-0.02, -0.1, -0.86),
    "HEEL": (-0.095, -0.1, -0.915),
    "FOOT_INDEX": (0.155, -0.1, -0.915),
}

POSE_POINTS = (
    "NOSE",
    "LEFT_EYE_INNER",
    "LEFT_EYE",
    "LEFT_EYE_OUTER",
    "RIGHT_EYE_INNER",
    "RIGHT_EYE",
    "RIGHT_EYE_OUTER",
    "LEFT_EAR",
    "RIGHT_EAR",
    "MOUTH_LEFT",
    "MOUTH_RIGHT",
    "LEFT_SHOULDER",
    "RIGHT_SHOULDER",
    "LEFT_ELBOW",
    "RIGHT_ELBOW",
    "LEFT_WRIST",
    "RIGHT_WRIST",
    "LEFT_PINKY",
    "RIGHT_PINKY",
    "LEFT_INDEX",
    "RIGHT_INDEX",
    "LEFT_THUMB",
    "RIGHT_THUMB",
    "LEFT_HIP",
    "RIGHT_HIP",
    "LEFT_KNEE",
    "RIGHT_KNEE",
    "LEFT_ANKLE",
    "RIGHT_ANKLE",
    "LEFT_HEEL",
    "RIGHT_HEEL",
    "LEFT_FOOT_INDEX",
    "RIGHT_FOOT_INDEX",
)
#: MediaPipe's POSE_CONNECTIONS.
POSE_LIMBS = (
    (0, 1),
    (1, 2),
    (2, 3),
    (3, 7),
    (0, 4),
    (4, 5),
    (5, 6),
    (6, 8),
    (9, 10),
    (11, 12),
    (11, 13),
    (13, 15),
    (15, 17),
    (15, 19),
    (15, 21),
    (17, 19),
    (12, 14),
    (14, 16),
    (16, 18),
    (16, 20),
    (16, 22),
    (18, 20),
    (11, 23),
    (12, 24),
    (23, 24),
    (23, 25),
    (24, 26),
    (25, 27),
    (26, 28),
    (27, 29),
    (28, 30),
    (29, 31),
    (30, 32),
    (27, 31),
    (28, 32),
)
HAND_POINTS = (
    "WRIST",
    "THUMB_CMC",
    "THUMB_MCP",
    "THUMB_IP",
    "THUMB_TIP",
    "INDEX_FINGER_MCP",
    "INDEX_FINGER_PIP",
    "INDEX_FINGER_DIP",
    "INDEX_FINGER_TIP",
    "MIDDLE_FINGER_MCP",
    "MIDDLE_FINGER_PIP",
    "MIDDLE_FINGER_DIP",
    "MIDDLE_FINGER_TIP",
    "RING_FINGER_MCP",
    "RING_FINGER_PIP",
    "RING_FINGER_DIP",
    "RING_FINGER_TIP",
    "PINKY_MCP",
    "PINKY_PIP",
    "PINKY_DIP",
    "PINKY_TIP",
)
#: MediaPipe's HAND_CONNECTIONS.
HAND_LIMBS = (
    (0, 1),
    (1, 2),
    (2, 3),
    (3, 4),
    (0, 5),
    (5, 6),
    (6, 7),
    (7, 8),
    (5, 9),
    (9, 10),
    (10, 11),
    (11, 12),
    (9, 13),
    (13, 14),
    (14, 15),
    (15, 16),
    (13, 17),
    (0, 17),
    (17, 18),
    (18, 19),
    (19, 20),
)
#: Face-mesh index -> AZee site (the subject's right is MediaPipe's lower-numbered side).
FACE_SITES = {
    "1": "NO",
    "2": "NSP",
    "13": "MO",
    "152": "CH",
    "151": "FH",
    "468": "EYE_R",
    "473": "EYE_L",
    "105": "EB_R",
    "334": "EB_L",
    "107": "EBi_R",
    "336": "EBi_L",
    "70": "EBe_R",
    "300": "EBe_L",
    "61": "MO_R",
    "291": "MO_L",
    "98": "NO_R",
    "327": "NO_L",
    "50": "CK_R",
    "280": "CK_L",
    "21": "TE_R",
    "251": "TE_L",
    "234": "EAR_R",
    "454": "EAR_L",
    "93": "LOBE_R",
    "323": "LOBE_L",
}
#: Face points carried by the rig's face parts: face-mesh index -> (AZee site, the model
#: bodies that move it, offset from the site at rest [m, signer frame]). A point carried by
#: two bodies is their mean (the lips' two halves meet on the midline). The brows (105, 107
#: on the inner brow, 70 on the outer) and mouth corners ride on their bodies; the upper
#: lids' margins (159, 386) on the lids, where the lid meets the eyeball in front (11.9 mm
#: from the eye's centre, 26 degrees above its axis); the lower lids' (145, 374) 30 degrees
#: below; the lips' inner edges (13, 14) on the upper and lower lip on the midline.
FACE_RIG = {
    **{
        i: (site, (body + site[-1],), (0.0, 0.0, 0.0))
        for i, site, body in (
            ("105", "EB_R", "brow_"),
            ("334", "EB_L", "brow_"),
            ("107", "EBi_R", "brow_"),
            ("336", "EBi_L", "brow_"),
            ("70", "EBe_R", "brow_out_"),
            ("300", "EBe_L", "brow_out_"),
            ("61", "MO_R", "mouth_"),
            ("291", "MO_L", "mouth_"),
        )
    },
    "159": ("EYE_R", ("lid_R",), (-0.00172, 0.0, 0.00526)),
    "386": ("EYE_L", ("lid_L",), (-0.00172, 0.0, 0.00526)),
    "145": ("EYE_R", ("lid_low_R",), (-0.00212, 0.0, -0.00601)),
    "374": ("EYE_L", ("lid_low_L",), (-0.00212, 0.0, -0.00601)),
    "13": ("MO", ("lip_up_R", "lip_up_L"), (-0.002744, 0.0, -0.002854)),
    "14": ("MO", ("lip_low_R", "lip_low_L"), (-0.003744, 0.0, -0.003954)),
}
#: Lines drawn between face points (brows, eyes, nose, mouth, the side of the face).
FACE_LIMBS_BY_NAME = (
    ("70", "105"),
    ("105", "107"),
    ("336", "334"),
    ("334", "300"),
    ("468", "473"),
    ("151", "1"),
    ("98", "2"),
    ("2", "327"),
    ("61", "13"),
    ("13", "291"),
    ("13", "152"),
    ("21", "234"),
    ("234", "93"),
    ("251", "454"),
    ("454", "323"),
    ("50", "61"),
    ("280", "291"),
    ("159", "145"),
    ("386", "374"),
    ("61", "14"),
    ("14", "291"),
)

_HAND_DIGITS = (
    ("THUMB", "thumb", "T"),
    ("INDEX_FINGER", "index", "I"),
    ("MIDDLE_FINGER", "middle", "M"),
    ("RING_FINGER", "ring", "R"),
    ("PINKY", "little", "L"),
)


def _pose_point_terms(name: str) -> tuple[Term, ...]:
    side = "L" if name.startswith("LEFT") else "R"
    part = name.split("_", 1)[1] if name.startswith(("LEFT_", "RIGHT_")) else name
    if name == "NOSE":
        return (_s("NO"),)
    if name.startswith("MOUTH_"):
        return (_s("MO_L" if name.endswith("LEFT") else "MO_R"),)
    table = {
        "EYE": (_s(f"EYE_{side}"),),
        "EYE_INNER": _eye_corner(side, "EBi"),
        "EYE_OUTER": _eye_corner(side, "EBe"),
        "EAR": (_s(f"EAR_{side}"),),
        "SHOULDER": (_b(f"arm_{side}"),),
        "ELBOW": (_b(f"f_arm_{side}"),),
        "WRIST": (_s(f"WR_{side}"),),
        "PINKY": (_b(f"little_{side}_1"),),
        "INDEX": (_b(f"index_{side}_1"),),
        "THUMB": (_b(f"thumb_{side}_2"),),
    }
    if part in table:
        return table[part]
    x, y, z = LEG_POINTS_R[part]
    return (Term(body="pelvis", offset=(x, y if side == "R" else -y, z)),)


def _face(index: str, site: str) -> tuple[Term, ...]:
    if index not in FACE_RIG:
        return (_s(site),)
    site, carriers, offset = FACE_RIG[index]
    w = 1.0 / len(carriers)
    return tuple(Term(w, site=site, carrier=c, offset=offset) for c in carriers)


def _hand_terms(side: str) -> list[tuple[Term, ...]]:
    out = [(_s(f"WR_{side}"),)]
    for _, bone, letter in _HAND_DIGITS:
        out += [(_b(f"{bone}_{side}_{n}"),) for n in (1, 2, 3)]
        out.append((_s(f"{letter}_TIP_{side}"),))
    return out


#: Component -> (point names, the terms of each point).
POINTS: dict[str, tuple[tuple[str, ...], tuple[tuple[Term, ...], ...]]] = {
    "POSE_LANDMARKS": (POSE_POINTS, tuple(_pose_point_terms(p) for p in POSE_POINTS)),
    "FACE_LANDMARKS": (
        (*FACE_SITES, *(i for i in FACE_RIG if i not in FACE_SITES)),
        (
            *(_face(i, s) for i, s in FACE_SITES.items()),
            *(_face(i, FACE_RIG[i][0]) for i in FACE_RIG if i not in FACE_SITES),
        ),
    ),
    "LEFT_HAND_LANDMARKS": (HAND_POINTS, tuple(_hand_terms("L"))),
    "RIGHT_HAND_LANDMARKS": (HAND_POINTS, tuple(_hand_terms("R"))),
}


def signer_to_pose(p: np.ndarray) -> np.ndarray:
    """Signer-frame points (..., 3) [m] -> .pose coordinates (..., 3) [px]."""
    p = np.asarray(p, float)
    return np.stack([CX + SCALE * p[..., 1], CY - SCALE * p[..., 2], -SCALE * p[..., 0]], -1)


def pose_to_signer(p: np.ndarray) -> np.ndarray:
    """.pose coordinates (..., 3) [px] -> signer-frame points (..., 3) [m]."""
    p = np.asarray(p, float)
    return np.stack([-p[..., 2] / SCALE, (p[..., 0] - CX) / SCALE, (CY - p[..., 1]) / SCALE], -1)


def keypoints(
    model: mujoco.MjModel, qpos: np.ndarray, signer_map: SignerMap = DEFAULT_MAP
) -> dict[str, np.ndarray]:
    """Per component, its points (T, P, 3) in the signer frame [m] on every frame."""
    data = mujoco.MjData(model)
    T = len(qpos)
    site = np.empty((T, model.nsite, 3))
    xpos = np.empty((T, model.nbody, 3))
    xmat = np.empty((T, model.nbody, 3, 3))
    for k in range(T):
        data.qpos[:] = qpos[k]
        mujoco.mj_kinematics(model, data)
        site[k], xpos[k] = data.site_xpos, data.xpos
        xmat[k] = data.xmat.reshape(-1, 3, 3)
    out = {}
    for c, (names, terms) in POINTS.items():
        pts = np.zeros((T, len(names), 3))
        for i, point in enumerate(terms):
            for t in point:
                w, s, b, off = _resolve(model, t, signer_map)
                pts[:, i] += w * (site[:, s] if s >= 0 else xpos[:, b] + xmat[:, b] @ off)
        out[c] = pts
    return out


def _carried(model: mujoco.MjModel, t: Term, smap: SignerMap) -> tuple[int, np.ndarray]:
    """The body carrying ``t`` and the point's offset in that body's frame (from qpos0)."""
    s = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, smap.sites[t.site])
    if s < 0:
        raise AzeeError(f".pose export: the model has no site {smap.sites[t.site]!r}")
    b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, t.carrier)
    b = int(model.site_bodyid[s]) if b < 0 else b
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    p = data.site_xpos[s] + np.asarray(t.offset, float)
    return b, data.xmat[b].reshape(3, 3).T @ (p - data.xpos[b])


def _resolve(model, t: Term, smap: SignerMap):
    if t.carrier is not None:
        b, off = _carried(model, t, smap)
        return (t.weight, -1, b, off)
    if t.site is not None:
        s = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, smap.sites[t.site])
        if s < 0:
            raise AzeeError(f".pose export: the model has no site {smap.sites[t.site]!r}")
        return (t.weight, s, -1, None)
    body = smap.bones[t.bone].body if t.bone is not None else t.body
    b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
    if b < 0:
        raise AzeeError(f".pose export: the model has no body {body!r}")
    return (t.weight, -1, b, np.asarray(t.offset, float))


def _face_limbs() -> list[tuple[int, int]]:
    idx = {n: i for i, n in enumerate(POINTS["FACE_LANDMARKS"][0])}
    return [(idx[a], idx[b]) for a, b in FACE_LIMBS_BY_NAME]


def _hand_colors() -> list[tuple[int, int, int]]:
    # pose-format's holistic hand palette: a hue per finger, lighter toward the tip
    base = [(192, 0, 0), (192, 192, 0), (0, 192, 0), (0, 192, 192), (0, 0, 192)]
    return [(255, 0, 0)] + [
        tuple(min(255, math.floor(x + 35 * (i % 4))) for x in base[i // 4]) for i in range(20)
    ]


def pose_header():
    """The file's ``pose_format.PoseHeader``: the four components with their points,
    limbs and colours, a ``WIDTH`` x ``HEIGHT`` image."""
    mo.require("pose_format", ".pose")
    from pose_format.pose_header import PoseHeader, PoseHeaderComponent, PoseHeaderDimensions

    limbs = {
        "POSE_LANDMARKS": list(POSE_LIMBS),
        "FACE_LANDMARKS": _face_limbs(),
        "LEFT_HAND_LANDMARKS": list(HAND_LIMBS),
        "RIGHT_HAND_LANDMARKS": list(HAND_LIMBS),
    }
    colors = {
        "POSE_LANDMARKS": [(255, 0, 0)],
        "FACE_LANDMARKS": [(128, 0, 0)],
        "LEFT_HAND_LANDMARKS": _hand_colors(),
        "RIGHT_HAND_LANDMARKS": _hand_colors(),
    }
    components = [
        PoseHeaderComponent(
            name=c, points=list(POINTS[c][0]), limbs=limbs[c], colors=colors[c], point_format="XYZC"
        )
        for c in POINTS
    ]
    return PoseHeader(
        version=0.2, dimensions=PoseHeaderDimensions(WIDTH, HEIGHT, 0), components=components
    )


def _points(model, qpos: np.ndarray, signer_map: SignerMap) -> np.ndarray:
    """The keypoints of every component in file order, (T, points, 3) float32 [px]."""
    pts = keypoints(model, np.asarray(qpos, float), signer_map)
    return np.concatenate([signer_to_pose(pts[c]) for c in POINTS], axis=1).astype(np.float32)


def build_pose(
    model: mujoco.MjModel, qpos: np.ndarray, fps: float, *, signer_map: SignerMap = DEFAULT_MAP
):
    """The keypoints as a ``pose_format.Pose`` in memory (see the module docstring;
    :func:`write_pose` writes the same bytes a chunk of frames at a time)."""
    pf = mo.require("pose_format", ".pose")
    mo.require("pose_format.numpy", ".pose")
    from pose_format.numpy.pose_body import NumPyPoseBody

    mo.check_qpos(model, qpos, fps)
    data = _points(model, qpos, signer_map)[:, None]  # (frames, people, points, dims)
    conf = np.ones(data.shape[:3], np.float32)
    return pf.Pose(pose_header(), NumPyPoseBody(fps=float(fps), data=data, confidence=conf))


def write_pose(
    path: str | os.PathLike,
    model: mujoco.MjModel,
    qpos: np.ndarray,
    fps: float,
    *,
    signer_map: SignerMap = DEFAULT_MAP,
) -> None:
    """Write the keypoints to ``path`` as ``.pose`` (the caller makes it atomic), a chunk
    of frames at a time: the header, ``fps`` (float32), frames (uint32) and people
    (uint16), the points (frames, 1, points, 3) float32, then their confidences (all 1)."""
    mo.check_qpos(model, qpos, fps)
    header = pose_header()
    n = sum(len(POINTS[c][0]) for c in POINTS)
    T = len(qpos)
    with open(path, "wb") as f:
        header.write(f)
        f.write(struct.pack("<f", float(fps)) + struct.pack("<I", T) + struct.pack("<H", 1))
        f.writelines(_points(model, q, signer_map).tobytes() for _, q in mo.chunks(qpos))
        ones = np.ones(min(T, mo.CHUNK) * n, np.float32).tobytes()
        f.writelines(ones[: min(mo.CHUNK, T - k0) * n * 4] for k0 in range(0, T, mo.CHUNK))
