"""How natural one posture of the signer looks: trunk and head from upright, elbow and hand
heights, and a RULA-style score.

Pure functions of a MuJoCo model and a posture ``qpos`` (no files, no display); the bones are
read through a :class:`~azee_mj.sites.SignerMap` (its DIR / NRM axes), so another signer with
its own map is measured the same way. Angles are radians, lengths metres. World frame = signer
frame: ``+x`` forward, ``+y`` the signer's left, ``+z`` up (the pelvis is fixed upright).

RULA (Rapid Upper Limb Assessment; McAtamney and Corlett 1993, Applied Ergonomics 24(2),
91-99) scores each arm (group A: upper arm, lower arm, wrist, wrist twist) and the
neck, trunk and legs (group B), looks both up in its tables A and B, adds muscle-use and
force scores, and combines them in table C into a grand score of 1 (acceptable) to 7
(investigate and change now). What is measured here, from the bones' axes:

- **upper arm** (1 to 6): the angle between the arm's DIR (shoulder to elbow) and the
  trunk's down axis (the ``back_2`` body), binned 0-20, 20-45, 45-90, > 90 degrees
  (scores 1, 2, 3, 4); an arm behind the trunk's frontal plane and more than 20 degrees
  from it is extension (2). +1 if the shoulder is raised (the clavicle's DIR more than
  10 degrees above the trunk's transverse plane), +1 if the arm is abducted (its DIR more
  than 20 degrees out of the trunk's sagittal plane, outward). Approximation: RULA bins
  the sagittal flexion; the elevation angle is used instead so that an arm raised to the
  side is not "neutral". The -1 for a supported arm never applies (nothing supports it).
- **lower arm** (1 to 3): elbow flexion (angle between the arm's and forearm's DIR) 60 to
  100 degrees scores 1, otherwise 2; +1 if the wrist works across the midline (the wrist,
  the hand bone's origin, past the trunk's sagittal plane toward the other side) or out to
  the side (more than ``OUT_TO_SIDE`` lateral of its shoulder joint: a threshold of ours).
- **wrist** (1 to 4): flexion / extension of the hand's DIR from the forearm's DIR in the
  forearm's DIR-NRM plane: within 5 degrees neutral (1; RULA says 0 degrees), up to 15
  degrees 2, beyond 3; +1 if deviated (radial / ulnar, out of that plane) over 10 degrees.
- **wrist twist** (1 or 2): the forearm's twist joint (the joint of the forearm body whose
  axis is along its DIR) in the middle half of its range (1) or nearer an end (2).
- **neck** (1 to 6): the head's up axis against the trunk's, in the trunk's sagittal plane:
  flexion 0-10, 10-20, > 20 degrees (1, 2, 3), extension past 5 degrees (4); +1 if twisted
  (the face's facing more than 10 degrees from the trunk's about its up axis), +1 if side
  bent (more than 10 degrees).
- **trunk** (1 to 6): the ``back_2`` up axis against world up in the sagittal plane:
  within 5 degrees upright (1), flexion up to 20 (2), 20-60 (3), > 60 (4); extension past 5
  degrees scores 2 (RULA's trunk figure shows flexion only; 2 as common practice); +1 if
  twisted over 10 degrees, +1 if side bent over 10 degrees.
- **legs**: 1 (the signer is seated or stands balanced: its pelvis is fixed).
- **muscle use, force**: 0 (one posture tells nothing of repetition or holding time; the
  hands carry no load).

The grand score of each side is table C of (table A of that arm, table B); the posture's
``rula.score`` is the larger of the two sides.
"""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np

from azee_mj.sites import DEFAULT_MAP, SIDES, SignerMap

#: The wrist counts as "out to the side" this far lateral of its shoulder joint [m].
OUT_TO_SIDE = 0.15
_DEG = np.pi / 180.0

# RULA Table A (McAtamney and Corlett 1993): rows upper arm 1-6 x lower arm 1-3, columns
# wrist 1-4 x wrist twist 1-2.
_TABLE_A = np.array(
    [
        [1, 2, 2, 2, 2, 3, 3, 3],
        [2, 2, 2, 2, 3, 3, 3, 3],
        [2, 3, 3, 3, 3, 3, 4, 4],
        [2, 3, 3, 3, 3, 4, 4, 4],
        [3, 3, 3, 3, 3, 4, 4, 4],
        [3, 4, 4, 4, 4, 4, 5, 5],
        [3, 3, 4, 4, 4, 4, 5, 5],
        [3, 4, 4, 4, 4, 4, 5, 5],
        [4, 4, 4, 4, 4, 5, 5, 5],
        [4, 4, 4, 4, 4, 5, 5, 5],
        [4, 4, 4, 4, 4, 5, 5, 5],
        [4, 4, 4, 5, 5, 5, 6, 6],
        [5, 5, 5, 5, 5, 6, 6, 7],
        [5, 6, 6, 6, 6, 7, 7, 7],
        [6, 6, 6, 7, 7, 7, 7, 8],
        [7, 7, 7, 7, 7, 8, 8, 9],
        [8, 8, 8, 8, 8, 9, 9, 9],
        [9, 9, 9, 9, 9, 9, 9, 9],
    ]
)
# RULA Table B: rows neck 1-6, columns trunk 1-6 x legs 1-2.
_TABLE_B = np.array(
    [
        [1, 3, 2, 3, 3, 4, 5, 5, 6, 6, 7, 7],
        [2, 3, 2, 3, 4, 5, 5, 5, 6, 7, 7, 7],
        [3, 3, 3, 4, 4, 5, 5, 6, 6, 7, 7, 7],
        [5, 5, 5, 6, 6, 7, 7, 7, 7, 7, 8, 8],
        [7, 7, 7, 7, 7, 8, 8, 8, 8, 8, 8, 8],
        [8, 8, 8, 8, 8, 8, 8, 9, 9, 9, 9, 9],
    ]
)
# RULA Table C: rows score A 1-8+ (with muscle and force), columns score B 1-7+.
_TABLE_C = np.array(
    [
        [1, 2, 3, 3, 4, 5, 5],
        [2, 2, 3, 4, 4, 5, 5],
        [3, 3, 3, 4, 4, 5, 6],
        [3, 3, 3, 4, 5, 6, 6],
        [4, 4, 4, 5, 6, 7, 7],
        [4, 4, 5, 6, 6, 7, 7],
        [5, 5, 6, 6, 7, 7, 7],
        [5, 5, 6, 7, 7, 7, 7],
    ]
)


def table_a(upper_arm: int, lower_arm: int, wrist: int, wrist_twist: int) -> int:
    """RULA table A: the arm and wrist posture score."""
    ua, la = min(max(upper_arm, 1), 6), min(max(lower_arm, 1), 3)
    w, t = min(max(wrist, 1), 4), min(max(wrist_twist, 1), 2)
    return int(_TABLE_A[(ua - 1) * 3 + la - 1, (w - 1) * 2 + t - 1])


def table_b(neck: int, trunk: int, legs: int = 1) -> int:
    """RULA table B: the neck, trunk and legs posture score."""
    n, tr, lg = min(max(neck, 1), 6), min(max(trunk, 1), 6), min(max(legs, 1), 2)
    return int(_TABLE_B[n - 1, (tr - 1) * 2 + lg - 1])


def table_c(score_a: int, score_b: int) -> int:
    """RULA table C: the grand score from the (muscle- and force-adjusted) A and B scores."""
    return int(_TABLE_C[min(max(score_a, 1), 8) - 1, min(max(score_b, 1), 7) - 1])


@dataclasses.dataclass(frozen=True)
class RulaArm:
    """One side's RULA group A and its grand score, with the angles scored [rad]."""

    side: str
    upper_arm: int
    lower_arm: int
    wrist: int
    wrist_twist: int
    score_a: int
    score: int
    upper_arm_elevation: float
    upper_arm_abduction: float
    shoulder_elevation: float
    elbow_flexion: float
    wrist_flexion: float
    wrist_deviation: float
    twist_fraction: float  # forearm twist from mid-range, as a fraction of half the range


@dataclasses.dataclass(frozen=True)
class Rula:
    """RULA-style scores of one posture: group B, each arm, and the worse side's grand score."""

    neck: int
    trunk: int
    legs: int
    score_b: int
    right: RulaArm
    left: RulaArm

    @property
    def score(self) -> int:
        """The grand score of the worse side (1 acceptable ... 7 change now)."""
        return max(self.right.score, self.left.score)


@dataclasses.dataclass(frozen=True)
class ArmHeights:
    """One side's heights [m]: elbow joint above its shoulder joint, palm centre above the
    eyes (mean height of the two eye bodies); negative = below."""

    side: str
    elbow_above_shoulder: float
    hand_above_eyes: float


@dataclasses.dataclass(frozen=True)
class Ergonomics:
    """Naturalness metrics of one posture (angles in radians, heights in metres).

    Attributes:
      trunk_angle: the chest's (``back_2``) up axis from world up.
      trunk_flexion, trunk_side_bend, trunk_twist: its sagittal, lateral and axial parts.
      head_angle: the head's up axis from world up.
      gaze_deviation: the face's facing (head NRM) from world forward.
      neck_flexion, neck_side_bend, neck_twist: the head relative to the chest.
      right, left: :class:`ArmHeights` per side.
      rula: :class:`Rula`.
    """

    trunk_angle: float
    trunk_flexion: float
    trunk_side_bend: float
    trunk_twist: float
    head_angle: float
    gaze_deviation: float
    neck_flexion: float
    neck_side_bend: float
    neck_twist: float
    right: ArmHeights
    left: ArmHeights
    rula: Rula

    def arm(self, side: str) -> ArmHeights:
        """The :class:`ArmHeights` of ``"R"`` or ``"L"``."""
        return {"R": self.right, "L": self.left}[side]

    def elbows_ok(self) -> bool:
        """The issue's rule: an elbow rises above its shoulder only when its hand is at or
        above the eyes."""
        return all(
            a.elbow_above_shoulder <= 0.0 or a.hand_above_eyes >= 0.0
            for a in (self.right, self.left)
        )


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.arccos(np.clip(a @ b / (np.linalg.norm(a) * np.linalg.norm(b)), -1.0, 1.0)))


class _Pose:
    """Body frames of one posture, read through the signer map."""

    def __init__(self, model: mujoco.MjModel, qpos, smap: SignerMap):
        self.m, self.smap = model, smap
        self.d = mujoco.MjData(model)
        q = np.asarray(qpos, float)
        if q.shape != (model.nq,):
            raise ValueError(f"qpos must have shape ({model.nq},), got {q.shape}")
        self.d.qpos[:] = q
        mujoco.mj_kinematics(model, self.d)

    def bid(self, bone: str) -> int:
        return mujoco.mj_name2id(self.m, mujoco.mjtObj.mjOBJ_BODY, self.smap.bones[bone].body)

    def axis(self, bone: str, which: str) -> np.ndarray:
        b = self.smap.bones[bone]
        return self.d.xmat[self.bid(bone)].reshape(3, 3) @ np.asarray(getattr(b, which), float)

    def origin(self, bone: str) -> np.ndarray:
        return self.d.xpos[self.bid(bone)].copy()

    def site(self, azee: str) -> np.ndarray:
        sid = mujoco.mj_name2id(self.m, mujoco.mjtObj.mjOBJ_SITE, self.smap.sites[azee])
        return self.d.site_xpos[sid].copy()


def _frame(up: np.ndarray, fwd: np.ndarray) -> np.ndarray:
    """Rows fwd, left, up of an orthonormal frame from an up and a (roughly) forward axis."""
    up = up / np.linalg.norm(up)
    fwd = fwd - (fwd @ up) * up
    fwd = fwd / np.linalg.norm(fwd)
    return np.array([fwd, np.cross(up, fwd), up])


def _bend(up_in: np.ndarray) -> tuple[float, float]:
    """(sagittal, lateral) angles of an up axis given in a (fwd, left, up) frame."""
    return (float(np.arctan2(up_in[0], up_in[2])), float(np.arctan2(up_in[1], up_in[2])))


def _twist_joint(p: _Pose, bone: str) -> int | None:
    """The joint of ``bone``'s body whose axis is along its DIR (the forearm's pronation)."""
    m, b = p.m, p.bid(bone)
    d = np.asarray(p.smap.bones[bone].dir, float)
    for j in range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b]):
        if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE and abs(m.jnt_axis[j] @ d) > 0.9:
            return j
    return None


def _rula_arm(p: _Pose, side: str, trunk: np.ndarray, score_b: int) -> RulaArm:
    out = -1.0 if side == "R" else 1.0  # the trunk frame's lateral row points to the left
    arm = trunk @ p.axis(f"arm_{side}", "dir")
    elev = _angle(arm, np.array([0.0, 0.0, -1.0]))
    abd = float(np.arcsin(np.clip(out * arm[1], -1.0, 1.0)))
    if arm[0] < 0.0 and elev > 20 * _DEG:
        ua = 2
    else:
        ua = 1 if elev <= 20 * _DEG else 2 if elev <= 45 * _DEG else 3 if elev <= 90 * _DEG else 4
    clav = trunk @ p.axis(f"clav_{side}", "dir")
    shoulder = float(np.arcsin(np.clip(clav[2], -1.0, 1.0)))
    ua += int(shoulder > 10 * _DEG) + int(abd > 20 * _DEG)

    elbow = _angle(p.axis(f"arm_{side}", "dir"), p.axis(f"f_arm_{side}", "dir"))
    la = 1 if 60 * _DEG <= elbow <= 100 * _DEG else 2
    centre = p.origin("back_2")
    wrist = trunk @ (p.origin(f"palm_{side}") - centre)
    shoulder_pos = trunk @ (p.origin(f"arm_{side}") - centre)
    across = out * wrist[1] < 0.0
    to_side = out * (wrist[1] - shoulder_pos[1]) > OUT_TO_SIDE
    la += int(across or to_side)

    fa, fn = p.axis(f"f_arm_{side}", "dir"), p.axis(f"f_arm_{side}", "nrm")
    fr = np.cross(fa, fn)
    h = p.axis(f"palm_{side}", "dir")
    flex = float(np.arctan2(h @ fn, h @ fa))
    dev = float(np.arcsin(np.clip(h @ fr, -1.0, 1.0)))
    w = 1 if abs(flex) <= 5 * _DEG else 2 if abs(flex) <= 15 * _DEG else 3
    w += int(abs(dev) > 10 * _DEG)

    j = _twist_joint(p, f"f_arm_{side}")
    frac = 0.0
    if j is not None and p.m.jnt_limited[j]:
        lo, hi = p.m.jnt_range[j]
        frac = float(abs(p.d.qpos[p.m.jnt_qposadr[j]] - 0.5 * (lo + hi)) / (0.5 * (hi - lo)))
    twist = 1 if frac <= 0.5 else 2

    a = table_a(ua, la, w, twist)
    return RulaArm(
        side, ua, la, w, twist, a, table_c(a, score_b), elev, abd, shoulder, elbow, flex, dev, frac
    )


def ergonomics(model: mujoco.MjModel, qpos, signer_map: SignerMap = DEFAULT_MAP) -> Ergonomics:
    """The naturalness metrics of posture ``qpos`` (nq,) of ``model`` (see the module doc)."""
    p = _Pose(model, qpos, signer_map)
    t_up, t_fwd = p.axis("back_2", "dir"), p.axis("back_2", "nrm")
    trunk = _frame(t_up, t_fwd)
    world_up = np.array([0.0, 0.0, 1.0])
    t_flex, t_lat = _bend(t_up)
    t_twist = float(np.arctan2(trunk[0][1], trunk[0][0]))
    h_up, h_fwd = p.axis("head", "dir"), p.axis("head", "nrm")
    n_flex, n_lat = _bend(trunk @ h_up)
    hf = trunk @ h_fwd
    n_twist = float(np.arctan2(hf[1], hf[0]))

    neck = 1 if n_flex <= 10 * _DEG else 2 if n_flex <= 20 * _DEG else 3
    if n_flex < -5 * _DEG:
        neck = 4
    neck += int(abs(n_twist) > 10 * _DEG) + int(abs(n_lat) > 10 * _DEG)
    if t_flex < -5 * _DEG:
        tr = 2
    else:
        tr = (
            1
            if t_flex <= 5 * _DEG
            else 2
            if t_flex <= 20 * _DEG
            else 3
            if t_flex <= 60 * _DEG
            else 4
        )
    tr += int(abs(t_twist) > 10 * _DEG) + int(abs(t_lat) > 10 * _DEG)
    legs = 1
    b = table_b(neck, tr, legs)
    rula = Rula(neck, tr, legs, b, _rula_arm(p, "R", trunk, b), _rula_arm(p, "L", trunk, b))

    eyes_z = 0.5 * (p.origin("eye_L")[2] + p.origin("eye_R")[2])
    heights = {
        s: ArmHeights(
            s,
            float(p.origin(f"f_arm_{s}")[2] - p.origin(f"arm_{s}")[2]),
            float(p.site(f"PA_{s}")[2] - eyes_z),
        )
        for s in SIDES
    }
    return Ergonomics(
        trunk_angle=_angle(t_up, world_up),
        trunk_flexion=t_flex,
        trunk_side_bend=t_lat,
        trunk_twist=t_twist,
        head_angle=_angle(h_up, world_up),
        gaze_deviation=_angle(h_fwd, np.array([1.0, 0.0, 0.0])),
        neck_flexion=n_flex,
        neck_side_bend=n_lat,
        neck_twist=n_twist,
        right=heights["R"],
        left=heights["L"],
        rula=rula,
    )
