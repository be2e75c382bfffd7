"""How natural a posture is: the effort of holding it and the comfort of its joints.

The posture solver meets the score's constraints first and avoids penetration second; among
the postures that remain it prefers the one a person would take, measured physically:

* **effort**: the gravity torque each joint must hold at rest, ``tau_i = M_i a_i . (r_i x g)``
  (``M_i`` and ``r_i`` the mass and centre of mass of everything the joint carries, from its
  anchor; ``a_i`` its axis), divided by the joint's strength [N m]. It is zero for a hanging
  arm, grows as the elbow rises or the trunk leans, and is what makes a held arm tuck its
  elbow rather than lift it.
* **comfort**: each joint's distance from its neutral angle, as a fraction of its range,
  weighted by its recruitment cost: fingers, wrist, forearm and arm are cheap, the
  clavicle dearer, the neck and spine dearest, so they move only when the arms cannot
  reach alone.

Both are residual rows with exact Jacobians (:func:`rows`), so a Gauss-Newton step can
minimise them; the gradient of the effort is analytic (derivatives of the joint axes and of
the carried centres of mass under each joint's rotation), checked against finite differences
in the tests. Units: metres, radians, newton-metres.
"""

from __future__ import annotations

import dataclasses
from typing import ClassVar

import mujoco
import numpy as np

from azee_mj import native
from azee_mj.kinematics import BodyOrigin, Kinematics


@dataclasses.dataclass(frozen=True)
class Naturalness:
    """The naturalness objective of one model.

    Attributes:
      neutral: (nv,) the neutral posture comfort pulls toward [rad].
      strength: (nv,) each hinge's strength [N m]; 0 = no effort row (fingers, face, eyes).
      comfort: (nv,) comfort weight per dof, already divided by the joint's range [1/rad].
      effort_weight: weight of the effort rows relative to the comfort rows.
    """

    neutral: np.ndarray
    strength: np.ndarray
    comfort: np.ndarray
    effort_weight: float = 1.0

    def __post_init__(self):
        for f in ("neutral", "strength", "comfort"):
            a = np.asarray(getattr(self, f), float)
            a.setflags(write=False)
            object.__setattr__(self, f, a)


class Effort:
    """Gravity torques of a model and their Jacobian, on the posture in ``data``.

    ``data`` must hold ``mj_kinematics`` and ``mj_comPos`` results (``xaxis``, ``xanchor``,
    ``subtree_com``).
    """

    def __init__(self, model: mujoco.MjModel, dofs: np.ndarray):
        m = model
        self.m = m
        self.dofs = np.asarray(dofs, int)
        self.jnt = m.dof_jntid[self.dofs]
        self.body = m.dof_bodyid[self.dofs]
        self.mass = m.body_subtreemass[self.body]
        n = m.nv
        # anc[k, i]: dof k is dof i or one of its ancestors (rotating k moves i's axis).
        anc = np.zeros((n, n), bool)
        for i in range(n):
            k = i
            while k >= 0:
                anc[k, i] = True
                k = m.dof_parentid[k]
        self.anc = anc
        #: ``anc`` as bytes for the compiled core.
        self.anc_u8 = anc.astype(np.uint8)
        self._dofs32 = self.dofs.astype(np.int32)

    def torques(self, d: mujoco.MjData) -> np.ndarray:
        """(len(dofs),) gravity torque each dof holds [N m]."""
        return self._eval(d, np.zeros(0, np.int32))[0]

    def jacobian(self, d: mujoco.MjData, cols: np.ndarray) -> np.ndarray:
        """(len(dofs), len(cols)) derivative of :meth:`torques` with respect to ``qpos[cols]``.

        For a dof k above dof i, rotating k turns i's axis and its carried centre of mass
        rigidly: ``d tau_i = M_i a_k . (a_i x (r_i x g) + r_i x (g x a_i))``. For k below i,
        only i's carried centre of mass moves: ``d tau_i = M_k (a_k x r_k) . (g x a_i)``.
        """
        cols = np.asarray(cols, np.int32)
        return self._eval(d, cols)[1].reshape(self.dofs.size, cols.size)

    def _eval(self, d: mujoco.MjData, cols: np.ndarray):
        # The solver's compiled core computes both (its polish uses the same code).
        tau, J = native.core().effort(
            self.m._address,
            d._address,
            self._dofs32,
            self.anc_u8,
            np.ascontiguousarray(cols, np.int32),
        )
        return np.frombuffer(tau), np.frombuffer(J)


def rows(nat: Naturalness, effort: Effort, d: mujoco.MjData, cols: np.ndarray):
    """Naturalness residual rows and their Jacobian over dofs ``cols``.

    Returns (r, J): effort rows ``sqrt(w) tau_i / strength_i`` for every dof with a strength,
    then comfort rows ``comfort_k (q_k - neutral_k)`` for the dofs ``cols``; the cost is
    ``r . r``.
    """
    s = nat.strength[effort.dofs]
    scale = np.sqrt(nat.effort_weight) / s
    re = scale * effort.torques(d)
    Je = scale[:, None] * effort.jacobian(d, cols)
    c = nat.comfort[cols]
    rc = c * (d.qpos[cols] - nat.neutral[cols])
    Jc = np.diag(c)
    return np.concatenate([re, rc]), np.vstack([Je, Jc])


#: Strength of each joint group [N m] (rough maximal isometric torques of an adult; only
#: their ratios matter): the trunk and the shoulder are strong, the neck and wrist weak.
STRENGTH = {
    "spine": 150.0,
    "head": 20.0,
    "clav": 50.0,
    "arm": 60.0,
    "f_arm_flex": 50.0,
    "f_arm_pron": 10.0,
    "palm": 10.0,
}
#: Recruitment cost per joint group: the comfort weight of one range's travel. Fingers,
#: wrist, forearm and arm move first, the clavicle next, the neck and spine last.
RECRUIT = {
    "hand": 0.3,
    "palm": 0.5,
    "f_arm": 0.5,
    "arm": 1.0,
    "clav": 4.0,
    "head": 8.0,
    "spine": 16.0,
    "eyes": 1.0,
    "face": 1.0,
}


_STEMS = (
    ("back", "spine"),
    ("neck", "head"),
    ("head", "head"),
    ("eye", "eyes"),
    ("clav", "clav"),
    ("f_arm", "f_arm"),
    ("arm", "arm"),
    ("palm", "palm"),
)


def _group(bone: str | None, track: str) -> str:
    """The joint group of a joint on AZee ``bone`` (None: no bone, e.g. the jaw)."""
    for stem, group in _STEMS:
        if bone is not None and bone.startswith(stem):
            return group
    return "hand" if bone is not None else track


def from_signer_map(
    model: mujoco.MjModel, signer_map, neutral: np.ndarray, effort_weight: float = 1.0
) -> Naturalness:
    """The objective of a signer mapped by ``signer_map`` (its AZee bones and articulator
    tracks), neutral at ``neutral`` (nq,). A joint's group is the AZee bone of its body; a
    forearm joint turning about the bone's DIR is the weaker pronation."""
    m = model
    bone_of = {b.body: name for name, b in signer_map.bones.items()}
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    strength = np.zeros(m.nv)
    comfort = np.zeros(m.nv)
    for track, joints in signer_map.tracks.items():
        for j in joints:
            jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j)
            if jid < 0:
                continue
            body = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, m.jnt_bodyid[jid])
            bone = bone_of.get(body)
            g = _group(bone, track)
            dof = m.jnt_dofadr[jid]
            span = float(np.ptp(m.jnt_range[jid])) if m.jnt_limited[jid] else np.pi
            comfort[dof] = np.sqrt(RECRUIT.get(g, 1.0)) / max(span, 1e-6)
            if m.jnt_type[jid] != mujoco.mjtJoint.mjJNT_HINGE:
                continue
            key = g
            if g == "f_arm":
                R = d.xmat[m.jnt_bodyid[jid]].reshape(3, 3)
                twist = abs(float(d.xaxis[jid] @ (R @ signer_map.bones[bone].dir))) > 0.9
                key = "f_arm_pron" if twist else "f_arm_flex"
            strength[dof] = STRENGTH.get(key, 0.0)
    return Naturalness(np.asarray(neutral, float).copy(), strength, comfort, effort_weight)


@dataclasses.dataclass(frozen=True)
class Below:
    """A preference (a naturalness row, never a constraint): the origin of body ``body``
    no higher than ``margin`` [m] below that of body ``ref`` (an elbow below its
    shoulder). One row, ``max(0, z - z_ref + margin) / tol``: zero while it holds, so it
    only ever pulls a raised elbow down. ``tol`` [m] is the height that costs one unit of
    naturalness."""

    body: str
    ref: str
    margin: float = 0.0
    tol: float = 0.05
    label: str = ""
    soft: ClassVar[bool] = True

    def rows(self, k: Kinematics) -> tuple[np.ndarray, np.ndarray]:
        p, jp = k.eval(BodyOrigin(self.body))
        q, jq = k.eval(BodyOrigin(self.ref))
        h = p[2] - q[2] + self.margin
        if h <= 0.0:
            return np.zeros(1), np.zeros((1, k.m.nv))
        return np.array([h / self.tol]), ((jp[2] - jq[2]) / self.tol)[None]
