"""Analytic two-bone arm postures: a start in the natural basin for the posture solver.

A numerical solver started from the wrong posture converges to the wrong branch (the elbow
up instead of down, the arm rotated the other way). For a hand target the arm's posture is
known in closed form up to one angle, the elbow's *swivel* about the shoulder-wrist line
(Tolani, Goswami and Badler 2000): the elbow angle from the law of cosines, the swivel chosen
as people choose it, the elbow hanging below the shoulder-wrist line and turned a little out
(Soechting and Flanders 1989). :func:`arm_seed` computes that posture for the bundled
signer's arm joints (shoulder flexion about -y, abduction about -x, rotation about the arm,
elbow flexion about -y, mirrored on the left); the solver then refines it.

Units: metres, radians.

:func:`arm_seeds` turns a problem's placements into such starts for the solver.
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Iterable

import mujoco
import numpy as np

from azee_mj import constraints as cn
from azee_mj import ik, surface
from azee_mj.kinematics import BodyAxis, SitePos

#: The hand comes to its target from this far in front of the shoulder [m].
APPROACH = 0.3
#: How far each of two hands meeting in the signing space starts from its centre [m].
MEET_GAP = 0.05
#: The elbow's swivel out of the vertical plane through the shoulder-wrist line [rad].
SWIVEL_OUT = np.deg2rad(25.0)
#: Forearm pronation of two hands that start stacked, palms down [rad].
STACKED_PRONATION = 1.0


@dataclasses.dataclass(frozen=True)
class Arm:
    """One arm of the signer: its shoulder, elbow and wrist bodies and the four joints the
    two-bone solution sets (shoulder flexion, abduction, rotation; elbow flexion), and the
    sign of the outward (lateral) world y direction (-1 right arm, +1 left arm)."""

    upper: str
    fore: str
    hand: str
    flex: str
    abd: str
    rot: str
    elbow: str
    out: float
    #: The joints below the elbow that turn the hand (forearm rotation, wrist).
    wrist: tuple[str, ...] = ()

    @property
    def pron(self) -> str:
        """The forearm rotation joint (the first of :attr:`wrist`), or ""."""
        return self.wrist[0] if self.wrist else ""


def arms_of(signer_map, sides=("R", "L")) -> tuple[Arm, ...]:
    """The arms of a signer mapped like the bundled one: the bones ``arm_X``, ``f_arm_X``,
    ``palm_X`` and the track ``arm_X`` (clavicle elevation and protraction, then shoulder
    flexion, abduction and rotation, then elbow flexion...)."""
    out = []
    for s in sides:
        track = signer_map.tracks.get(f"arm_{s}", ())
        bones = [signer_map.bones.get(f"{b}_{s}") for b in ("arm", "f_arm", "palm")]
        if len(track) < 6 or None in bones:
            continue
        flex, abd, rot, elbow = track[2:6]
        out.append(
            Arm(
                bones[0].body,
                bones[1].body,
                bones[2].body,
                flex,
                abd,
                rot,
                elbow,
                -1.0 if s == "R" else 1.0,
                tuple(track[6:]),
            )
        )
    return tuple(out)


def arm_seed(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    arm: Arm,
    hand_point: np.ndarray,
    target: np.ndarray,
    facing: tuple[np.ndarray, float] | None = None,
    swivel: float | None = None,
    lying: np.ndarray | None = None,
    rising: bool = False,
) -> dict[str, float] | None:
    """Joint values [rad] that bring ``hand_point`` (a world point on the hand, on the
    posture in ``data`` after ``mj_kinematics``) to ``target`` [m], with a natural swivel
    (``swivel`` [rad] from the elbow hanging down, outward positive; None: ``SWIVEL_OUT``).

    The wrist goes short of ``target`` by the hand point's distance from the wrist, on the
    line from a point ``APPROACH`` in front of the shoulder (a straight wrist). With
    ``facing`` (the target surface's outward unit normal, world, and a tolerance [rad]) the
    hand point is a fingertip that must meet the surface nearly head-on: the hand comes in
    along the normal, turned toward that frontal approach as far as the tolerance allows.
    With ``lying`` (the surface's outward unit normal, world) the hand point is a pad: the
    hand comes in along the surface (the frontal approach less its normal part).
    Returns None when the joint frames are not the ones this solution assumes (another
    signer).
    """
    m, d = model, data
    bid = {
        n: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, n)
        for n in (arm.upper, arm.fore, arm.hand)
    }
    jid = {
        n: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n)
        for n in (arm.flex, arm.abd, arm.rot, arm.elbow)
    }
    if min(bid.values()) < 0 or min(jid.values()) < 0:
        return None
    s = d.xpos[bid[arm.upper]].copy()
    e0 = d.xpos[bid[arm.fore]]
    w0 = d.xpos[bid[arm.hand]]
    l1 = float(np.linalg.norm(e0 - s))
    l2 = float(np.linalg.norm(w0 - e0))
    # The hand continues the forearm (a straight wrist) toward the target, coming from in
    # front of the shoulder (so it reaches the face or the chest from the front).
    Rp = d.xmat[m.body_parentid[bid[arm.upper]]].reshape(3, 3)
    target = np.asarray(target, float)
    source = s + APPROACH * Rp[:, 0]
    reach_dir = (target - source) / max(float(np.linalg.norm(target - source)), 1e-9)
    if rising:
        reach_dir = np.array([0.0, 0.0, 1.0])
    elif facing is not None:
        reach_dir = -_turn_toward(np.asarray(facing[0], float), -reach_dir, facing[1])
    elif lying is not None:
        reach_dir = _along(reach_dir, lying)
    w = target - float(np.linalg.norm(np.asarray(hand_point, float) - w0)) * reach_dir
    # The arm's rest frame: the parent (clavicle) frame of the shoulder joints.
    x = Rp.T @ (w - s)
    L = float(np.linalg.norm(x))
    L = min(max(L, abs(l1 - l2) + 1e-6), l1 + l2 - 1e-6)
    n = x / max(np.linalg.norm(x), 1e-9)
    cos_e = (L * L - l1 * l1 - l2 * l2) / (2.0 * l1 * l2)
    e = float(np.arccos(np.clip(cos_e, -1.0, 1.0)))
    a1 = (l1 * l1 + L * L - l2 * l2) / (2.0 * L)
    rho = np.sqrt(max(l1 * l1 - a1 * a1, 0.0))
    down = np.array([0.0, 0.0, -1.0]) + n[2] * n
    if np.linalg.norm(down) < 1e-6:
        down = np.array([1.0, 0.0, 0.0]) - n[0] * n
    down /= np.linalg.norm(down)
    side = np.cross(n, down)
    if side[1] * arm.out < 0:
        side = -side
    sw = (0.0 if rising else SWIVEL_OUT) if swivel is None else swivel
    elbow = n * a1 + rho * (np.cos(sw) * down + np.sin(sw) * side)
    u = elbow / l1
    # u = (cos a sin f, -sin a, -cos a cos f) in the rest frame; mirrored on the left.
    abd = float(np.arcsin(np.clip(-u[1] * -arm.out, -1.0, 1.0)))
    flex = float(np.arctan2(u[0], -u[2]))
    v = (L * n - elbow) / l2
    Ry = _rot_y(-flex)
    Rx = _rot_x(-abd * -arm.out)
    vl = (Ry @ Rx).T @ v
    # forearm in the upper arm's frame: (sin e cos r, sin e sin r, -cos e)
    rot = float(np.arctan2(vl[1] * -arm.out, vl[0])) if e > 1e-3 else 0.0
    return {arm.flex: flex, arm.abd: abd, arm.rot: rot, arm.elbow: e}


def _along(v: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Unit ``v`` with its part along the unit ``normal`` taken out (``v`` if along it)."""
    t = v - (v @ normal) * normal
    n = float(np.linalg.norm(t))
    return t / n if n > 1e-6 else v


def _turn_toward(a: np.ndarray, b: np.ndarray, limit: float) -> np.ndarray:
    """Unit vector ``a`` turned toward unit ``b`` by their angle, at most ``limit`` [rad]."""
    ang = float(np.arccos(np.clip(a @ b, -1.0, 1.0)))
    if ang <= limit or ang < 1e-9:
        return b if ang <= limit else a
    perp = b - (a @ b) * a
    perp /= np.linalg.norm(perp)
    return np.cos(limit) * a + np.sin(limit) * perp


def _rot_x(t: float) -> np.ndarray:
    c, s = np.cos(t), np.sin(t)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _rot_y(t: float) -> np.ndarray:
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _goals(solver: ik.Solver, cons, arm_of, meet: str | None):
    """The reach goals of :func:`arm_seeds` on the posture in the solver's data: (reach:
    each free arm's first placement, meeting: both hands at ``meet`` when a placement joins
    them, head_on: the arms bringing a fingertip in face to face, joined: (arm, other arm,
    the joining placement, the meeting centre) or None, lying: the arms bringing a pad
    onto a surface face to face, see :func:`_lying`)."""
    d = solver.data
    reach, meeting, head_on, lying, used, joined = [], [], [], [], set(), None
    for c in cons:
        if not isinstance(c, cn.Place) or (arm := arm_of(c.site)) is None or arm in used:
            continue
        used.add(arm)
        target = solver.kinematics().value(c.target)
        reach.append((arm, c.site, target))
        if (f := _head_on(solver, arm, c, cons)) is not None:
            head_on.append((arm, c.site, target, f))
        elif (p := _lying(solver, arm, c, cons)) is not None:
            lying.append((arm, c.site, target, *p))
        other = arm_of(c.target.site) if isinstance(c.target, SitePos) else None
        if other is not None and other is not arm and meet is not None and not meeting:
            # each hand a little to its own side, so that they start apart and close in
            centre = d.site_xpos[solver.site_id(meet)].copy()
            gap = np.array([0.0, MEET_GAP, 0.0])
            meeting = [
                (arm, c.site, centre + arm.out * gap),
                (other, c.target.site, centre + other.out * gap),
            ]
            joined = (arm, other, c, centre)
    return reach, meeting, head_on, joined, lying


def arm_seeds(
    solver: ik.Solver,
    arms,
    cons,
    free,
    q0: np.ndarray,
    hand_of,
    meet: str | None = None,
    carried_by=None,
) -> tuple[np.ndarray, ...]:
    """Starts (nq,) for a problem: each free arm in its two-bone posture for the first
    placement of a site on its hand; when a placement joins the two hands, both hands
    meeting at model site ``meet`` (the neutral signing space), once as the arms bring them (palms facing each
    other) and once stacked, both forearms pronated (palms down: a palm on the back of the
    other hand), each of these again with the hands the score orients turned as it asks
    (:func:`_turned`), and for a fingertip on the other hand that hand there palm down with the
    fingertip reaching it head-on; and when a fingertip must
    meet its target face to face (an ``Orient`` ``OPP`` of the two bodies' normals among
    ``cons``), the arm bringing it in head-on (see :func:`arm_seed`), and a pad the finger
    lying across the surface (:func:`_lying_seeds`); when a hand touches
    the other arm, that arm with its palm in the signing space first, then the hand
    reaching it. ``hand_of(site)`` is the arm whose hand carries a model site, or None;
    ``carried_by(site)`` (arm, its palm site, where that palm rests: an expression) for a
    site on an arm but not on its hand, or None. Empty when no placement moves a free arm.
    """
    m, d = solver.model, solver.data
    solver.at(q0, jacobians=True)
    free = set(free)
    arms = [a for a in arms if {a.flex, a.abd, a.rot, a.elbow} <= free]

    def arm_of(site: str) -> Arm | None:
        arm = hand_of(site)
        return arm if arm in arms else None

    def seeded(goals) -> np.ndarray:
        q = q0.copy()
        aims = []
        for arm, site, target, *facing in goals:
            sol = arm_seed(m, d, arm, d.site_xpos[solver.site_id(site)], target, *facing)
            for j, v in (sol or {}).items():
                q[m.jnt_qposadr[solver.joint_id(j)]] = v
            if facing and sol:
                aims.append((arm, site, target))
        for arm, site, target in aims:
            q = _aim_hand(solver, q, arm.wrist, site, target)
        if aims:  # leave ``data`` on ``q0`` for the next group
            solver.at(q0, jacobians=True)
        return q

    reach, meeting, head_on, joined, lying = _goals(solver, cons, arm_of, meet)
    aimed = {h[0] for h in head_on}  # the arms that bring a fingertip in head-on
    if head_on:
        head_on += [g for g in reach if g[0] not in aimed]
    seeds = [seeded(g) for g in (reach, meeting, head_on) if g]
    seeds += _lying_seeds(solver, seeds[0], lying, q0) if lying else []
    if meeting:
        # the placed hand above the other, both palms down
        (arm, site, p), (other, osite, po) = meeting
        up = np.array([0.0, 0.0, MEET_GAP])
        stacked = seeded([(arm, site, 0.5 * (p + po) + up), (other, osite, 0.5 * (p + po))])
        for a in (arm, other):
            if a.pron and a.pron in free:
                stacked[m.jnt_qposadr[solver.joint_id(a.pron)]] = STACKED_PRONATION
        seeds.append(stacked)
        arm, other, c, centre = joined
        if arm in aimed:
            # a fingertip on the other hand: that hand held in the signing space first,
            # palm down, then the fingertip reaching it there head-on
            held = seeded([(other, c.target.site, centre)])
            if other.pron and other.pron in free:
                held[m.jnt_qposadr[solver.joint_id(other.pron)]] = STACKED_PRONATION
            seeds += _then_reach(solver, held, arm, c, cons, q0)[1:]
    if seeds and carried_by is not None:
        seeds += _across(solver, arms, cons, q0, hand_of, carried_by, seeded)
    if meeting:  # two hands joined, their palms oriented by the score: turned as asked
        turned = [_turned(solver, arms, cons, free, q) for q in seeds]
        seeds += [t for t in turned if t is not None]
        solver.at(q0, jacobians=True)  # leave ``data`` on ``q0`` for the next group
    return tuple(seeds)


def rising_seed(solver: ik.Solver, arms, cons, q0: np.ndarray, hand_of) -> np.ndarray:
    """A start (nq,): ``q0`` with each arm of ``arms`` in its two-bone posture for its
    hand's first placement among ``cons``, the hand brought up from below (the wrist under
    the target, the elbow hanging in the vertical plane through shoulder and wrist): a hand
    on the face held with the elbow low in front, not the upper arm raised sideways.
    ``hand_of(site)`` is the arm whose hand carries a model site, or None."""
    m, d = solver.model, solver.data
    k = solver.at(q0)
    q, done = q0.copy(), set()
    for c in cons:
        if not isinstance(c, cn.Place) or (arm := hand_of(c.site)) not in arms or arm in done:
            continue
        done.add(arm)
        point = d.site_xpos[solver.site_id(c.site)]
        sol = arm_seed(m, d, arm, point, k.value(c.target), rising=True)
        for j, v in (sol or {}).items():
            q[m.jnt_qposadr[solver.joint_id(j)]] = v
    return q


#: Forearm rotations tried [fraction of the joint's range] to turn a seeded hand as the
#: score orients it.
TURN_SAMPLES = 9


def _turned(solver: ik.Solver, arms, cons, free, q: np.ndarray) -> np.ndarray | None:
    """Seed ``q`` with each arm whose palm the score orients (an ``Orient`` of its hand
    body among ``cons``: the weak palm turned up under the other hand) turned at the
    forearm to the rotation that best meets its orientations (the score's and face to
    face), or None when no arm is turned. Both hands are turned in the one start: a
    contact whose two sides are oriented starts with both."""
    m = solver.model
    out, turned = q.copy(), False
    for arm in arms:
        mine = [c for c in cons if isinstance(c, cn.Orient) and c.body == arm.hand]
        if not any(not c.label.endswith(":facing") for c in mine):
            continue  # the score orients neither hand: face to face alone seeds as before
        if not arm.pron or arm.pron not in free:
            continue
        j = solver.joint_id(arm.pron)
        adr = m.jnt_qposadr[j]

        costs = []
        for v in np.linspace(*m.jnt_range[j], TURN_SAMPLES):
            out[adr] = v
            k = solver.at(out)
            costs.append((sum(float(np.sum(c.rows(k)[0] ** 2)) for c in mine), v))
        out[adr] = min(costs)[1]
        turned = True
    return out if turned else None


def _across(
    solver: ik.Solver, arms, cons, q0: np.ndarray, hand_of, carried_by, seeded
) -> list[np.ndarray]:
    """Starts for a hand that touches the other arm: that arm's palm where
    ``carried_by`` says it rests (its forearm across in front of the body), then the hand
    reaching the touched site there, as it comes and head-on."""
    for c in cons:
        if not isinstance(c, cn.Place) or not isinstance(c.target, SitePos):
            continue
        arm, held = hand_of(c.site), carried_by(c.target.site)
        if arm not in arms or held is None or held[0] not in arms or held[0] is arm:
            continue
        other, palm, at = held
        return _then_reach(
            solver, seeded([(other, palm, solver.kinematics().value(at))]), arm, c, cons, q0
        )
    return []


def _then_reach(
    solver: ik.Solver, q1: np.ndarray, arm: Arm, c: cn.Place, cons, q0: np.ndarray
) -> list[np.ndarray]:
    """From ``q1``, where the other hand already holds ``c``'s target site, ``arm``
    reaching that site as it comes and, for a fingertip, head-on. Leaves ``data`` on
    ``q0``."""
    m, d = solver.model, solver.data
    out = []
    solver.at(q1, jacobians=True)
    target = d.site_xpos[solver.site_id(c.target.site)].copy()
    head_on, rule = _head_on(solver, arm, c, cons), _facing_of(solver, c, cons)
    for goal in [(target,)] + ([(target, head_on)] if head_on else []):
        q = q1.copy()
        sol = arm_seed(m, d, arm, d.site_xpos[solver.site_id(c.site)], *goal)
        for j, v in (sol or {}).items():
            q[m.jnt_qposadr[solver.joint_id(j)]] = v
        if sol and rule is not None:
            q = _aim_hand(solver, q, arm.wrist, c.site, target, rule)
        out.append(q)
    solver.at(q0, jacobians=True)
    return out


def _aim_hand(
    solver: ik.Solver,
    q: np.ndarray,
    joints,
    site: str,
    target: np.ndarray,
    facing: cn.Orient | None = None,
) -> np.ndarray:
    """``q`` with the forearm rotation and wrist ``joints`` (within their ranges) turning
    the hand so that ``site`` comes nearest ``target`` [m] and, with ``facing``, its
    surface turns to face the other (the elbow and the wrist stay where the two-bone
    solution put them; one radian of facing counts as ``AIM_M_PER_RAD``)."""
    m, d = solver.model, solver.data
    jid = [solver.joint_id(j) for j in joints]
    if not jid:
        return q
    adr = m.jnt_qposadr[jid]
    lo, hi = m.jnt_range[jid].T
    sid = solver.site_id(site)
    if facing is not None:
        ba, bb = solver.body_id(facing.body), solver.body_id(facing.vector.body)
        la, lb = np.asarray(facing.local, float), np.asarray(facing.vector.local, float)
    q = q.copy()

    def miss(x):
        q[adr] = np.clip(x, lo, hi)
        solver.at(q)
        cost = float(np.sum((d.site_xpos[sid] - target) ** 2))
        if facing is not None:
            c = (d.xmat[ba].reshape(3, 3) @ la) @ (d.xmat[bb].reshape(3, 3) @ lb)
            cost += 2.0 * (1.0 + c) * AIM_M_PER_RAD**2  # ~ (angle from opposed)^2
        return cost

    q[adr] = np.clip(_box_search(miss, _grid(lo, hi, 5), 200), lo, hi)
    return q


def _grid(lo: np.ndarray, hi: np.ndarray, n: int) -> np.ndarray:
    """(n ** k, k) points of a regular grid over the box ``lo``..``hi`` (k joints)."""
    return np.stack(
        np.meshgrid(*[np.linspace(a, b, n) for a, b in zip(lo, hi)], indexing="ij"), -1
    ).reshape(-1, len(lo))


def _box_search(miss, grid: np.ndarray, maxfev: int) -> np.ndarray:
    """The minimum of ``miss`` over joint values: the best point of ``grid``, then
    Nelder-Mead from it (at most ``maxfev`` evaluations; ``miss`` clips to the box)."""
    from scipy import optimize  # here: a realization that never needs it stays 45 MB lighter

    best = min(grid, key=miss)
    return optimize.minimize(
        miss, best, method="Nelder-Mead", options={"xatol": 1e-3, "fatol": 1e-8, "maxfev": maxfev}
    ).x


#: How much one radian of two surfaces turned from face to face weighs against a distance
#: when a seed aims its hand [m].
AIM_M_PER_RAD = 0.05


def _facing_of(solver: ik.Solver, place: cn.Place, cons) -> cn.Orient | None:
    """The face-to-face rule (an ``Orient`` ``OPP`` between the bodies of the two sites
    ``place`` joins) among ``cons``, or None."""
    if not isinstance(place.target, SitePos):
        return None
    m = solver.model
    body = int(m.site_bodyid[solver.site_id(place.site)])
    tbody = int(m.site_bodyid[solver.site_id(place.target.site)])
    return next(
        (
            o
            for o in cons
            if isinstance(o, cn.Orient)
            and o.rel is cn.Rel.OPP
            and isinstance(o.vector, BodyAxis)
            and solver.body_id(o.body) == body
            and solver.body_id(o.vector.body) == tbody
        ),
        None,
    )


#: A hand site whose outward normal is this close to the direction from the wrist to it
#: (cosine) is an end of the hand (a fingertip), which meets a surface head-on.
HEAD_ON_COS = 0.7


def _head_on(solver: ik.Solver, arm: Arm, place: cn.Place, cons):
    """(the target surface's outward normal, world; the facing tolerance [rad]) when
    ``place`` brings an end of ``arm``'s hand (a fingertip) face to face with a surface
    (an ``Orient`` ``OPP`` between the two sites' bodies among ``cons``), else None."""
    m, d = solver.model, solver.data
    o = _facing_of(solver, place, cons)
    if o is None:
        return None
    body = int(m.site_bodyid[solver.site_id(place.site)])
    out = d.xmat[body].reshape(3, 3) @ np.asarray(o.local, float)
    along = d.site_xpos[solver.site_id(place.site)] - d.xpos[solver.body_id(arm.hand)]
    if out @ along < HEAD_ON_COS * np.linalg.norm(along):
        return None
    tbody = solver.body_id(o.vector.body)
    normal = d.xmat[tbody].reshape(3, 3) @ np.asarray(o.vector.local, float)
    return normal / np.linalg.norm(normal), float(o.tol)


def _lying_seeds(solver: ik.Solver, q1: np.ndarray, lying, q0: np.ndarray) -> list[np.ndarray]:
    """From start ``q1``, each arm of ``lying`` (arm, pad site, target, the surface's
    outward normal, the face-to-face rule) bringing its pad in along the surface, the
    finger lying across it, the hand aimed to face it. Leaves ``data`` on ``q0``."""
    m, d, out = solver.model, solver.data, []
    for arm, site, target, normal, rule in lying:
        sol = arm_seed(m, d, arm, d.site_xpos[solver.site_id(site)], target, lying=normal)
        if sol:
            q = q1.copy()
            for j, v in sol.items():
                q[m.jnt_qposadr[solver.joint_id(j)]] = v
            out.append(_aim_hand(solver, q, arm.wrist, site, target, rule))
            solver.at(q0, jacobians=True)
    return out


def _lying(solver: ik.Solver, arm: Arm, place: cn.Place, cons):
    """(the target surface's outward normal, world; the face-to-face rule) when ``place``
    brings a pad of ``arm``'s fingers (a site on a digit that is not its end) face to face
    with a surface, else None."""
    m, d = solver.model, solver.data
    o = _facing_of(solver, place, cons)
    if o is None or int(m.site_bodyid[solver.site_id(place.site)]) == solver.body_id(arm.hand):
        return None
    normal = d.xmat[solver.body_id(o.vector.body)].reshape(3, 3) @ np.asarray(o.vector.local)
    return normal / np.linalg.norm(normal), o


#: Elbow swivels tried, in this order, when a solve fails from its warm start [rad, from
#: ``SWIVEL_OUT``]: the natural one, a quarter turn either way, the opposite side.
SWIVEL_RETRIES = (0.0, -np.pi / 2, np.pi / 2, np.pi)
#: Turns of a placed hand tried when a solve fails [rad]: (forearm pronation, wrist
#: flexion), each either way; a hand that meets its contact from the wrong side (a finger
#: under the other hand, in front of the face) needs another face toward it.
HAND_TURNS = (1.2, 0.8)


def swivel_seeds(
    solver: ik.Solver, arms, hand_of, problem: ik.IKProblem, q0: np.ndarray, turns=None
) -> Iterable[np.ndarray]:
    """Starts (nq,) on other arm branches, for a solve that failed from ``q0``: first every
    free arm in its natural two-bone posture for its hand's first placement
    (:func:`arm_seeds`); then ``q0`` with each placed hand turned by ``HAND_TURNS`` (about
    the forearm, then at the wrist, each way; ``turns`` maps an arm to its (pronation,
    wrist flexion) joint names, None: no turns); then one free arm at a time (the rest as
    in ``q0``) in its two-bone posture at each swivel of ``SWIVEL_RETRIES``, its hand at the
    target of the first placement of a site on it, then its wrist kept where it is; last,
    made only when asked for, ``problem`` solved with a fingertip held head-on to the
    surface it meets (:func:`_head_on_solves`). ``hand_of(site)`` is the arm whose hand
    carries a model site, or None."""
    m, d = solver.model, solver.data
    solver.at(q0, jacobians=True)
    free = set(solver.free_dofs(problem).tolist())
    goals: dict[Arm, list[tuple[np.ndarray, np.ndarray]]] = {}  # (hand point, target)
    for arm in arms:
        if not all(
            solver.joint_info(j)[1] in free for j in (arm.flex, arm.abd, arm.rot, arm.elbow)
        ):
            continue
        wrist = d.xpos[solver.body_id(arm.hand)].copy()
        goals[arm] = [(wrist, wrist)]
    k = solver.kinematics()
    for c in problem.constraints:
        if isinstance(c, cn.Place) and (arm := hand_of(c.site)) in goals and len(goals[arm]) < 2:
            goals[arm].insert(0, (d.site_xpos[solver.site_id(c.site)].copy(), k.value(c.target)))
    joints = [j for a in goals for j in (a.flex, a.abd, a.rot, a.elbow)]
    out = list(arm_seeds(solver, list(goals), problem.constraints, joints, q0, hand_of))
    for arm, pairs in goals.items():
        if len(pairs) < 2 or arm not in (turns or {}):
            continue  # no placement on this hand
        for j, turn in zip(turns[arm], HAND_TURNS):
            qadr, dof, _ = solver.joint_info(j)
            if dof in free:
                for sign in (1.0, -1.0):
                    q = q0.copy()
                    q[qadr] += sign * turn
                    out.append(q)
    for off in SWIVEL_RETRIES:
        for arm, pairs in goals.items():
            for point, target in pairs:
                sol = arm_seed(m, d, arm, point, target, swivel=SWIVEL_OUT + off)
                q = q0.copy()
                for j, v in (sol or {}).items():
                    q[solver.joint_info(j)[0]] = v
                out.append(q)
    return itertools.chain(
        out,
        _head_on_solves(solver, goals, hand_of, problem, q0),
        _turned_upper_arms(solver, goals, problem, q0),
    )


def _turned_upper_arms(solver: ik.Solver, goals, problem: ik.IKProblem, q0: np.ndarray):
    """Starts (nq,), made lazily: ``q0`` with each arm's shoulder joints turned so that its
    upper arm meets the orientation rules on it (a grid over the joint ranges, then
    Nelder-Mead): an upper arm raised past the side has its own branch of the shoulder."""
    m = solver.model
    k = solver.kinematics()
    for arm in goals:
        rules = [c for c in problem.constraints if isinstance(c, cn.Orient) and c.body == arm.upper]
        if not rules:
            continue
        solver.at(q0)
        vecs = [k.value(c.vector) for c in rules]
        vecs = [v / max(float(np.linalg.norm(v)), 1e-9) for v in vecs]
        jid = [solver.joint_id(j) for j in (arm.flex, arm.abd, arm.rot)]
        adr = m.jnt_qposadr[jid]
        lo, hi = m.jnt_range[jid].T
        q = q0.copy()
        miss = _orient_miss(solver, q, adr, lo, hi, solver.body_id(arm.upper), rules, vecs)
        grid = _grid(lo, hi, 7)
        # one start on each side of the abduction's right angle (two shoulder branches)
        for side in (grid[:, 1] <= np.pi / 2, grid[:, 1] > np.pi / 2):
            if not side.any():
                continue
            q[adr] = np.clip(_box_search(miss, grid[side], 300), lo, hi)
            yield q.copy()


#: Largest angle [rad] between a fingertip's segment and the normal of the surface it
#: meets in the seeder's head-on solves.
HEAD_ON_SEGMENT = np.deg2rad(20.0)


def _head_on_solves(solver: ik.Solver, goals, hand_of, problem: ik.IKProblem, q0: np.ndarray):
    """Starts (nq,), made lazily: for each arm's first placement of a hand site on a site
    of another body, ``problem`` solved from ``q0`` (without restarts) with that site's
    segment held within ``HEAD_ON_SEGMENT`` of the target surface's inward normal; a finger
    that meets the chin or the other hand at a slant touches it with its pad first."""
    m, d = solver.model, solver.data
    k = solver.kinematics()
    for arm in goals:
        c = next(
            (
                c
                for c in problem.constraints
                if isinstance(c, cn.Place)
                and hand_of(c.site) is arm
                and isinstance(c.target, SitePos)
                and hand_of(c.target.site) is not arm
            ),
            None,
        )
        if c is None:
            continue
        sid = solver.site_id(c.site)
        local = np.asarray(m.site_pos[sid], float)
        if m.site_bodyid[sid] == solver.body_id(arm.hand) or np.linalg.norm(local) < 1e-6:
            continue  # not the end of a finger segment
        solver.at(q0)
        tbody = int(m.site_bodyid[solver.site_id(c.target.site)])
        try:
            normal = surface.skin_distance(m, d, tbody, k.value(c.target))[1]
        except ValueError:
            continue
        nl = d.xmat[tbody].reshape(3, 3).T @ normal
        seg = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, int(m.site_bodyid[sid]))
        tname = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, tbody)
        rule = cn.Orient(
            seg,
            tuple(local / np.linalg.norm(local)),
            cn.Rel.OPP,
            BodyAxis(tname, tuple(nl)),
            tol=HEAD_ON_SEGMENT,
            label="head-on",
        )
        aug = dataclasses.replace(
            problem, constraints=tuple(problem.constraints) + (rule,), restarts=1
        )
        observer, solver.on_solve = solver.on_solve, None  # not one of the caller's solves
        try:
            q = solver.solve(aug, q0).qpos
        finally:
            solver.on_solve = observer
        yield q


def _orient_miss(solver: ik.Solver, q: np.ndarray, adr, lo, hi, body: int, rules, vecs):
    """The squared miss of the orientation ``rules`` (with their unit vectors ``vecs``) on
    ``body`` as a function of the joints at ``adr`` of ``q`` (set in place, within
    ``lo``..``hi``)."""
    d = solver.data

    def miss(x):
        q[adr] = np.clip(x, lo, hi)
        solver.at(q)
        R = d.xmat[body].reshape(3, 3)
        cost = 0.0
        for c, v in zip(rules, vecs):
            a = R @ np.asarray(c.local, float)
            if c.rel is cn.Rel.PERP:
                cost += float(a @ v) ** 2
            else:
                cost += float(np.sum((a - (-v if c.rel is cn.Rel.OPP else v)) ** 2))
        return cost

    return miss
