"""How close the arms can bring a contact of the natural-postures suite, upright (issue 26).

    python bench/reach_bound.py [--starts N] [--label NAME] CONTACT [CONTACT ...]

A contact of ``bench/natural.py`` (suite or held out) that the realizer misses is either a
search that did not find a posture or a posture the model does not have. This bench asks
the solver for the contact's placements (right-handed; the hand shapes as fixed joint
values; orientation rows left out) from ``--starts`` random postures of the arms it frees,
each joint drawn uniformly in its range, with the trunk, neck and head held upright, and
keeps the best result by placement error [mm] among:

- every result (``best_any_mm``);
- the natural ones (``best_natural_mm``): the suite's elbow rule (below the shoulders
  for targets below the eyes), RULA at most 4, no penetration beyond the solver's limit.

For the best natural result it lists the joints within 1 degree of a limit and the body
pairs closer than 0.5 mm (what holds it back). A best natural result above 1 mm over many
starts says the model, not the search, keeps the contact short. Results go to
``bench/results/reach-bound.json`` (or ``reach-bound-NAME.json`` with ``--label``).
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse
import sys
from pathlib import Path

import mujoco
import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

import natural as nat
from machine import machine, write_result

from azee_mj import constraints as cn
from azee_mj import ik
from azee_mj import kinematics as kin
from azee_mj.ergonomics import ergonomics
from azee_mj.schedule import make_solver
from azee_mj.sites import DEFAULT_MAP

#: Bodies of a hand (its palm and digits), named ``..._R`` / ``..._L`` or with a phalanx.
HAND = ("palm", "thumb", "index", "middle", "ring", "little")
#: Tracks held at rest: the trunk, neck and head stay upright.
HELD = ("back", "neck", "head")


def problem(contact, model: mujoco.MjModel) -> tuple[ik.IKProblem, np.ndarray, list]:
    """(the contact's placements freeing its arms only, the start with the hand shapes,
    the model site pairs placed) for the right-handed contact."""
    base, q0, _, _ = nat.mink_problem(contact, "R", model)
    pairs = [tuple(DEFAULT_MAP.sites[nat.site_name(x)] for x in p) for p in nat.places(contact)]
    cons = tuple(cn.Place(a, kin.SitePos(b), 0.001, f"place {i}") for i, (a, b) in enumerate(pairs))
    arms = {"R"} | ({"L"} if any("_L" in a + b for a, b in pairs) else set())
    limbs = ("clav", "arm", "f", "palm")
    free = tuple(
        n
        for n in (model.joint(j).name for j in range(model.njnt))
        if n.split("_")[0] in limbs and arms & set(n.split("_"))
    )
    free = tuple(j for j in free if not j.startswith(HELD)) or base.free_joints
    return ik.IKProblem(cons, free, natural=False, restarts=0), q0, pairs


def natural_enough(model: mujoco.MjModel, q: np.ndarray, penetration: float) -> bool:
    """The suite's elbow rule (below the shoulders for targets below the eyes), RULA at
    most 4, no penetration past the solver's limit."""
    e = ergonomics(model, q)
    return (
        e.elbows_ok()
        and e.rula.score <= nat.TARGETS["rula"]
        and penetration <= cn.PENETRATION_LIMIT
    )


def holding_back(model: mujoco.MjModel, q: np.ndarray, free) -> dict:
    """Joints within 1 degree of a limit and body pairs closer than 0.5 mm at ``q`` (pairs
    that collide: not a body and its parent, not excluded by the model, not one hand's
    own digits)."""
    d = mujoco.MjData(model)
    d.qpos[:] = q
    mujoco.mj_forward(model, d)
    limits = []
    for name in free:
        j = model.joint(name)
        v, (lo, hi) = q[j.qposadr[0]], j.range
        if min(v - lo, hi - v) < np.radians(1.0):
            limits.append(f"{name} {np.degrees(v):.0f} deg")
    close = set()
    excluded = set(model.exclude_signature.tolist())
    geoms = np.flatnonzero(model.geom_contype)
    for a in geoms:
        for b in geoms[geoms > a]:
            ba, bb = model.geom_bodyid[a], model.geom_bodyid[b]
            if ba == bb or model.body_parentid[ba] == bb or model.body_parentid[bb] == ba:
                continue
            if (min(ba, bb) << 16) + max(ba, bb) in excluded:
                continue
            names = model.body(ba).name, model.body(bb).name
            sides = [{"L", "R"} & set(n.split("_")) for n in names]
            if all(n.startswith(HAND) for n in names) and sides[0] == sides[1]:
                continue  # one hand's own digits, as its shape holds them
            if mujoco.mj_geomDistance(model, d, a, b, 0.001, None) < 0.0005:
                close.add("/".join(sorted((model.body(ba).name, model.body(bb).name))))
    return {"at_limit": limits, "touching": sorted(close)}


def bound(contact, solver: ik.Solver, starts: int, seed: int = 0) -> tuple[dict, np.ndarray]:
    m = solver.model
    prob, q0, pairs = problem(contact, m)
    d = mujoco.MjData(m)
    rng = np.random.default_rng(seed)
    adr = np.array([m.joint(j).qposadr[0] for j in prob.free_joints])
    rng_lo, rng_hi = np.array([m.joint(j).range for j in prob.free_joints]).T
    best_any, best_nat, q_nat, met = np.inf, np.inf, None, 0
    for _ in range(starts):
        q = q0.copy()
        q[adr] = rng.uniform(rng_lo, rng_hi)
        r = solver.solve(prob, q)
        d.qpos[:] = r.qpos
        mujoco.mj_kinematics(m, d)
        err = 1e3 * max(np.linalg.norm(d.site(a).xpos - d.site(b).xpos) for a, b in pairs)
        ok = r.penetration <= cn.PENETRATION_LIMIT
        met += int(ok and err <= nat.TARGETS["contact_mm"])
        best_any = min(best_any, err if ok else np.inf)
        if err < best_nat and natural_enough(m, r.qpos, r.penetration):
            best_nat, q_nat = err, r.qpos.copy()
    rec = {
        "contact": contact[0],
        "starts": starts,
        "met": met,
        "best_any_mm": best_any,
        "best_natural_mm": best_nat,
        **(holding_back(m, q_nat, prob.free_joints) if q_nat is not None else {}),
    }
    return rec, q_nat


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("contacts", nargs="+", help="contact names of bench/natural.py")
    ap.add_argument("--starts", type=int, default=1000, help="random starts per contact")
    ap.add_argument("--label", help="write bench/results/reach-bound-LABEL.json")
    ap.add_argument("--postures", type=Path, help="save each best natural posture here (.npy)")
    args = ap.parse_args(argv)
    known = {c[0]: c for c in nat.CONTACTS + nat.HELD_OUT}
    unknown = [n for n in args.contacts if n not in known]
    if unknown:
        ap.error(f"unknown contact {', '.join(unknown)}; see bench/natural.py")
    solver = make_solver()
    recs = []
    for name in args.contacts:
        rec, q = bound(known[name], solver, args.starts)
        recs.append(rec)
        if args.postures and q is not None:
            args.postures.mkdir(parents=True, exist_ok=True)
            np.save(args.postures / f"{name}.npy", q)
        print(
            f"{name}: best natural {rec['best_natural_mm']:.2f} mm, best of all "
            f"{rec['best_any_mm']:.2f} mm, {rec['met']}/{rec['starts']} starts met; "
            f"at a limit: {', '.join(rec.get('at_limit', [])) or '-'}; "
            f"touching: {', '.join(rec.get('touching', [])) or '-'}"
        )
    out = (
        HERE / "results" / (f"reach-bound-{args.label}.json" if args.label else "reach-bound.json")
    )
    doc = {"machine": machine(), "held_upright": HELD, "records": recs}
    write_result(out, doc)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
