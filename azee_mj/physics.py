"""The physics mode: MuJoCo moves the signer along the kinematic realization.

:func:`simulate` takes a kinematic :class:`~azee_mj.timeline.Rollout` (the reference) and
its score, and steps the signer with ``mj_step``: gravity on (the model's gravity
compensation removed), a time step of at most 2 ms, MuJoCo's own contacts and joint limits.
Every hinge and slide gets an actuator whose force is clamped to a human limit
(:func:`torque_limits`):

* **joint tracking**: ``tau = tau_ff + kp (q_ref - q) + kv (qd_ref - qd)``, with the
  feed-forward ``tau_ff`` the inverse dynamics (``mj_rne``: ``mj_inverse`` with the
  constraints off) of the reference's cubic-spline position, velocity and acceleration,
  and ``kp``, ``kv`` a critically damped joint of the tracking frequency on the joint's
  own inertia. The PD
  part is MuJoCo's affine actuator bias, so the ``implicitfast`` integrator treats its
  damping implicitly.
* **the score's constraints**: during each constraint block, every site a ``place`` names
  is joined by a soft ``connect`` equality, and every bone an ``orient`` names by a soft
  ``weld``, to a mocap body that carries the reference's site (or bone frame) along its
  path.

The result is a :class:`DynamicRollout`: the arrays of a kinematic rollout (so ``check``,
``render``, ``report``, ``export`` and the player read it unchanged) plus the actuator
torques, their limits, the effort and the energy, and the tracking error. A simulation
that diverges (a non-finite state or any MuJoCo warning) raises :class:`PhysicsError`
naming the time and the block. Units: seconds, metres, radians, newton-metres (newtons for
slides), joules.
"""

from __future__ import annotations

import dataclasses
import time as _time
from collections.abc import Callable

import mujoco
import numpy as np

from azee_mj import natural
from azee_mj import score as sc
from azee_mj.errors import AzeeError
from azee_mj.model import MODEL_PATH
from azee_mj.sites import DEFAULT_MAP, SignerMap
from azee_mj.timeline import Rollout, SolveStats, score_traces

__all__ = [
    "FALLBACK_LIMITS",
    "DynamicRollout",
    "PhysicsError",
    "Settings",
    "actuated_model",
    "frame_step",
    "realize",
    "simulate",
    "torque_limits",
]


class PhysicsError(AzeeError):
    """A simulation that diverged: ``time`` [s] and ``block`` (path) where it did."""

    def __init__(self, message: str, time: float = float("nan"), block: str = ""):
        super().__init__(message)
        self.time = time
        self.block = block


#: Limits of the joints the effort model gives no strength (fingers, eyes, face, and any
#: joint a later model adds, e.g. new face joints): [N m] for hinges, [N] for slides, by
#: track, else by joint type. Chosen, not measured: a finger's flexors hold a few
#: newton-metres at the knuckles, the face a fraction of that. The model's eyes carry an
#: armature of 1e-4 kg m^2 (for stable steps; about a hundred times an eyeball's inertia),
#: so their limit lets that inertia make a saccade (about 20 000 deg/s^2), not an
#: eyeball's real torque.
FALLBACK_LIMITS = {"hand": 2.0, "eyes": 0.2, "face": 1.0, "hinge": 1.0, "slide": 5.0}


#: How far past its range a simulated joint may be and still be clipped back into it
#: [rad or m]: the slack of MuJoCo's soft joint limits.
LIMIT_SLACK = 1e-3


@dataclasses.dataclass(frozen=True)
class Settings:
    """How the signer is simulated.

    Attributes:
      timestep: the simulation step [s], at most 0.002; the frame period is cut into whole
        steps no longer than it.
      frequency: the joint tracking's natural frequency [Hz] (``kp = I w^2``).
      damping_ratio: its damping ratio (``kv = 2 zeta I w``); 1 is critical.
      eq_solref: ``solref`` (time constant [s], damping ratio) of the constraint equalities.
      eq_solimp: their ``solimp``.
    """

    timestep: float = 0.002
    frequency: float = 20.0
    damping_ratio: float = 1.0
    eq_solref: tuple[float, float] = (0.008, 1.0)
    eq_solimp: tuple[float, float, float] = (0.9, 0.95, 0.001)

    def __post_init__(self):
        if not (0.0 < self.timestep <= 0.002):
            raise AzeeError(f"timestep must be in (0, 0.002] s, got {self.timestep:g}")
        if not (self.frequency > 0.0 and self.damping_ratio > 0.0):
            raise AzeeError("frequency and damping_ratio must be positive")


# ---------------------------------------------------------------------------------------
# The actuated model
# ---------------------------------------------------------------------------------------


def frame_step(fps: float, timestep: float) -> float:
    """The longest step [s] no longer than ``timestep`` that cuts a frame period
    ``1 / fps`` into whole steps."""
    return 1.0 / (fps * int(np.ceil(1.0 / (fps * timestep) - 1e-9)))


def _track_of(signer_map: SignerMap) -> dict[str, str]:
    """Joint name -> its track's group (``hand``, ``eyes``, ``face``, ...)."""
    return {j: t.split("_")[0] for t, js in signer_map.tracks.items() for j in js}


def torque_limits(model: mujoco.MjModel, signer_map: SignerMap = DEFAULT_MAP) -> np.ndarray:
    """(nv,) the largest force each dof's actuator may exert [N m or N].

    A hinge the effort model gives a strength (:data:`azee_mj.natural.STRENGTH`: the spine
    150, shoulder 60, elbow 50, clavicle 50, neck 20, pronation and wrist 10 N m, rough
    maximal isometric torques of an adult) keeps it; any other joint gets its track's
    :data:`FALLBACK_LIMITS` entry, or the hinge / slide default.
    """
    m = model
    strength = natural.from_signer_map(m, signer_map, np.zeros(m.nq)).strength
    track = _track_of(signer_map)
    out = np.zeros(m.nv)
    for j in range(m.njnt):
        dof = m.jnt_dofadr[j]
        if strength[dof] > 0.0:
            out[dof] = strength[dof]
            continue
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j)
        slide = int(m.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_SLIDE)
        default = FALLBACK_LIMITS["slide" if slide else "hinge"]
        out[dof] = default if slide else FALLBACK_LIMITS.get(track.get(name, ""), default)
    return out


@dataclasses.dataclass(frozen=True)
class Tie:
    """A soft equality: model ``site`` (a ``place``) or the frame of ``body`` (an
    ``orient``) held to a mocap body during ``windows`` [(start, end) s]."""

    kind: str  # "site" or "body"
    name: str
    windows: tuple[tuple[float, float], ...]


def ties(score: sc.Score, signer_map: SignerMap = DEFAULT_MAP) -> tuple[Tie, ...]:
    """The equalities the score's ``place`` and ``orient`` constraints ask for, one per
    site or bone, with the intervals of their blocks."""
    win: dict[tuple[str, str], list[tuple[float, float]]] = {}
    for b in score.blocks():
        if b.kind is not sc.BlockKind.CSTR:
            continue
        for c in b.constraints:
            if isinstance(c, sc.Place) and not c.site.locus:
                key = ("site", signer_map.sites.get(c.site.name, c.site.name))
            elif isinstance(c, sc.Orient):
                bone = signer_map.bones.get(c.bone.name)
                key = ("body", bone.body if bone else c.bone.name)
            else:
                continue
            win.setdefault(key, []).append((b.start, b.end))
    return tuple(Tie(k, n, tuple(sorted(set(w)))) for (k, n), w in sorted(win.items()))


def _gains(model: mujoco.MjModel, settings: Settings) -> tuple[np.ndarray, np.ndarray]:
    """(kp, kv) per dof from the joint-space inertia's diagonal at ``qpos0``."""
    d = mujoco.MjData(model)
    mujoco.mj_forward(model, d)
    full = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, d, full)
    inertia = np.diag(full).copy()
    w = 2.0 * np.pi * settings.frequency
    return inertia * w * w, 2.0 * settings.damping_ratio * inertia * w


def actuated_model(
    score_ties: tuple[Tie, ...] = (),
    settings: Settings = Settings(),
    signer_map: SignerMap = DEFAULT_MAP,
    model=MODEL_PATH,
) -> mujoco.MjModel:
    """The signer ``model`` (an MJCF path or a :class:`mujoco.MjSpec`, copied) built for
    simulation with :class:`mujoco.MjSpec`: gravity
    compensation off, one force-limited PD actuator per hinge or slide (named after its
    joint, ``ctrl`` = ``tau_ff + kp q_ref + kv qd_ref``), and a mocap body and an inactive
    equality per tie (named ``tie<i>``)."""
    spec = model.copy() if isinstance(model, mujoco.MjSpec) else mujoco.MjSpec.from_file(str(model))
    for b in spec.bodies:
        b.gravcomp = 0.0
    spec.option.timestep = settings.timestep
    base = spec.compile()
    for j in range(base.njnt):
        if int(base.jnt_type[j]) not in (
            int(mujoco.mjtJoint.mjJNT_HINGE),
            int(mujoco.mjtJoint.mjJNT_SLIDE),
        ):
            raise AzeeError(
                f"joint {mujoco.mj_id2name(base, mujoco.mjtObj.mjOBJ_JOINT, j)!r}: the physics "
                "mode drives hinges and slides only"
            )
    kp, kv = _gains(base, settings)
    limit = torque_limits(base, signer_map)
    for j in range(base.njnt):
        dof = base.jnt_dofadr[j]
        name = mujoco.mj_id2name(base, mujoco.mjtObj.mjOBJ_JOINT, j)
        a = spec.add_actuator()
        a.name, a.target = name, name
        a.trntype = mujoco.mjtTrn.mjTRN_JOINT
        a.gaintype = mujoco.mjtGain.mjGAIN_FIXED
        a.gainprm[0] = 1.0
        a.biastype = mujoco.mjtBias.mjBIAS_AFFINE
        a.biasprm[1], a.biasprm[2] = -kp[dof], -kv[dof]
        a.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
        a.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
        a.forcerange = [-limit[dof], limit[dof]]
        sensor = spec.add_sensor()
        sensor.name, sensor.type = name, mujoco.mjtSensor.mjSENS_ACTUATORFRC
        sensor.objtype, sensor.objname = mujoco.mjtObj.mjOBJ_ACTUATOR, name
    for i, tie in enumerate(score_ties):
        _add_tie(spec, i, tie, settings)
    return spec.compile()


def _add_tie(spec: mujoco.MjSpec, i: int, tie: Tie, settings: Settings) -> None:
    mocap = spec.worldbody.add_body()
    mocap.name, mocap.mocap = f"tie{i}", True
    mocap.add_site().name = f"tie{i}"
    if tie.kind == "body":  # the bone's frame, as a site at its origin
        spec.body(tie.name).add_site().name = f"tie{i}_frame"
    eq = spec.add_equality()
    eq.name = f"tie{i}"
    eq.type = mujoco.mjtEq.mjEQ_CONNECT if tie.kind == "site" else mujoco.mjtEq.mjEQ_WELD
    eq.objtype = mujoco.mjtObj.mjOBJ_SITE
    eq.name1 = tie.name if tie.kind == "site" else f"tie{i}_frame"
    eq.name2 = f"tie{i}"
    eq.active = False
    eq.solref = list(settings.eq_solref)
    eq.solimp = [*settings.eq_solimp, 0.5, 2.0]
    if tie.kind == "body":
        eq.data[10] = 1.0  # torquescale: rotation weighs as 1 m of translation
    # the mocap body has no mass: the force on it is the equality's pull on the signer
    sensor = spec.add_sensor()
    sensor.name, sensor.type = f"tie{i}", mujoco.mjtSensor.mjSENS_FORCE
    sensor.objtype, sensor.objname = mujoco.mjtObj.mjOBJ_SITE, f"tie{i}"


# ---------------------------------------------------------------------------------------
# The reference at the simulation's steps
# ---------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Reference:
    """What the actuators and mocap bodies follow at each simulation step ``i`` (time
    ``i * dt``): ``ctrl`` (N, nu), ``mocap_pos`` (N, ties, 3), ``mocap_quat`` (N, ties, 4)
    and ``active`` (N, ties) which equalities act; ``torque_ff`` (N, nu) the inverse
    dynamics of the reference alone: what the body needs to move as the kinematic frames
    do (it may exceed the limits; the actuators then saturate)."""

    dt: float
    substeps: int
    ctrl: np.ndarray
    mocap_pos: np.ndarray
    mocap_quat: np.ndarray
    active: np.ndarray
    qpos: np.ndarray
    qvel: np.ndarray
    torque_ff: np.ndarray


def reference(
    model: mujoco.MjModel, rollout: Rollout, score_ties: tuple[Tie, ...] = ()
) -> Reference:
    """The kinematic rollout as a cubic spline through its frames, sampled at the steps
    (``model.opt.timestep`` must divide the frame period), its inverse dynamics
    (:func:`feed_forward`) and the poses of the sites the ties hold.

    The velocity and acceleration are the samples' backward and central differences, not
    the spline's derivatives: these are what the semi-implicit step produces when it
    follows the samples exactly, so a body on the reference stays on it (the derivatives
    would leave a lag of about ``dt qdd / w``)."""
    m = model
    fps = float(rollout.fps)
    dt = float(m.opt.timestep)
    sub = round(1.0 / (fps * dt))
    T = len(rollout.time)
    n = (T - 1) * sub + 1
    if T > 1:
        from scipy.interpolate import CubicSpline  # imported here: importing azee_mj stays light

        spline = CubicSpline(np.arange(T) / fps, rollout.qpos, axis=0)
        ext = spline(np.arange(-1, n + 1) * dt)
    else:
        ext = np.repeat(rollout.qpos[:1], 3, axis=0)
        n = 1
    q = ext[1:-1]
    qd = (ext[1:-1] - ext[:-2]) / dt
    qdd = (ext[2:] - 2.0 * ext[1:-1] + ext[:-2]) / (dt * dt)
    sites = [
        mujoco.mj_name2id(
            m, mujoco.mjtObj.mjOBJ_SITE, t.name if t.kind == "site" else f"tie{i}_frame"
        )
        for i, t in enumerate(score_ties)
    ]
    # The inverse dynamics at the frames, linear in between: within a frame the spline's
    # acceleration is linear and the posture changes little (a tenth of the cost).
    ff, mpos, mquat = (
        _between(x, sub) for x in feed_forward(m, q[::sub], qd[::sub], qdd[::sub], sites)
    )
    mquat /= np.maximum(np.linalg.norm(mquat, axis=-1, keepdims=True), 1e-12)
    jdof = m.actuator_trnid[:, 0]
    dof = m.jnt_dofadr[jdof]
    kp, kv = -m.actuator_biasprm[:, 1], -m.actuator_biasprm[:, 2]
    # implicitfast integrates the damping (the actuators' kv, the joints' own) at the next
    # velocity: the effective inertia is M + dt (kv + b), so the feed-forward carries the
    # extra dt (kv + b) qdd_ref or the body lags the reference.
    implicit = dt * (kv + m.dof_damping[dof])
    ctrl = ff[:, dof] + kp * q[:, m.jnt_qposadr[jdof]] + kv * qd[:, dof] + implicit * qdd[:, dof]
    steps = np.arange(n) * dt
    active = np.zeros((n, len(score_ties)), bool)
    for k, t in enumerate(score_ties):
        for a, b in t.windows:
            active[(steps >= a - 1e-9) & (steps < b - 1e-9), k] = True
    return Reference(dt, sub, ctrl, mpos, mquat, active, q, qd, ff[:, dof])


# ---------------------------------------------------------------------------------------
# Stepping
# ---------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Trajectory:
    """What the simulation did, per frame: ``qpos`` (T, nq), ``torque`` (T, nu) the
    actuator forces at the frame, ``torque_peak`` (T, nu) the largest magnitude over the
    steps that end at the frame, ``energy`` (T,) the actuators' absolute work so far [J],
    ``tie_force`` (T,) the largest force an equality exerted over those steps [N]."""

    qpos: np.ndarray
    torque: np.ndarray
    torque_peak: np.ndarray
    energy: np.ndarray
    tie_force: np.ndarray


def block_at(score: sc.Score, t: float) -> str:
    """The path of the innermost block of ``score`` running at time ``t`` [s]."""
    inside = [b for b in score.blocks() if b.start - 1e-9 <= t < b.end]
    if not inside:
        return score.root.path
    # the deepest, and of equally deep blocks the shortest (a key posture, not the
    # permanent hand shape around it)
    return max(inside, key=lambda b: (b.path.count("."), b.start - b.end)).path


def _between(x: np.ndarray, sub: int) -> np.ndarray:
    """Frame samples ``x`` (T, ...) linearly interpolated to ``sub`` steps per frame
    ((T - 1) * sub + 1, ...)."""
    if len(x) == 1:
        return x.copy()
    w = (np.arange(sub) / sub).reshape(-1, *([1] * (x.ndim - 1)))
    inner = x[:-1, None] * (1.0 - w) + x[1:, None] * w
    return np.concatenate([inner.reshape((len(x) - 1) * sub, *x.shape[1:]), x[-1:]])


def feed_forward(
    m: mujoco.MjModel, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, sites=()
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The generalized forces (N, nv) that give postures ``q`` (N, nq), velocities ``qd``
    and accelerations ``qdd`` (N, nv) with no contact or other constraint, and the
    positions (N, S, 3) and quaternions (N, S, 4) of model ``sites`` (S ids) on the way.

    The forces are ``M qdd + c(q, qd)`` (``mj_rne``, gravity included) plus the armature's
    inertia and the joints' damping and stiffness: what ``mj_inverse`` gives with the
    constraints disabled (tested), without its collision detection and factorization."""
    d = mujoco.MjData(m)
    n, sites = len(q), list(sites)
    out = np.empty((n, m.nv))
    pos, quat = np.empty((n, len(sites), 3)), np.zeros((n, len(sites), 4))
    qa, jd = m.jnt_qposadr, m.jnt_dofadr
    spring = np.zeros(m.nv)
    for i in range(n):
        d.qpos[:], d.qvel[:], d.qacc[:] = q[i], qd[i], qdd[i]
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        mujoco.mj_comVel(m, d)
        mujoco.mj_rne(m, d, 1, out[i])
        spring[jd] = m.jnt_stiffness * (q[i, qa] - m.qpos_spring[qa])
        out[i] += m.dof_armature * qdd[i] + m.dof_damping * qd[i] + spring
        if sites:
            pos[i] = d.site_xpos[sites]
            for k, s in enumerate(sites):
                mujoco.mju_mat2Quat(quat[i, k], d.site_xmat[s])
    return out, pos, quat


def _warning(d: mujoco.MjData, before: list[int]) -> str:
    """The name of the first MuJoCo warning counted since ``before``, or ""."""
    for name, w in mujoco.mjtWarning.__members__.items():
        i = int(w)
        if i < len(before) and d.warning[i].number > before[i]:
            return "MuJoCo warning " + name
    return ""


#: What the reference sets at each step, in MuJoCo's state order.
CONTROL = (
    mujoco.mjtState.mjSTATE_CTRL,
    mujoco.mjtState.mjSTATE_EQ_ACTIVE,
    mujoco.mjtState.mjSTATE_MOCAP_POS,
    mujoco.mjtState.mjSTATE_MOCAP_QUAT,
)


def _controls(ref: Reference) -> np.ndarray:
    """(N, ncontrol) the reference as ``mujoco.rollout`` controls (:data:`CONTROL`)."""
    n = len(ref.ctrl)
    return np.ascontiguousarray(
        np.hstack(
            [
                ref.ctrl,
                ref.active.astype(float),
                ref.mocap_pos.reshape(n, -1),
                ref.mocap_quat.reshape(n, -1),
            ]
        )
    )


def step(
    model: mujoco.MjModel,
    ref: Reference,
    frames: int,
    score: sc.Score,
    progress: Callable[[float], None] | None = None,
) -> Trajectory:
    """Step ``model`` from the reference's first state through ``frames`` frames, a frame's
    steps at a time (``mujoco.rollout``, in C); raise :class:`PhysicsError` at the first
    frame whose state is not finite or that raised a MuJoCo warning."""
    from mujoco import rollout as mjrollout

    m, sub = model, ref.substeps
    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:] = ref.qpos[0], ref.qvel[0]
    d.ctrl[:] = ref.ctrl[0]
    mujoco.mj_forward(m, d)
    full = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)
    spec = sum(int(c) for c in CONTROL)
    state = np.empty(mujoco.mj_stateSize(m, full))
    mujoco.mj_getState(m, d, state, full)
    controls = _controls(ref)
    dofs = m.jnt_dofadr[m.actuator_trnid[:, 0]]
    vel = 1 + m.nq + dofs  # qvel of the actuated dofs in a state (time, qpos, qvel, ...)
    q = np.empty((frames, m.nq))
    tau = np.empty((frames, m.nu))
    peak = np.empty((frames, m.nu))
    energy, pull = np.zeros(frames), np.zeros(frames)
    q[0], tau[0], peak[0] = d.qpos, d.actuator_force, np.abs(d.actuator_force)
    acts = _sensor_columns(
        m, [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, a) for a in range(m.nu)]
    )
    n_ties = sum(1 for b in range(m.nbody) if m.body_mocapid[b] >= 0)
    ties = _sensor_columns(m, [f"tie{i}" for i in range(n_ties)]).reshape(n_ties, 3)
    out_state = np.empty((1, sub, state.size))
    out_sens = np.empty((1, sub, m.nsensordata))
    runner = mjrollout.Rollout(nthread=0)
    try:
        for f in range(1, frames):
            before = [w.number for w in d.warning]
            runner.rollout(
                [m],
                [d],
                state[None],
                np.ascontiguousarray(controls[None, (f - 1) * sub : f * sub]),
                control_spec=spec,
                nstep=sub,
                state=out_state,
                sensordata=out_sens,
                skip_checks=True,
            )
            force = out_sens[0][:, acts]
            state = out_state[0, -1].copy()
            bad = _warning(d, before) or ("" if np.isfinite(state).all() else "non-finite state")
            if bad:
                t = f * sub * ref.dt
                where = block_at(score, t)
                raise PhysicsError(
                    f"the simulation diverged by t = {t:.3f} s in block {where} ({bad}); "
                    "nothing was written",
                    t,
                    where,
                )
            q[f] = state[1 : 1 + m.nq]
            tau[f], peak[f] = force[-1], np.abs(force).max(axis=0)
            power = np.abs(force * out_state[0][:, vel]).sum()
            energy[f] = energy[f - 1] + power * ref.dt
            if n_ties:
                pull[f] = np.linalg.norm(out_sens[0][:, ties], axis=-1).max()
            if progress and f % 50 == 0:
                progress(f / frames)
    finally:
        runner.close()
    return Trajectory(q, tau, peak, energy, pull)


def _sensor_columns(m: mujoco.MjModel, names: list[str]) -> np.ndarray:
    """The ``sensordata`` columns of the sensors ``names``, in order."""
    cols = []
    for n in names:
        k = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SENSOR, n)
        cols.extend(range(m.sensor_adr[k], m.sensor_adr[k] + m.sensor_dim[k]))
    return np.array(cols, int)


# ---------------------------------------------------------------------------------------
# The dynamic rollout
# ---------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class BlockDynamics:
    """One block's dynamics: the worst tracking error of a site [m] and of a joint [rad]
    against the kinematic reference, the peak torque as a fraction of its limit and its
    joint, the actuators' work [J] over the block, and the largest force an equality
    exerted [N]."""

    block: str
    start: float
    end: float
    tracking_site: float
    tracking_joint: float
    peak_ratio: float
    peak_joint: str
    energy: float
    tie_force: float


@dataclasses.dataclass(frozen=True)
class DynamicRollout(Rollout):
    """A :class:`~azee_mj.timeline.Rollout` the simulator moved, with its dynamics.

    Attributes (besides a rollout's):
      joints: (nu,) the actuated joints, in actuator order.
      torque: (T, nu) actuator forces at each frame [N m or N].
      torque_peak: (T, nu) the largest magnitude over the steps ending at each frame.
      torque_limit: (nu,) each actuator's limit.
      effort: (T,) ``sum (torque / limit)^2`` at each frame.
      energy: (T,) the actuators' absolute work since the start [J].
      tracking_site: (T,) the largest distance of a site from the reference's [m].
      tracking_joint: (T,) the largest joint deviation from the reference [rad or m].
      tie_force: (T,) the largest force a ``place`` / ``orient`` equality exerted on the
        body over the steps ending at each frame [N]: help from outside the muscles.
      timestep: the simulation step [s].
    """

    joints: tuple[str, ...] = ()
    torque: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 0)))
    torque_peak: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 0)))
    torque_limit: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    effort: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    energy: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    tracking_site: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    tracking_joint: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    tie_force: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    timestep: float = 0.002
    #: Wall time the simulation took [s] (not stored in files).
    sim_seconds: float = 0.0
    #: The largest slack of a joint past its range clipped from ``qpos`` (at most
    #: :data:`LIMIT_SLACK`; MuJoCo's limits are soft) [rad or m]; not stored in files.
    clipped: float = 0.0

    def summary(self) -> str:
        """One line: the peak torque against its limit, the energy, the worst tracking
        error and the simulation's speed."""
        ratio = self.torque_peak / self.torque_limit
        j = int(np.unravel_index(np.argmax(ratio), ratio.shape)[1]) if ratio.size else 0
        speed = float(self.time[-1]) / self.sim_seconds if self.sim_seconds > 0 else 0.0
        return (
            f"physics: peak torque {100 * ratio.max():.0f}% of its limit ({self.joints[j]}), "
            f"energy {self.energy[-1]:.1f} J, tracking within "
            f"{1000 * self.tracking_site.max():.1f} mm of the kinematic sites, equalities "
            f"pulling at most {self.tie_force.max():.1f} N; "
            f"simulated at {speed:.1f}x real time (step {1000 * self.timestep:g} ms)"
        )

    def blocks(self) -> list[BlockDynamics]:
        """Per block of the schedule (in order of start), its :class:`BlockDynamics`."""
        spans: dict[str, tuple[float, float]] = {}
        for ivs in self.schedule.values():
            for iv in ivs:
                a, b = spans.get(iv.block, (iv.start, iv.end))
                spans[iv.block] = (min(a, iv.start), max(b, iv.end))
        T = len(self.time)
        out = []
        for block, (a, b) in sorted(spans.items(), key=lambda kv: (kv[1][0], kv[0])):
            f0 = min(T - 1, max(0, int(np.ceil(a * self.fps - 1e-9))))
            f1 = min(T, max(f0 + 1, int(np.ceil(b * self.fps - 1e-9))))
            ratio = self.torque_peak[f0:f1] / self.torque_limit
            j = int(np.unravel_index(np.argmax(ratio), ratio.shape)[1])
            out.append(
                BlockDynamics(
                    block,
                    a,
                    b,
                    float(self.tracking_site[f0:f1].max()),
                    float(self.tracking_joint[f0:f1].max()),
                    float(ratio.max()),
                    self.joints[j],
                    float(self.energy[f1 - 1] - self.energy[f0]),
                    float(self.tie_force[f0:f1].max()),
                )
            )
        return out

    def report(self) -> dict:
        """The kinematic report plus ``dynamics``: the peak torque ratio, the energy and,
        per block, tracking error, peak torque against its limit and energy."""
        out = super().report()
        ratio = self.torque_peak / self.torque_limit
        out["dynamics"] = {
            "timestep_s": self.timestep,
            "peak_torque_ratio": float(ratio.max()) if ratio.size else 0.0,
            "energy_j": float(self.energy[-1]) if self.energy.size else 0.0,
            "tie_force_n": float(self.tie_force.max()) if self.tie_force.size else 0.0,
            "blocks": [
                {
                    "block": b.block,
                    "start": b.start,
                    "end": b.end,
                    "tracking_site_mm": b.tracking_site * 1000.0,
                    "tracking_joint_deg": float(np.degrees(b.tracking_joint)),
                    "peak_torque_ratio": b.peak_ratio,
                    "peak_torque_joint": b.peak_joint,
                    "energy_j": b.energy,
                    "tie_force_n": b.tie_force,
                }
                for b in self.blocks()
            ],
        }
        return out


def simulate(
    rollout: Rollout,
    score: sc.Score | str,
    *,
    settings: Settings = Settings(),
    signer_map: SignerMap | None = None,
    solver=None,
    model=MODEL_PATH,
    progress: Callable[[float], None] | None = None,
) -> DynamicRollout:
    """Simulate the signer along the kinematic ``rollout`` of ``score``.

    Args:
      rollout: the kinematic realization (:func:`azee_mj.timeline.realize`), the reference.
      score: its score (a :class:`~azee_mj.score.Score` or a path).
      settings: time step, tracking gains and equality softness (:class:`Settings`).
      signer_map: the AZee names of the signer (default: the bundled signer's).
      solver: an :class:`~azee_mj.ik.Solver` on the same signer, to compute the residual
        traces with (default: one for the bundled signer).
      model: the signer's MJCF path or :class:`mujoco.MjSpec` (default the bundled one).
      progress: called with the fraction done (0..1).

    Returns:
      A :class:`DynamicRollout` at the reference's frames.

    Raises:
      PhysicsError: the simulation diverged (the time and the block in the message).
    """
    t0 = _time.perf_counter()
    if not isinstance(score, sc.Score):
        score = sc.load_score(score)
    # the score's blocks on the rollout's clock (its lead-in from rest comes first)
    score = score.shifted(rollout.score_start) if rollout.score_start else score
    smap = signer_map or DEFAULT_MAP
    score_ties = ties(score, smap)
    settings = dataclasses.replace(settings, timestep=frame_step(rollout.fps, settings.timestep))
    if solver is None:
        from azee_mj.schedule import make_solver

        solver = make_solver(model, signer_map=smap)
    m = actuated_model(score_ties, settings, smap, model)
    ref = reference(m, rollout, score_ties)
    traj = step(m, ref, len(rollout.time), score, progress)
    return _dynamic(rollout, score, m, ref, traj, solver, smap, _time.perf_counter() - t0)


def realize(
    score: sc.Score | str,
    *,
    fps: float = 50.0,
    settings: Settings = Settings(),
    solver=None,
    signer_map: SignerMap | None = None,
    model=MODEL_PATH,
    progress: Callable[[float], None] | None = None,
    **motion,
) -> DynamicRollout:
    """Realize ``score`` kinematically (:func:`azee_mj.timeline.realize`) and simulate the
    signer along it (:func:`simulate`): the physics mode's rollout, frame ``k`` at
    ``k / fps`` [s]. ``model``: the signer's MJCF path or spec; ``solver`` (default one
    for ``model`` and ``signer_map``) must be on the same signer; ``motion``: the kinematic
    realization's ``rest``, ``hold`` and ``tempo`` (the score is simulated at that tempo)."""
    from azee_mj import timeline
    from azee_mj.schedule import make_solver

    if not isinstance(score, sc.Score):
        score = sc.load_score(score)
    smap = signer_map or DEFAULT_MAP
    solver = solver or make_solver(model, signer_map=smap)
    tick = progress or (lambda f: None)
    kin = timeline.realize(
        score, fps=fps, solver=solver, signer_map=smap, progress=lambda f: tick(0.5 * f), **motion
    )
    tempo = motion.get("tempo", 1.0)
    if tempo != 1.0:  # the blocks at the times the kinematic rollout played them
        score = score.at_tempo(tempo)
    return simulate(
        kin,
        score,
        settings=settings,
        signer_map=smap,
        solver=solver,
        model=model,
        progress=lambda f: tick(0.5 + 0.5 * f),
    )


def trill_windows(score: sc.Score) -> list[tuple[float, float]]:
    """The intervals [s] of the blocks with a trill."""
    return [
        (b.start, b.end)
        for b in score.blocks()
        if any(isinstance(c, sc.Trill) for c in b.constraints)
    ]


def _trill_notes(score: sc.Score, traces):
    """``traces`` with a reason on those a trill overlaps: a kinematic trace is measured
    before the trill is added, a simulated one includes the trill's motion."""
    wins = trill_windows(score)
    out = []
    for t in traces:
        over = [(a, b) for a, b in wins if a < t.end and b > t.start]
        if over and not t.reason:
            a, b = over[0]
            note = f"a trill moves the body from {a:g} to {b:g} s; the residual includes it"
            t = dataclasses.replace(t, reason=note)
        out.append(t)
    return tuple(out)


def _findings(rollout, score, solver, smap, q, site_pos, traces) -> tuple:
    """The findings of the simulated motion ``q`` (not those of the kinematic ``rollout``
    it follows): speeds over the human range and constraints left, as
    :func:`azee_mj.timeline.findings_of` finds them on a kinematic rollout."""
    from azee_mj.findings import constraint_findings, speed_findings

    joints = {
        j: (track, solver.model.jnt_qposadr[solver.joint_id(j)])
        for track, names in smap.tracks.items()
        for j in names
    }
    t0 = rollout.score_start
    found = speed_findings(
        rollout.time,
        q,
        site_pos,
        list(rollout.site_names),
        joints,
        rollout.schedule,
        t0,
        t0 + score.duration,
    )
    return tuple(found + constraint_findings(list(traces), rollout.time))


def _dynamic(rollout, score, m, ref, traj, solver, smap, seconds) -> DynamicRollout:
    base = solver.model
    # MuJoCo's joint limits are soft: a joint held at its limit sits up to ~1e-4 rad past
    # it. Such slack is clipped from the stored postures (``clipped`` says how much); a
    # joint forced further past its limit is left as it is, for ``check`` to report.
    lim = base.jnt_limited.astype(bool)
    qa = base.jnt_qposadr[lim]
    q = traj.qpos.copy()
    inside = np.clip(q[:, qa], base.jnt_range[lim, 0], base.jnt_range[lim, 1])
    slack = np.abs(inside - q[:, qa]) <= LIMIT_SLACK
    q[:, qa] = np.where(slack, inside, q[:, qa])
    clipped = float(np.abs(q - traj.qpos).max()) if q.size else 0.0
    traj = dataclasses.replace(traj, qpos=q)
    d = mujoco.MjData(base)
    sids = [mujoco.mj_name2id(base, mujoco.mjtObj.mjOBJ_SITE, s) for s in rollout.site_names]
    site_pos = np.empty_like(rollout.site_pos)
    for f, q in enumerate(traj.qpos):
        d.qpos[:] = q
        mujoco.mj_kinematics(base, d)
        site_pos[f] = d.site_xpos[sids]
    limit = m.actuator_forcerange[:, 1].copy()
    joints = tuple(
        mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) for j in m.actuator_trnid[:, 0]
    )
    traces = _trill_notes(score, score_traces(score, traj.qpos, rollout.fps, solver))
    s = rollout.stats
    stats = SolveStats(
        s.problems,
        s.key_problems,
        s.iterations,
        s.not_converged,
        s.solve_time,
        s.total_time + seconds,
        s.per_problem_iterations,
    )
    return DynamicRollout(
        rollout.fps,
        rollout.mode,
        rollout.time,
        traj.qpos,
        rollout.site_names,
        site_pos,
        rollout.schedule,
        traces,
        stats,
        joints=joints,
        torque=traj.torque,
        torque_peak=traj.torque_peak,
        torque_limit=limit,
        effort=((traj.torque / limit) ** 2).sum(axis=1),
        energy=traj.energy,
        tracking_site=np.linalg.norm(site_pos - rollout.site_pos, axis=2).max(axis=1),
        tracking_joint=np.abs(traj.qpos - rollout.qpos).max(axis=1),
        tie_force=traj.tie_force,
        timestep=ref.dt,
        score_start=rollout.score_start,
        findings=_findings(rollout, score, solver, smap, traj.qpos, site_pos, traces),
        sim_seconds=seconds,
        clipped=clipped,
    )
