"""Why a constraint was not met: out of reach, in conflict, blocked by a collision, or
stopped by a joint limit.

:func:`diagnose` examines an unconverged :class:`~azee_mj.ik.IKResult` and gives one reason
per constraint that misses, tried in this order:

1. **out of reach**: a placement whose target lies farther from the root of its limb (a
   clavicle for a hand) than the limb can stretch (the sum of its segments), by how much;
2. **conflict**: this one alone can be met, but not together with one other named one;
3. **blocked by a collision**: the problem is met with self-collision switched off; the
   two body parts that solution drives deepest into each other are named, with how deep
   (or, when it drives none into another, the two closest at the result);
4. **stopped by a joint limit**: a free joint sits at a limit and moving it past the limit
   would reduce the residual; the joint that would help most is named;
5. otherwise a local minimum of the solver, with why its run stopped
   (:attr:`~azee_mj.ik.IKResult.stop_message`).

Units: metres, radians.
"""

from __future__ import annotations

import dataclasses
import itertools

import mujoco
import numpy as np

from azee_mj import constraints as cn
from azee_mj import ik

#: How deep two parts must pass into each other at a collision-free solution to be named
#: as what blocks it [m]: deeper than the contact allowance.
PASS_THROUGH = 2 * cn.CONTACT_ALLOWANCE


@dataclasses.dataclass(frozen=True)
class Diagnosis:
    """Why constraint ``label`` misses: ``kind`` is ``reach``, ``conflict``, ``collision``,
    ``limit`` or ``minimum``; ``detail`` says it in words."""

    label: str
    kind: str
    detail: str


def diagnose(
    solver: ik.Solver,
    problem: ik.IKProblem,
    result: ik.IKResult,
    q0: np.ndarray,
    limb_root=None,
    only: str | None = None,
) -> tuple[Diagnosis, ...]:
    """A :class:`Diagnosis` for each hard constraint of ``problem`` that ``result`` (solved
    from ``q0``) misses (only the one labelled ``only``, if given). ``limb_root(site)`` is
    the body where the limb carrying a model site starts (a clavicle for a hand site), or
    None: reach is measured from there."""
    out = []
    missed = [
        (c, r)
        for c, r in zip(problem.constraints, result.residuals)
        if not c.soft and not r.ok and only in (None, c.label)
    ]
    for c, r in missed:
        d = (
            _reach(solver, c, result.qpos, limb_root)
            or _conflict(solver, problem, c, q0)
            or _collision(solver, problem, c, result.qpos)
            or _limit(solver, problem, c, result.qpos)
        )
        out.append(d or Diagnosis(c.label, "minimum", minimum_detail(result)))
    return tuple(out)


def _name(m: mujoco.MjModel, obj, i: int) -> str:
    return mujoco.mj_id2name(m, obj, int(i)) or str(i)


def minimum_detail(result: ik.IKResult) -> str:
    """The words of a local minimum, with why the solver stopped when it says."""
    text = "a local minimum of the solver (no limit, reach or collision explains it)"
    return text if result.stop is None else f"{text}; the solver stopped: {result.stop_message}"


def _reach(solver, c, q, limb_root) -> Diagnosis | None:
    if not isinstance(c, cn.Place) or limb_root is None or (root := limb_root(c.site)) is None:
        return None
    m, d = solver.model, solver.data
    solver.at(q)
    sid = solver.site_id(c.site)
    chain, b = [], int(m.site_bodyid[sid])
    while b > 0 and b != root:
        chain.append(b)
        b = int(m.body_parentid[b])
    if b != root:
        return None
    # the limb stretched straight: from its root joint through each joint to the site
    points = [d.xpos[x] for x in [root, *reversed(chain)]] + [d.site_xpos[sid]]
    length = sum(float(np.linalg.norm(y - x)) for x, y in itertools.pairwise(points))
    target = solver.kinematics().value(c.target)
    dist = float(np.linalg.norm(target - d.xpos[root]))
    if dist <= length:
        return None
    return Diagnosis(
        c.label,
        "reach",
        f"out of reach by {(dist - length) * 1000:.0f} mm (the "
        f"target is {dist * 1000:.0f} mm from {_name(m, mujoco.mjtObj.mjOBJ_BODY, root)}, "
        f"the limb reaches {length * 1000:.0f} mm)",
    )


def _conflict(solver, problem, c, q0) -> Diagnosis | None:
    """``c`` alone is met, and met with each other constraint but one."""

    def met_with(extra) -> bool:
        keep = tuple(
            x
            for x in problem.constraints
            if x is c or x in extra or x.soft or isinstance(x, cn.JointTarget)
        )
        res = solver.solve(dataclasses.replace(problem, constraints=keep, natural=False), q0)
        return res.residuals[keep.index(c)].ok

    block = c.label.rsplit("#", 1)[0]
    # (not the one it derives from: ``X:facing`` of placement ``X``)
    others = sorted(
        (
            o
            for o in problem.constraints
            if o is not c
            and not o.soft
            and not isinstance(o, cn.JointTarget)
            and not c.label.startswith(f"{o.label}:")
        ),
        key=lambda o: o.label.rsplit("#", 1)[0] != block,
    )  # its own block first
    if not others or not met_with(()):
        return None
    for o in others:
        if not met_with((o,)):
            return Diagnosis(
                c.label, "conflict", f"conflicts with {o.label}: each can be met without the other"
            )
    return None


def _collision(solver, problem, c, q) -> Diagnosis | None:
    """Met with self-collision off: the two parts that solution drives deepest into each
    other (or, if none goes deeper than ``PASS_THROUGH``, the two closest at ``q``)."""
    res = solver.solve(dataclasses.replace(problem, collide=False, natural=False), q)
    if not res.residuals[problem.constraints.index(c)].ok:
        return None
    through = _deepest(solver, res.qpos)
    if through is not None and through[0] > PASS_THROUGH:
        depth, a, b = through
        return Diagnosis(
            c.label,
            "collision",
            f"blocked by a collision between {a} and {b} "
            f"(met only with them {depth * 1000:.0f} mm into each other)",
        )
    near = _deepest(solver, q)
    if near is None:
        return Diagnosis(c.label, "collision", "blocked by self-collision")
    _, a, b = near
    return Diagnosis(c.label, "collision", f"blocked by a collision between {a} and {b}")


def _deepest(solver, q) -> tuple[float, str, str] | None:
    """(depth [m], negative if apart; the two bodies) of the deepest contact MuJoCo finds
    in posture ``q``, or None without any."""
    m, d = solver.model, solver.data
    solver.at(q)
    mujoco.mj_collision(m, d)
    if not d.ncon:
        return None
    i = int(np.argmin(d.contact.dist[: d.ncon]))
    a, b = (_name(m, mujoco.mjtObj.mjOBJ_BODY, m.geom_bodyid[g]) for g in d.contact.geom[i])
    return -float(d.contact.dist[i]), a, b


def _limit(solver, problem, c, q) -> Diagnosis | None:
    m = solver.model
    plan = solver.plan(problem)
    solver.at(q, jacobians=True)
    r, J = plan.rows()
    k = problem.constraints.index(c)
    blk = plan.items[k]
    grad = J[blk.start : blk.stop].T @ r[blk.start : blk.stop]  # (nv,) d(|r|^2 / 2)/dq
    best = None
    for dof in plan.free:
        lo, hi = solver.lower[dof], solver.upper[dof]
        at_lo, at_hi = q[dof] <= lo + 1e-6, q[dof] >= hi - 1e-6
        # moving past the limit (down at lo, up at hi) would lower the residual
        gain = grad[dof] if at_lo else -grad[dof] if at_hi else 0.0
        if gain > 1e-9 and (best is None or gain > best[0]):
            best = (gain, dof, "lower" if at_lo else "upper")
    if best is None:
        return None
    _, dof, side = best
    j = m.dof_jntid[dof]
    lim = np.degrees(m.jnt_range[j][0 if side == "lower" else 1])
    return Diagnosis(
        c.label,
        "limit",
        f"stopped by the {side} limit of joint "
        f"{_name(m, mujoco.mjtObj.mjOBJ_JOINT, j)} ({lim:.0f} deg)",
    )
