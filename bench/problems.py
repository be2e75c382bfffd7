"""A fixed, seeded set of reachable keyframes for the bundled signer.

Targets come from forward kinematics of random collision-free postures: 6 to 12 constraints
each, including perpendicular orientations, two-hand contacts and hand-to-face contacts.
A contact keyframe is made by first bringing the two sites together from the random posture
(any posture that meets it proves it reachable), then reading every other target off it.

By default the keyframes form a *sequence*, as the postures of a signed sentence do: each
truth posture is the previous truth plus a bounded random change of the free joints
(uniform within +-``STEP`` rad, clipped to the middle 90 % of each arm joint's range and to
the same middle band as :func:`random_posture` for the trunk and neck, redrawn if it
penetrates; a contact keyframe is redrawn if reaching the contact moves a joint more than
``2 * STEP`` from the previous truth), so warm-starting from the previous solution means something. ``sequence=False``
gives independent random postures.
"""

from __future__ import annotations

import dataclasses
import json
import pathlib

import mujoco
import numpy as np

from azee_mj import constraints as cn
from azee_mj import ik
from azee_mj import kinematics as kin
from azee_mj.schedule import make_solver
from azee_mj.sites import DEFAULT_MAP

ARM = (
    "clav_{X}_elev",
    "clav_{X}_prot",
    "arm_{X}_flex",
    "arm_{X}_abd",
    "arm_{X}_rot",
    "f_arm_{X}_flex",
    "f_arm_{X}_pron",
    "palm_{X}_flex",
    "palm_{X}_dev",
)
HAND_SITES = (
    "I_TIP_{X}",
    "T_TIP_{X}",
    "M_TIP_{X}",
    "PA_{X}",
    "WR_{X}",
    "H_BACK_{X}",
    "L_TIP_{X}",
    "EL_{X}",
)
FACE_SITES = ("CH", "NO", "FH", "CK_{X}", "MO", "TE_{X}", "EAR_{X}")
OTHER_HAND = ("PA_{X}", "H_BACK_{X}", "I_TIP_{X}", "WR_{X}", "F_ARM_{X}")


@dataclasses.dataclass(frozen=True)
class Keyframe:
    """A reachable problem and the posture it was read off (``truth``)."""

    kind: str  # "free", "two-hand", "hand-face"
    problem: ik.IKProblem
    truth: np.ndarray


def _joints(sides=("R", "L")):
    return tuple(j.format(X=s) for s in sides for j in ARM) + (
        "back_1_flex",
        "back_2_flex",
        "back_2_rot",
        "neck_flex",
        "head_rot",
    )


#: Largest change of one free joint between consecutive truth postures of a sequence [rad].
STEP = 0.6


def _box(solver: ik.Solver, arm_pad: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(qpos addresses, lower, upper) of the free joints: arm ranges shrunk by ``arm_pad``
    of their span at each end, trunk and neck by 35 %."""
    m = solver.model
    adr, lo, hi = [], [], []
    for j in _joints():
        jid = solver.joint_id(j)
        a, b = m.jnt_range[jid]
        pad = (0.35 if j.startswith(("back", "neck", "head")) else arm_pad) * (b - a)
        adr.append(m.jnt_qposadr[jid])
        lo.append(a + pad)
        hi.append(b - pad)
    return np.array(adr), np.array(lo), np.array(hi)


def random_posture(solver: ik.Solver, rng: np.random.Generator) -> np.ndarray:
    """A random collision-free posture: arms anywhere in their ranges (shrunk 10 %)."""
    m, d = solver.model, mujoco.MjData(solver.model)
    adr, lo, hi = _box(solver, 0.1)
    while True:
        q = solver.natural.copy()
        q[adr] = rng.uniform(lo, hi)
        d.qpos[:] = q
        if cn.penetration_depth(m, d) <= 0.0:
            return q


def next_posture(
    solver: ik.Solver, q: np.ndarray, rng: np.random.Generator, step: float = STEP
) -> np.ndarray:
    """``q`` plus a uniform random change of at most ``step`` [rad] per free joint, clipped
    to the middle 90 % of the arm ranges (trunk and neck as in :func:`random_posture`),
    redrawn until collision-free."""
    m, d = solver.model, mujoco.MjData(solver.model)
    adr, lo, hi = _box(solver, 0.05)
    while True:
        out = q.copy()
        out[adr] = np.clip(q[adr] + rng.uniform(-step, step, adr.size), lo, hi)
        d.qpos[:] = out
        if cn.penetration_depth(m, d) <= 0.0:
            return out


def _fk(solver, q):
    d = solver.data
    d.qpos[:] = q
    mujoco.mj_kinematics(solver.model, d)
    return d


def _read_off(solver, q, rng, n_place, n_orient, with_perp=True):
    """Place and orient constraints read off posture ``q``."""
    d = _fk(solver, q)
    cons = []
    sides = ["R", "L"]
    for i in range(n_place):
        side = sides[i % 2]
        site = rng.choice(HAND_SITES).format(X=side)
        cons.append(
            cn.Place(
                site, kin.Const(tuple(d.site_xpos[solver.site_id(site)])), label=f"place {site}"
            )
        )
    bones = ["palm_{X}", "f_arm_{X}", "index_{X}_3", "arm_{X}"]
    for i in range(n_orient):
        side = sides[i % 2]
        bone = DEFAULT_MAP.bones[rng.choice(bones).format(X=side)]
        axis = bone.dir if rng.random() < 0.5 else bone.nrm
        R = d.xmat[solver.body_id(bone.body)].reshape(3, 3)
        a = R @ np.asarray(axis)
        if with_perp and i % 3 == 2:
            v = np.cross(a, rng.normal(size=3))
            v /= np.linalg.norm(v)
            cons.append(
                cn.Orient(
                    bone.body, axis, cn.Rel.PERP, kin.Const(tuple(v)), label=f"perp {bone.body}"
                )
            )
        elif rng.random() < 0.5:
            cons.append(
                cn.Orient(
                    bone.body, axis, cn.Rel.ALONG, kin.Const(tuple(a)), label=f"along {bone.body}"
                )
            )
        else:
            cons.append(
                cn.Orient(
                    bone.body, axis, cn.Rel.OPP, kin.Const(tuple(-a)), label=f"opp {bone.body}"
                )
            )
    return cons


def make_keyframes(
    n: int = 200, seed: int = 0, solver: ik.Solver | None = None, sequence: bool = True
) -> list[Keyframe]:
    """``n`` reachable keyframes: 1/2 free placements, 1/4 two-hand, 1/4 hand-to-face.

    With ``sequence`` (the default) each truth posture is a bounded random change of the
    previous one (see :func:`next_posture`); otherwise each is an independent random posture.
    """
    solver = solver or make_solver()
    rng = np.random.default_rng(seed)
    out: list[Keyframe] = []
    free = _joints()
    while len(out) < n:
        kind = ("free", "free", "two-hand", "hand-face")[len(out) % 4]
        if sequence and out:
            q = next_posture(solver, out[-1].truth, rng)
        else:
            q = random_posture(solver, rng)
        contact = []
        if kind != "free":
            a = rng.choice(HAND_SITES[:4]).format(X="R")
            if kind == "two-hand":
                b = rng.choice(OTHER_HAND).format(X="L")
            else:
                b = rng.choice(FACE_SITES).format(X=rng.choice(["R", "L"]))
            contact = [cn.Place(a, kin.SitePos(b), label=f"contact {a}-{b}")]
            res = solver.solve(ik.IKProblem(tuple(contact), free), q)
            if not res.converged:
                continue
            if sequence and out and np.abs(res.qpos - out[-1].truth).max() > 2 * STEP:
                continue  # reaching the contact moved too far from the previous posture
            q = res.qpos
        n_cons = int(rng.integers(6, 13)) - len(contact)
        n_place = max(1, n_cons // 2 - 1)
        cons = contact + _read_off(solver, q, rng, n_place, n_cons - n_place)
        out.append(Keyframe(kind, ik.IKProblem(tuple(cons), free), q))
    return out


# ---------------------------------------------------------------------------------------
# The stored set: generating contact keyframes uses a solver, so the benchmark reads a set
# written once to JSON and stays the same while the solver changes.
# ---------------------------------------------------------------------------------------

DATA = pathlib.Path(__file__).resolve().parent / "data" / "keyframes.json"


def _expr(e) -> dict:
    if isinstance(e, kin.Const):
        return {"const": list(e.value)}
    if isinstance(e, kin.SitePos):
        return {"site": e.site}
    raise TypeError(f"not stored: {e!r}")


def _unexpr(o: dict):
    return kin.Const(tuple(o["const"])) if "const" in o else kin.SitePos(o["site"])


def _cons(c) -> dict:
    if isinstance(c, cn.Place):
        return {"place": c.site, "target": _expr(c.target), "tol": c.tol, "label": c.label}
    if isinstance(c, cn.Orient):
        return {
            "orient": c.body,
            "local": list(c.local),
            "rel": c.rel.value,
            "vector": _expr(c.vector),
            "tol": c.tol,
            "label": c.label,
        }
    raise TypeError(f"not stored: {c!r}")


def _uncons(o: dict):
    if "place" in o:
        return cn.Place(o["place"], _unexpr(o["target"]), o["tol"], o["label"])
    return cn.Orient(
        o["orient"], tuple(o["local"]), cn.Rel(o["rel"]), _unexpr(o["vector"]), o["tol"], o["label"]
    )


def save_keyframes(kfs: list[Keyframe], path=DATA, **meta) -> None:
    """Write ``kfs`` (and ``meta``, e.g. how they were made) to JSON."""
    path.parent.mkdir(parents=True, exist_ok=True)
    rows = [
        {
            "kind": k.kind,
            "free_joints": list(k.problem.free_joints),
            "constraints": [_cons(c) for c in k.problem.constraints],
            "truth": [float(x) for x in k.truth],
        }
        for k in kfs
    ]
    path.write_text(json.dumps({"meta": meta, "keyframes": rows}) + "\n")


def load_keyframes(path=DATA) -> list[Keyframe]:
    """The stored keyframes (see :func:`save_keyframes`)."""
    rows = json.loads(path.read_text())["keyframes"]
    return [
        Keyframe(
            r["kind"],
            ik.IKProblem(tuple(_uncons(c) for c in r["constraints"]), tuple(r["free_joints"])),
            np.array(r["truth"]),
        )
        for r in rows
    ]
