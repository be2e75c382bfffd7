"""Every bundled example score realizes within tolerance and without penetration.

Realized at 25 fps to keep the suite fast. A test marked ``xfail(strict=True)`` fails
because of a known realizer problem named in its reason (see examples/README.md); it
turns into an error as soon as the realizer is fixed, so the mark must then be removed.
"""

from __future__ import annotations

import pathlib
import subprocess
import sys

import pytest

from azee_mj import ik
from azee_mj.check import check_poses
from azee_mj.model import load_model
from azee_mj.timeline import contact_pairs, realize

EXAMPLES = pathlib.Path(__file__).resolve().parent.parent / "examples"
NAMES = sorted(p.stem for p in EXAMPLES.glob("*.json"))
FPS = 25.0

#: Examples that fail because of a realizer problem (exact reasons; see examples/README.md).
KNOWN = {
    "armoire": "solver: HANDS_CONTACT (index tips touching, flat hands, palms down) stops "
    "1.15 mm short: the longer middle fingers must pass each other and the solve ends in a "
    "local minimum",
    "nicht-sondern": "solver: the same HANDS_CONTACT local minimum in its wardrobe part "
    "(3 mm, and PALMS_DOWN 2.5 deg in the same posture)",
}


@pytest.fixture(scope="module")
def model():
    return load_model()


def _cases():
    for n in NAMES:
        marks = [pytest.mark.xfail(strict=True, reason=KNOWN[n])] if n in KNOWN else []
        yield pytest.param(n, marks=marks, id=n)


def test_examples_exist():
    assert {"arbre", "armoire", "nicht-sondern", "bien", "info-about"} <= set(NAMES)
    assert len(NAMES) >= 7


@pytest.mark.parametrize("name", list(_cases()))
def test_example_realizes_within_tolerance(name, model):
    # A fresh solver per example: a Solver reused across realize() calls carries state from
    # one score to the next (pointing.json realized after armoire.json on the same solver
    # misses IX_R by 52 mm; alone it is within tolerance), a realizer problem of its own.
    path = EXAMPLES / f"{name}.json"
    rollout = realize(str(path), fps=FPS, solver=ik.Solver())
    bad = [f"{t.block}#{t.index} {t.kind} worst {t.worst:.4g} {t.unit} > tol {t.tol:.4g}"
           for t in rollout.traces if not t.ok]  # fmt: skip
    assert all(t.ok for t in rollout.traces), "; ".join(bad)
    report = check_poses(model, rollout.qpos, allowed=contact_pairs(str(path), rollout.time))
    assert not report.penetrations, [
        (round(p.frame / FPS, 3), p.geom1, p.geom2, round(p.depth * 1000, 2))
        for p in report.penetrations[:5]
    ]


@pytest.mark.parametrize("name", NAMES)
def test_cli_realize_exits_zero(name, tmp_path):
    out = tmp_path / f"{name}.npz"
    cmd = [sys.executable, "-m", "azee_mj.cli", "realize", str(EXAMPLES / f"{name}.json"),
           "-o", str(out), "--fps", str(FPS), "--report", str(tmp_path / "r.json")]  # fmt: skip
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert out.exists()
