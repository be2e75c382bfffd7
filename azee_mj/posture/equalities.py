"""Placements mirrored as MuJoCo ``connect`` equalities on a pool of mocap targets.

A placement at a fixed point uses a mocap target; a site-to-site contact connects the two
sites directly, so the viewer can draw them and a simulation can use them; their rows are
MuJoCo's (the tests compare them with ``efc_J``/``efc_pos``).

Units: metres.
"""

from __future__ import annotations

import mujoco

from azee_mj.constraints import Place
from azee_mj.kinematics import Const, Names, SitePos
from azee_mj.posture.problem import IKProblem


def add_target_pool(spec: mujoco.MjSpec, n: int) -> None:
    """Add ``n`` mocap bodies ``ik_target_k`` with a site each, and ``n`` inactive site-based
    ``connect`` equalities ``ik_connect_k`` that :meth:`Solver.configure_equalities` aims."""
    anchor = spec.sites[0].name
    for k in range(n):
        body = spec.worldbody.add_body(name=f"ik_target_{k}", mocap=True)
        body.add_site(name=f"ik_target_{k}", size=[0.006, 0, 0], rgba=[0.1, 0.8, 0.2, 0.6], group=5)
        spec.add_equality(
            name=f"ik_connect_{k}",
            type=mujoco.mjtEq.mjEQ_CONNECT,
            objtype=mujoco.mjtObj.mjOBJ_SITE,
            name1=anchor,
            name2=f"ik_target_{k}",
            active=False,
        )


def configure(
    model: mujoco.MjModel, data: mujoco.MjData, names: Names, n_targets: int, problem: IKProblem
) -> int:
    """Aim the pool's equalities (the last ``n_targets`` of ``model``) at the placements of
    ``problem``; returns how many are active (see :meth:`azee_mj.ik.Solver.configure_equalities`)."""
    m, d = model, data
    first = m.neq - n_targets
    m.eq_active0[first:] = 0
    d.eq_active[first:] = 0
    k = 0
    for c in problem.constraints:
        if not isinstance(c, Place) or k >= n_targets:
            continue
        eq = first + k
        m.eq_obj1id[eq] = names.site(c.site)
        if isinstance(c.target, SitePos):
            m.eq_obj2id[eq] = names.site(c.target.site)
        elif isinstance(c.target, Const):
            m.eq_obj2id[eq] = names.site(f"ik_target_{k}")
            d.mocap_pos[m.body_mocapid[names.body(f"ik_target_{k}")]] = c.target.value
        else:
            continue
        m.eq_active0[eq] = 1
        d.eq_active[eq] = 1
        k += 1
    return k
