"""Every bundled example score realizes within tolerance and without penetration.

Realized at 25 fps to keep the suite fast.
"""

from __future__ import annotations

import pathlib
import subprocess
import sys

import numpy as np
import pytest

from azee_mj.check import check_poses
from azee_mj.schedule import contact_pairs, make_solver
from azee_mj.timeline import realize

EXAMPLES = pathlib.Path(__file__).resolve().parent.parent / "examples"
NAMES = sorted(p.stem for p in EXAMPLES.glob("*.json"))
FPS = 25.0


def test_examples_exist():
    assert {"arbre", "armoire", "nicht-sondern", "bien", "info-about"} <= set(NAMES)
    assert len(NAMES) >= 7


@pytest.mark.parametrize("name", NAMES)
def test_example_realizes_within_tolerance(name, model):
    path = EXAMPLES / f"{name}.json"
    rollout = realize(str(path), fps=FPS, solver=make_solver())
    bad = [
        f"{t.block}#{t.index} {t.kind} worst {t.worst:.4g} {t.unit} > tol {t.tol:.4g}"
        for t in rollout.traces
        if not t.ok
    ]
    assert all(t.ok for t in rollout.traces), "; ".join(bad)
    report = check_poses(model, rollout.qpos, allowed=contact_pairs(str(path), rollout.time))
    assert not report.penetrations, [
        (round(p.frame / FPS, 3), p.geom1, p.geom2, round(p.depth * 1000, 2))
        for p in report.penetrations[:5]
    ]


def test_a_reused_solver_gives_the_same_motion():
    # A solve depends only on its problem and start, not on what the solver did before.
    fresh = realize(str(EXAMPLES / "pointing.json"), fps=FPS, solver=make_solver())
    solver = make_solver()
    realize(str(EXAMPLES / "armoire.json"), fps=FPS, solver=solver)
    again = realize(str(EXAMPLES / "pointing.json"), fps=FPS, solver=solver)
    np.testing.assert_array_equal(again.qpos, fresh.qpos)


@pytest.mark.parametrize("name", NAMES)
def test_cli_realize_exits_zero(name, tmp_path):
    out = tmp_path / f"{name}.npz"
    cmd = [
        sys.executable,
        "-m",
        "azee_mj.cli",
        "realize",
        str(EXAMPLES / f"{name}.json"),
        "-o",
        str(out),
        "--fps",
        str(FPS),
        "--report",
        str(tmp_path / "r.json"),
    ]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600, check=False)
    assert proc.returncode == 0, proc.stderr
    assert out.exists()
