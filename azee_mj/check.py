"""Pose checking: penetrating geom pairs, joint-range violations and constraint residuals.

Works on one posture or on every frame of a rollout. Thresholds: a penetration deeper than
``penetration_limit`` [m] or a joint beyond its range by more than ``range_tol`` [rad or m]
is a finding.
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Mapping

import mujoco
import numpy as np

from azee_mj.constraints import PENETRATION_LIMIT
from azee_mj.frames import nonfinite_frames


@dataclasses.dataclass(frozen=True)
class Penetration:
    """Two geoms interpenetrating by ``depth`` [m] at frame ``frame``."""

    frame: int
    geom1: str
    geom2: str
    depth: float


@dataclasses.dataclass(frozen=True)
class RangeViolation:
    """Joint ``joint`` outside its range by ``excess`` [rad or m] at frame ``frame``."""

    frame: int
    joint: str
    value: float
    excess: float


@dataclasses.dataclass(frozen=True)
class PoseReport:
    """Findings over ``frames`` postures; ``clean`` when there are none.

    ``max_depth`` (frames,) is the deepest penetration of each frame [m], counting every pair
    (also those under the limit).
    """

    frames: int
    penetrations: tuple[Penetration, ...]
    range_violations: tuple[RangeViolation, ...]
    max_depth: np.ndarray
    #: frames whose posture holds NaN or infinity (not checked further)
    nonfinite: tuple[int, ...] = ()
    #: frames whose stored site positions hold NaN or infinity (a rollout's ``site_pos``)
    nonfinite_sites: tuple[int, ...] = ()

    @property
    def clean(self) -> bool:
        return not (
            self.penetrations or self.range_violations or self.nonfinite or self.nonfinite_sites
        )


def _name(m: mujoco.MjModel, gid: int) -> str:
    name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, gid)
    if name:
        return name
    body = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, int(m.geom_bodyid[gid]))
    return f"{body}/geom{gid}"


def without_margins(model: mujoco.MjModel) -> mujoco.MjModel:
    """``model``, or a copy of it with every geom margin zero: MuJoCo's narrow phase gives
    slightly different depths (up to about 1 mm) for pairs it finds within a margin (the
    IK solver's model has one for its distance rows), so a penetration verdict taken on a
    model with margins would disagree with the same verdict on the signer's own model."""
    if not np.any(model.geom_margin):
        return model
    bare = copy.deepcopy(model)
    bare.geom_margin[:] = 0.0
    return bare


def check_poses(
    model: mujoco.MjModel,
    qpos: np.ndarray,
    *,
    penetration_limit: float = PENETRATION_LIMIT,
    range_tol: float = 1e-6,
    allowed: frozenset[tuple[str, str]] | Mapping[int, frozenset] = frozenset(),
) -> PoseReport:
    """Check postures ``qpos`` (nq,) or (T, nq) of ``model``.

    ``allowed`` holds body-name pairs (either order) whose contact is wanted (a contact
    constraint brings them together), or a mapping frame -> such pairs (e.g.
    :func:`~azee_mj.schedule.contact_pairs`); their penetration is
    not a finding.
    """
    q = np.atleast_2d(np.asarray(qpos, float))
    if q.shape[1] != model.nq:
        raise ValueError(f"qpos has {q.shape[1]} columns; the model has nq={model.nq}")
    model = without_margins(model)
    d = mujoco.MjData(model)
    lo = np.where(model.jnt_limited, model.jnt_range[:, 0], -np.inf)
    hi = np.where(model.jnt_limited, model.jnt_range[:, 1], np.inf)
    adr = model.jnt_qposadr
    body = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) for b in range(model.nbody)]
    pens: list[Penetration] = []
    viol: list[RangeViolation] = []
    max_depth = np.zeros(len(q))
    finite = np.ones(len(q), bool)
    for a in range(0, len(q), 4096):  # a block at a time: no (T, nq) mask
        finite[a : a + 4096] = np.isfinite(q[a : a + 4096]).all(axis=1)
    for f, qf in enumerate(q):
        if not finite[f]:
            continue
        vals = qf[adr]
        excess = np.maximum(lo - vals, vals - hi)
        for j in np.flatnonzero(excess > range_tol):
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, int(j))
            viol.append(RangeViolation(f, name, float(vals[j]), float(excess[j])))
        d.qpos[:] = qf
        mujoco.mj_kinematics(model, d)
        mujoco.mj_collision(model, d)
        ok = allowed.get(f, frozenset()) if isinstance(allowed, Mapping) else allowed
        for i in range(d.ncon):
            c = d.contact[i]
            depth = -float(c.dist)
            if depth <= 0:
                continue
            max_depth[f] = max(max_depth[f], depth)
            b1, b2 = body[model.geom_bodyid[c.geom1]], body[model.geom_bodyid[c.geom2]]
            if depth > penetration_limit and (b1, b2) not in ok and (b2, b1) not in ok:
                pens.append(Penetration(f, _name(model, c.geom1), _name(model, c.geom2), depth))
    return PoseReport(
        len(q), tuple(pens), tuple(viol), max_depth, tuple(int(f) for f in np.flatnonzero(~finite))
    )


def check_rollout(
    model: mujoco.MjModel,
    qpos: np.ndarray,
    site_pos: np.ndarray,
    *,
    allowed: frozenset[tuple[str, str]] | Mapping[int, frozenset] = frozenset(),
) -> PoseReport:
    """:func:`check_poses` of a rollout's postures, with the frames whose stored site
    positions ``site_pos`` (T, S, 3) [m] are not finite as findings too (every export
    refuses such a file, so ``check`` cannot call it clean)."""
    report = check_poses(model, qpos, allowed=allowed)
    bad = nonfinite_frames(site_pos)
    return dataclasses.replace(report, nonfinite_sites=tuple(int(f) for f in bad))


def rollout_verdict(model: mujoco.MjModel, rollout, score=None, solver=None) -> PoseReport:
    """The one verdict on a rollout's postures that ``realize`` and ``check`` both say:
    :func:`check_rollout` with the contacts ``score`` asks for allowed (none without it)."""
    allowed: frozenset | Mapping = frozenset()
    if score is not None:
        from azee_mj.schedule import contact_pairs

        allowed = contact_pairs(score, rollout.time, solver, rollout.score_start)
    return check_rollout(model, rollout.qpos, rollout.site_pos, allowed=allowed)


def summary(report: PoseReport, fps: float | None = None) -> str:
    """A readable multi-line summary of ``report``: the frames checked, the deepest
    contact, then :func:`verdict_lines`."""
    worst = float(report.max_depth.max(initial=0.0))
    lines = [f"{report.frames} frame(s) checked", f"deepest contact: {worst * 1000:.2f} mm"]
    return "\n".join([*lines, *verdict_lines(report, fps)])


def verdict_lines(report: PoseReport, fps: float | None = None) -> tuple[str, ...]:
    """The findings of ``report`` (non-finite frames, the deepest penetrations and range
    violations), or the one line saying it is clean."""
    lines = []
    when = (lambda f: f"t={f / fps:.3f}s") if fps else (lambda f: f"frame {f}")
    if report.nonfinite:
        lines.append(
            f"{len(report.nonfinite)} frame(s) with a non-finite posture (NaN or "
            f"infinity), first at {when(report.nonfinite[0])}"
        )
    if report.nonfinite_sites:
        lines.append(
            f"{len(report.nonfinite_sites)} frame(s) with a non-finite site position (NaN or "
            f"infinity), first at {when(report.nonfinite_sites[0])}"
        )
    if report.penetrations:
        lines.append(f"{len(report.penetrations)} penetration(s) over the limit, e.g.:")
        for p in sorted(report.penetrations, key=lambda p: -p.depth)[:5]:
            lines.append(f"  {when(p.frame)}: {p.geom1} / {p.geom2} {p.depth * 1000:.2f} mm")
    if report.range_violations:
        lines.append(f"{len(report.range_violations)} joint-range violation(s), e.g.:")
        for v in sorted(report.range_violations, key=lambda v: -v.excess)[:5]:
            lines.append(f"  {when(v.frame)}: {v.joint} = {v.value:.4f}, out by {v.excess:.4f}")
    if report.clean:
        lines.append("clean: no penetration over the limit, every joint inside its range")
    return tuple(lines)
