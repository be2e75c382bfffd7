"""How close to face to face a contact of the suite can come, with the arm's ranges as
modelled or widened (issue 10, *fist on the stomach*).

    python bench/facing.py [--contact fist-stomach] [--at SITE] [--starts 40] [--range JOINT:LO:HI ...]

A flat or gently convex skin surface meets another only within a few degrees of face to
face (the two outward normals opposed), so a contact whose bodies cannot turn to face each
other is missed however the rest of the arm moves. For a contact of ``bench/natural.py``
(right-handed, its hand shapes held), this searches the strong arm's nine joints (the
spine held upright at ``home``) for

- *facing*: the placed site on its target and the least angle between the two sites'
  outward normals (``SignerMap.normals``), the hand passing freely into the touched body
  (the palm and every digit: whatever the hand's own shape, this is the arm's reach) while
  every other pair of collision geoms stays apart, the elbow at least 2 cm below the
  shoulder joint;
- *touching*: every collision active (the two sites' bodies may touch 0.5 mm deep, the
  solver's contact allowance), the least distance between the two sites and the angle there.

Each is a bounded least-squares search (``scipy.optimize.least_squares``) from ``--starts``
random in-range postures (seeded) plus ``home``; *touching* also starts from the best
*facing* posture. ``--model`` measures another MJCF signer (e.g. a variant the generator
wrote). Without ``--range`` it runs the settings
that ``docs/benchmarks.md`` reports (the ranges as modelled, then the shoulder's internal
rotation, the forearm's pronation, the wrist's flexion and the clavicle's elevation
changed); ``--range JOINT:LO:HI`` (degrees, repeatable) runs one setting. Writes nothing.
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
from scipy.optimize import least_squares

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

from natural import CONTACTS, mink_problem

from azee_mj import constraints as cn
from azee_mj import load_model
from azee_mj.sites import DEFAULT_MAP

DEG = np.pi / 180.0

#: The settings of ``docs/benchmarks.md``: (label, {joint: (lo, hi) degrees}); the right
#: arm, the left mirrors it.
SETTINGS = (
    ("as modelled", {}),
    ("internal rotation 90", {"arm_R_rot": (-90, 90)}),
    ("internal rotation 100", {"arm_R_rot": (-90, 100)}),
    ("internal rotation 110", {"arm_R_rot": (-90, 110)}),
    (
        "rotation 90, pronation 90, wrist flexion 85",
        {"arm_R_rot": (-90, 90), "f_arm_R_pron": (-80, 90), "palm_R_flex": (-70, 85)},
    ),
    ("clavicle elevation <= 10", {"clav_R_elev": (-10, 10)}),
    ("clavicle <= 10, rotation 110", {"clav_R_elev": (-10, 10), "arm_R_rot": (-90, 110)}),
    ("clavicle <= 10, rotation 120", {"clav_R_elev": (-10, 10), "arm_R_rot": (-90, 120)}),
)


class Reach:
    """The strong arm of one contact's held problem on a model with the given ranges."""

    def __init__(self, contact, ranges: dict[str, tuple[float, float]], model=None):
        m = self.m = load_model() if model is None else mujoco.MjModel.from_xml_path(str(model))
        for j, (lo, hi) in ranges.items():
            m.jnt_range[m.joint(j).id] = np.array([lo, hi]) * DEG
        self.d = mujoco.MjData(m)
        _, q0, site, at = mink_problem(contact, "R", m)
        self.q0 = q0
        self.joints = DEFAULT_MAP.tracks["arm_R"]
        ids = [m.joint(j).id for j in self.joints]
        self.adr = m.jnt_qposadr[ids]
        self.lo, self.hi = m.jnt_range[ids, 0].copy(), m.jnt_range[ids, 1].copy()
        self.q0[self.adr] = np.clip(self.q0[self.adr], self.lo, self.hi)
        self.s1, self.s2 = (m.site(DEFAULT_MAP.sites[x]).id for x in (site, at))
        self.n1, self.n2 = (np.array(DEFAULT_MAP.normals[x]) for x in (site, at))
        self.b1, self.b2 = int(m.site_bodyid[self.s1]), int(m.site_bodyid[self.s2])
        hand = m.body("palm_R").id
        self.hand = {b for b in range(m.nbody) if self._under(b, hand)}
        self.elbow, self.shoulder = m.body("f_arm_R").id, m.body("arm_R").id

    def _under(self, b: int, top: int) -> bool:
        while b > 0:
            if b == top:
                return True
            b = int(self.m.body_parentid[b])
        return False

    def set(self, x) -> None:
        self.d.qpos[:] = self.q0
        self.d.qpos[self.adr] = x
        mujoco.mj_kinematics(self.m, self.d)

    def gap(self) -> tuple[np.ndarray, float]:
        """(site-to-target vector [m], angle between the normals and face to face [rad])."""
        d = self.d
        a = d.site_xmat[self.s1].reshape(3, 3) @ self.n1
        b = d.site_xmat[self.s2].reshape(3, 3) @ self.n2
        return d.site_xpos[self.s1] - d.site_xpos[self.s2], float(np.arccos(np.clip(-a @ b, -1, 1)))

    def depths(self, hand_free: bool) -> tuple[float, float]:
        """(deepest between the two sites' bodies, deepest elsewhere) [m], >= 0; with
        ``hand_free`` the hand's bodies pass into the touched body."""
        m, d = self.m, self.d
        mujoco.mj_collision(m, d)
        pair = other = 0.0
        for c in d.contact[: d.ncon]:
            if c.dist >= 0.0:
                continue
            g = {int(m.geom_bodyid[c.geom[0]]), int(m.geom_bodyid[c.geom[1]])}
            if g == {self.b1, self.b2} or (
                hand_free and self.b2 in g and g - {self.b2} <= self.hand
            ):
                pair = max(pair, -c.dist)
            else:
                other = max(other, -c.dist)
        return pair, other

    def elbow_drop(self) -> float:
        """How far the elbow is below the shoulder joint [m]."""
        return float(self.d.xpos[self.shoulder][2] - self.d.xpos[self.elbow][2])

    def contact(self, x):
        """On posture ``x``: the gap between the two sites and the sum of their outward
        normals (zero face to face)."""
        self.set(x)
        p, _ = self.gap()
        a = self.d.site_xmat[self.s1].reshape(3, 3) @ self.n1
        b = self.d.site_xmat[self.s2].reshape(3, 3) @ self.n2
        return p, a + b

    def facing_rows(self, x):
        p, ab = self.contact(x)
        _, other = self.depths(hand_free=True)
        low = max(0.0, 0.02 - self.elbow_drop())
        return np.r_[p * 1e4, ab * 57.3, other * 1e5, low * 1e4]

    def touching_rows(self, x):
        p, ab = self.contact(x)
        pair, other = self.depths(hand_free=False)
        over = max(0.0, pair - cn.CONTACT_ALLOWANCE)
        return np.r_[p * 1e3, ab * 5.73, over * 3e4, other * 3e4]

    def search(self, rows, starts: int, ok, first=()) -> np.ndarray | None:
        """Bounded least squares of ``rows`` from the postures ``first`` (arm joints),
        ``home`` and ``starts`` random ones; the best by ``ok(x)`` (a sortable key, None =
        not valid)."""
        rng = np.random.default_rng(0)
        xs = [*first, self.q0[self.adr].copy()]
        xs += [self.lo + (self.hi - self.lo) * rng.random(len(self.lo)) for _ in range(starts)]
        best, key = None, None
        for x in xs:
            s = least_squares(rows, x, bounds=(self.lo, self.hi), diff_step=1e-4, max_nfev=400)
            k = ok(s.x)
            if k is not None and (key is None or k < key):
                best, key = s.x, k
        return best

    def at_limits(self, x) -> str:
        lim = [
            f"{j} {x_ / DEG:.0f}"
            for j, x_, lo, hi in zip(self.joints, x, self.lo, self.hi)
            if min(x_ - lo, hi - x_) < 0.5 * DEG
        ]
        return ", ".join(lim) or "none"


def measure(contact, ranges, starts: int, model=None) -> dict:
    r = Reach(contact, ranges, model)

    def facing_ok(x):
        r.set(x)
        p, ang = r.gap()
        _, other = r.depths(hand_free=True)
        if np.linalg.norm(p) > 0.5e-3 or other > 0.05e-3 or r.elbow_drop() < 0.019:
            return None
        return ang

    def touching_ok(x):
        r.set(x)
        p, _ = r.gap()
        pair, other = r.depths(hand_free=False)
        if pair > cn.CONTACT_ALLOWANCE + 0.05e-3 or other > 0.05e-3:
            return None
        return float(np.linalg.norm(p))

    out = {}
    x = r.search(r.facing_rows, starts, facing_ok)
    first = () if x is None else (x,)
    if x is not None:
        r.set(x)
        out["facing_deg"] = r.gap()[1] / DEG
        out["facing_limits"] = r.at_limits(x)
        out["elbow_below_shoulder_mm"] = r.elbow_drop() * 1e3
    x = r.search(r.touching_rows, starts, touching_ok, first)
    if x is not None:
        r.set(x)
        p, ang = r.gap()
        out["touching_mm"] = float(np.linalg.norm(p)) * 1e3
        out["touching_deg"] = ang / DEG
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--contact", default="fist-stomach", choices=[c[0] for c in CONTACTS])
    ap.add_argument("--starts", type=int, default=40, help="random starts per search")
    ap.add_argument("--at", help="another target site for the contact (e.g. @AB, @AB(w))")
    ap.add_argument("--model", type=Path, help="an MJCF signer (default the bundled one)")
    ap.add_argument(
        "--range",
        action="append",
        default=[],
        metavar="JOINT:LO:HI",
        help="a joint's range in degrees (repeatable); default: the documented settings",
    )
    args = ap.parse_args(argv)
    contact = next(c for c in CONTACTS if c[0] == args.contact)
    if args.at:
        contact = (*contact[:5], args.at)
    if args.range:
        ranges = {}
        for r in args.range:
            j, lo, hi = r.split(":")
            ranges[j] = (float(lo), float(hi))
        settings = ((", ".join(args.range), ranges),)
    else:
        settings = SETTINGS
    print(f"{contact[0]}: {contact[4]} at {contact[5]}, right-handed")
    print(
        "| ranges | facing: least angle deg | joints at a limit | elbow below shoulder mm "
        "| touching: least distance mm | angle there deg |"
    )
    print("| --- | --- | --- | --- | --- | --- |")
    for label, ranges in settings:
        o = measure(contact, ranges, args.starts, args.model)
        f = (
            f"{o['facing_deg']:.1f} | {o['facing_limits']} | {o['elbow_below_shoulder_mm']:.0f}"
            if "facing_deg" in o
            else "none found | | "
        )
        t = (
            f"{o['touching_mm']:.2f} | {o['touching_deg']:.1f}"
            if "touching_mm" in o
            else "none found | "
        )
        print(f"| {label} | {f} | {t} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
