"""What every exporter needs: the motion record, forward kinematics per frame, the axis
change to Y-up formats, and the optional-extra import with its install hint.

Units: metres, radians, seconds; quaternions ``wxyz`` unless a function says otherwise.
"""

from __future__ import annotations

import dataclasses
import importlib
from collections.abc import Iterator, Mapping

import mujoco
import numpy as np

from azee_mj.errors import AzeeError

#: How to install the libraries the exporters use.
EXPORT_HINT = "pip install azee_mj[export]"
#: Frames computed and written at a time by the streaming writers (BVH, CSV, .pose): their
#: memory stays bounded whatever the motion's length.
CHUNK = 512

#: Signer frame (x forward, y left, z up) -> Y-up frame (x to the signer's left, y up, z
#: forward), as glTF and BVH expect: a proper rotation (a cyclic permutation of the axes).
YUP = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])


class MissingExtraError(AzeeError):
    """An exporter's optional library is not installed."""


def require(module: str, what: str):
    """Import ``module`` or raise :class:`MissingExtraError` saying how to install it."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise MissingExtraError(
            f"{what} export needs the package {module.split('.')[0]!r}: {EXPORT_HINT}"
        ) from None


@dataclasses.dataclass(frozen=True)
class Motion:
    """A motion to export.

    Attributes:
      qpos: (T, nq) postures in the model's joint order.
      fps: frames per second; frame ``k`` is at ``k / fps`` seconds.
      schedule: per track, ``(block, start, end)`` intervals [s] (empty when unknown).
      name: a label (the input file's stem).
    """

    qpos: np.ndarray
    fps: float
    schedule: Mapping[str, tuple[tuple[str, float, float], ...]] = dataclasses.field(
        default_factory=dict
    )
    name: str = ""

    @property
    def time(self) -> np.ndarray:
        """(T,) frame times [s]."""
        return np.arange(len(self.qpos)) / self.fps


def schedule_tuples(schedule) -> dict[str, tuple[tuple[str, float, float], ...]]:
    """A schedule of :class:`~azee_mj.timeline.TrackInterval` s (or of tuples) as tuples."""
    out = {}
    for track, ivs in schedule.items():
        out[track] = tuple(
            (i.block, float(i.start), float(i.end))
            if hasattr(i, "block")
            else (str(i[0]), float(i[1]), float(i[2]))
            for i in ivs
        )
    return out


def check_qpos(model: mujoco.MjModel, qpos: np.ndarray, fps: float, where: str = "qpos"):
    """Raise :class:`AzeeError` unless ``qpos`` is (T >= 1, nq) finite and ``fps`` > 0."""
    q = np.asarray(qpos)
    if q.ndim != 2 or q.shape[1] != model.nq or len(q) == 0:
        raise AzeeError(
            f"{where}: expected postures of shape (T >= 1, {model.nq}) for this "
            f"signer; got shape {q.shape}"
        )
    if not np.all(np.isfinite(q)):
        raise AzeeError(f"{where}: holds non-finite values")
    if not (np.isfinite(fps) and fps > 0):
        raise AzeeError(f"fps must be positive, got {fps}")


def chunks(qpos: np.ndarray, size: int = CHUNK) -> Iterator[tuple[int, np.ndarray]]:
    """``(first frame, postures as floats)`` of each chunk of ``size`` frames of ``qpos``,
    in order."""
    for k0 in range(0, len(qpos), size):
        yield k0, np.asarray(qpos[k0 : k0 + size], float)


def float_rows(
    values: np.ndarray, digits: int, sep: str, end: str = "\n", always_float: bool = False
) -> str:
    """Rows of ``values`` (N, M) as text lines ending in ``end``, numbers separated by
    ``sep``, each with ``digits`` significant digits; ``always_float``: a whole number is
    written ``12.0``, never ``12``, so that a reader infers a float column."""
    n, m = values.shape
    if n == 0:
        return ""
    g = f"%.{digits}g"
    whole = np.zeros(values.shape, bool)
    if always_float:  # would print without a point: a whole number at ``digits`` digits
        size = np.abs(values)
        with np.errstate(divide="ignore"):
            step = 10.0 ** (
                np.floor(np.log10(np.maximum(size, np.finfo(float).smallest_subnormal)))
                - digits
                + 1
            )
        whole = (np.abs(values - np.round(values)) <= step / 2) & (size < 10.0**digits)
    if not whole.any():
        return ((sep.join([g] * m) + end) * n) % tuple(values.ravel().tolist())
    cells = np.where(whole, "%.1f", g).tolist()
    return (end.join(sep.join(row) for row in cells) + end) % tuple(values.ravel().tolist())


def body_frames(model: mujoco.MjModel, qpos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World position (T, nbody, 3) [m] and orientation (T, nbody, 4) ``wxyz`` of every
    body on every frame (``mj_kinematics``)."""
    data = mujoco.MjData(model)
    T = len(qpos)
    pos = np.empty((T, model.nbody, 3))
    quat = np.empty((T, model.nbody, 4))
    for k in range(T):
        data.qpos[:] = qpos[k]
        mujoco.mj_kinematics(model, data)
        pos[k], quat[k] = data.xpos, data.xquat
    return pos, quat


def site_positions(model: mujoco.MjModel, qpos: np.ndarray, sites: list[str]) -> np.ndarray:
    """World positions (T, len(sites), 3) [m] of the named model sites on every frame."""
    ids = []
    for s in sites:
        i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, s)
        if i < 0:
            raise AzeeError(f"site {s!r} is not in the model")
        ids.append(i)
    data = mujoco.MjData(model)
    out = np.empty((len(qpos), len(ids), 3))
    for k in range(len(qpos)):
        data.qpos[:] = qpos[k]
        mujoco.mj_kinematics(model, data)
        out[k] = data.site_xpos[ids]
    return out


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton products ``a * b`` of quaternions (..., 4) ``wxyz``."""
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        -1,
    )


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Vectors (..., 3) rotated by unit quaternions (..., 4) ``wxyz``."""
    w, u = q[..., :1], q[..., 1:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def local_frames(
    model: mujoco.MjModel, pos: np.ndarray, quat: np.ndarray, prev: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Each body's pose in its parent's frame, (T, nbody, 3) and (T, nbody, 4) ``wxyz``,
    from world frames as :func:`body_frames` gives them (the world body keeps its own).
    Quaternion signs are made continuous in time (no flip between consecutive frames) for
    readers that interpolate; ``prev``: the local quaternions (nbody, 4) of the frame just
    before these (the previous chunk's last), so that signs stay continuous across chunks."""
    parent = np.array(model.body_parentid)
    inv = quat[:, parent] * np.array([1.0, -1.0, -1.0, -1.0])
    lquat = quat_mul(inv, quat)
    lquat /= np.linalg.norm(lquat, axis=-1, keepdims=True)
    lpos = quat_rotate(inv, pos - pos[:, parent])
    lpos[:, 0], lquat[:, 0] = pos[:, 0], quat[:, 0]
    for k in range(len(pos)):
        before = lquat[k - 1] if k else prev
        if before is not None:
            flip = np.sum(lquat[k] * before, axis=1) < 0
            lquat[k, flip] *= -1
    return lpos, lquat


def quat_to_yup(q: np.ndarray) -> np.ndarray:
    """Quaternions ``wxyz`` (..., 4) in the signer frame -> the same rotations in the Y-up
    frame of :data:`YUP`, still ``wxyz``."""
    q = np.asarray(q)
    return np.concatenate([q[..., :1], q[..., 1:] @ YUP.T], axis=-1)


def body_names(model: mujoco.MjModel) -> list[str]:
    """Names of the model's bodies, in body-id order."""
    return [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) for b in range(model.nbody)]


def moving_bodies(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """Per body: has a hinge (rotates relative to its parent), has a slide (translates)."""
    rot = np.zeros(model.nbody, bool)
    slide = np.zeros(model.nbody, bool)
    for j in range(model.njnt):
        t = int(model.jnt_type[j])
        if t in (int(mujoco.mjtJoint.mjJNT_SLIDE), int(mujoco.mjtJoint.mjJNT_FREE)):
            slide[model.jnt_bodyid[j]] = True
        if t != int(mujoco.mjtJoint.mjJNT_SLIDE):
            rot[model.jnt_bodyid[j]] = True
            if np.any(model.jnt_pos[j]):  # a hinge off the body origin moves the origin
                slide[model.jnt_bodyid[j]] = True
    return rot, slide
