"""``bench/reach_bound.py``: the contact's problem it poses, and its best posture measured
against the geometry (the placed sites' distance at the posture it returns)."""

import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))

import natural as nat
import reach_bound as rb

from azee_mj.ergonomics import ergonomics
from azee_mj.schedule import make_solver

CONTACTS = {c[0]: c for c in nat.CONTACTS + nat.HELD_OUT}


def test_site_names_resolve_the_strong_side():
    assert nat.site_name("@PA(s)") == "PA_R"
    assert nat.site_name("@PA(w)") == "PA_L"
    assert nat.site_name("@M_BACK(s,2)") == "M_BACK_R_2"
    assert nat.site_name("@NK") == "NK"


@pytest.mark.parametrize(
    "name, arms", [("index-pad-throat", {"R"}), ("two-palms-belly", {"R", "L"})]
)
def test_problem_frees_the_placing_arms_and_holds_the_trunk_and_head(name, arms):
    solver = make_solver()
    prob, _, pairs = rb.problem(CONTACTS[name], solver.model)
    assert len(prob.constraints) == len(pairs) == len(nat.places(CONTACTS[name]))
    sides = {s for j in prob.free_joints for s in ("L", "R") if s in j.split("_")}
    assert sides == arms
    assert not [j for j in prob.free_joints if j.startswith(rb.HELD)]
    assert {"f_arm_R_flex", "palm_R_dev", "clav_R_elev"} <= set(prob.free_joints)


def test_best_natural_posture_is_measured_on_the_geometry():
    solver = make_solver()
    m = solver.model
    rec, q = rb.bound(CONTACTS["index-tip-throat"], solver, starts=40)
    assert q is not None and rec["met"] >= 1
    d = mujoco.MjData(m)
    d.qpos[:] = q
    mujoco.mj_kinematics(m, d)
    a, b = (d.site(nat_site).xpos for nat_site in ("I_TIP_R", "NK"))
    assert np.linalg.norm(a - b) * 1e3 == pytest.approx(rec["best_natural_mm"], abs=1e-9)
    assert rec["best_natural_mm"] <= 1.0
    e = ergonomics(m, q)
    assert e.elbows_ok() and e.rula.score <= 4
    assert e.trunk_angle == pytest.approx(0.0, abs=1e-9)
