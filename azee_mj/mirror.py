"""Left-handed signing as the mirror image of right-handed signing, by construction.

A left-handed signer is a right-handed one seen in a mirror (the signer's sagittal plane,
``y = 0``). Rather than hoping that a numerical solve from other starting points lands on
mirrored postures, a score with ``strong_side: "L"`` is mirrored (:func:`mirror_score`: every
side swapped, every literal point and vector reflected), realized as right-handed, and the
motion mirrored back (:class:`JointMirror`). The bundled signer is symmetric, so the result
is the exact mirror image of the right-handed realization.
"""

from __future__ import annotations

import dataclasses
import re

import mujoco
import numpy as np

from azee_mj import score as sc

_SIDE = re.compile(r"(?<=_)([LR])(?=_|$)")
_REFLECT = np.array([1.0, -1.0, 1.0])


def mirror_name(name: str) -> str:
    """``name`` with its side swapped: ``I_TIP_R`` -> ``I_TIP_L``, ``arm_L_flex`` ->
    ``arm_R_flex``, ``Rssp`` -> ``Lssp``; a midline name is unchanged."""
    if name in ("Rssp", "Lssp"):
        return {"Rssp": "Lssp", "Lssp": "Rssp"}[name]
    return _SIDE.sub(lambda m: "L" if m.group(1) == "R" else "R", name)


def _xyz(v) -> tuple[float, float, float]:
    return tuple(float(x) for x in np.asarray(v, float) * _REFLECT)  # type: ignore[return-value]


_AXIS_NAME = {"left": "right", "right": "left"}


def mirror_words(text: str) -> str:
    """``text`` with every sided name in it swapped (``palm_R`` -> ``palm_L``)."""
    return re.sub(r"[A-Za-z][A-Za-z0-9_]*", lambda m: mirror_name(m.group(0)), text)


def _mirror(obj):
    """The mirror image of a score record (recursively)."""
    if isinstance(obj, tuple):
        return tuple(_mirror(x) for x in obj)
    if isinstance(obj, sc.SiteRef):
        return dataclasses.replace(obj, name=mirror_name(obj.name))
    if isinstance(obj, sc.BoneRef):
        return dataclasses.replace(obj, name=mirror_name(obj.name))
    if isinstance(obj, (sc.PLiteral, sc.VLiteral)):
        return dataclasses.replace(obj, xyz=_xyz(obj.xyz))
    if isinstance(obj, sc.VAxis):
        return dataclasses.replace(obj, xyz=_xyz(obj.xyz), name=_AXIS_NAME.get(obj.name, obj.name))
    if isinstance(obj, sc.VCross):
        # A reflection M turns a x b into -(Ma x Mb).
        return sc.VOpp(sc.VCross(_mirror(obj.a), _mirror(obj.b)))
    if isinstance(obj, sc.MorphC):
        side = {"L": "R", "R": "L"}.get(obj.side) if obj.side else None
        return dataclasses.replace(obj, side=side)
    if isinstance(obj, sc.Trill):
        # A rotation turns the other way in the mirror; a displacement does not.
        amp = -obj.amplitude if obj.bone is not None else obj.amplitude
        return dataclasses.replace(
            obj,
            site=_mirror(obj.site),
            bone=_mirror(obj.bone),
            vector=_mirror(obj.vector),
            amplitude=amp,
        )
    if isinstance(obj, sc.Score):
        return dataclasses.replace(
            obj, strong_side={"L": "R", "R": "L"}[obj.strong_side], root=_mirror(obj.root)
        )
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        changes = {
            f.name: _mirror(getattr(obj, f.name))
            for f in dataclasses.fields(obj)
            if f.name != "annotations"
        }
        return dataclasses.replace(obj, **changes)
    return obj


def mirror_score(score: sc.Score) -> sc.Score:
    """The score a mirror shows: sides swapped, points and vectors reflected in ``y = 0``,
    rotations reversed, ``strong_side`` swapped."""
    return _mirror(score)


class JointMirror:
    """Maps postures of a left/right symmetric model onto their mirror images.

    Each joint maps to its mirror joint (its own mirror on the midline) with a sign: a hinge
    whose mirror axis is the reflection of its axis turns the other way, a slide the same.
    Use :meth:`of`, which checks that the model is symmetric.
    """

    def __init__(self, model: mujoco.MjModel, perm: np.ndarray, sign: np.ndarray):
        self.model, self.perm, self.sign = model, perm, sign

    @classmethod
    def of(cls, model: mujoco.MjModel, tol: float = 1e-6) -> JointMirror | None:
        """The mirror of ``model``, or None if its joints or sites do not pair up by name
        (``_L`` / ``_R``) into mirror images within ``tol`` [m]."""
        m = model
        d = mujoco.MjData(m)
        mujoco.mj_kinematics(m, d)
        perm, sign = np.arange(m.nq), np.ones(m.nq)
        for j in range(m.njnt):
            name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j)
            k = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, mirror_name(name))
            kind = int(m.jnt_type[j])
            if k < 0 or kind not in (
                int(mujoco.mjtJoint.mjJNT_HINGE),
                int(mujoco.mjtJoint.mjJNT_SLIDE),
            ):
                return None
            c = float((_REFLECT * d.xaxis[j]) @ d.xaxis[k])
            hinge = kind == int(mujoco.mjtJoint.mjJNT_HINGE)
            perm[m.jnt_qposadr[j]] = m.jnt_qposadr[k]
            sign[m.jnt_qposadr[j]] = -np.sign(c) if hinge else np.sign(c)
        out = cls(m, perm, sign)
        return out if out._symmetric(tol) else None

    def _symmetric(self, tol: float) -> bool:
        m = self.model
        d = mujoco.MjData(m)
        rng = np.random.default_rng(0)
        lo, hi = m.jnt_range[m.dof_jntid].T
        q = np.where(m.jnt_limited[m.dof_jntid], rng.uniform(lo, hi), 0.0)
        pos = []
        for qq in (q, self(q)):
            d.qpos[:] = qq
            mujoco.mj_kinematics(m, d)
            pos.append(d.site_xpos.copy())
        for i in range(m.nsite):
            name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_SITE, i)
            k = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, mirror_name(name))
            if k >= 0 and np.abs(pos[0][i] * _REFLECT - pos[1][k]).max() > tol:
                return False
        return True

    def __call__(self, qpos: np.ndarray) -> np.ndarray:
        """(..., nq) mirrored postures."""
        q = np.asarray(qpos, float)
        return q[..., self.perm] * self.sign
