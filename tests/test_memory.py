"""Nothing a realization keeps grows with the score but what its frames need (issue 25):
solver plans are freed, the adapter keeps what each solve took and not its result."""

from __future__ import annotations

import gc
import subprocess
import sys
import weakref
from pathlib import Path

from azee_mj import constraints as cn
from azee_mj import ik
from azee_mj import kinematics as kin
from azee_mj.ikadapter import IKAdapter, Solved
from azee_mj.schedule import Schedule
from azee_mj.score import load_score
from azee_mj.sites import DEFAULT_MAP

DATA = Path(__file__).parent / "data"
EXAMPLES = Path(__file__).parent.parent / "examples"
REACH = (cn.Place("I_TIP_R", kin.Const((0.3, -0.1, 0.3))),)
ARM = tuple(DEFAULT_MAP.tracks["arm_R"])


def _plans() -> int:
    gc.collect()
    return sum(isinstance(o, ik.Plan) for o in gc.get_objects())


def test_a_plan_is_freed_once_unused(solver):
    problem = ik.IKProblem(REACH, ARM)
    plan = solver.plan(problem)
    gone = weakref.ref(plan)
    del plan
    gc.collect()  # a Plan and its compiled core refer to each other: a cycle
    assert gone() is None
    before = _plans()
    for _ in range(5):
        assert solver.solve(problem).qpos.shape == (solver.model.nq,)
    assert _plans() == before


def test_the_adapter_keeps_what_each_solve_took(solver):
    adapter = IKAdapter(Schedule(load_score(DATA / "good.json"), solver))
    res = adapter.solve(REACH, ARM, solver.natural.copy(), 0.0)
    assert adapter.results == [Solved(res.iterations, res.converged, res.time)]


def test_realizing_imports_no_scipy():
    # scipy.signal and scipy.interpolate cost a process 50 to 70 MB each: a realization (a
    # sign with a bent arm, paced movements) must not pull them in
    code = (
        "import sys; from azee_mj.timeline import realize; "
        f"realize({str(EXAMPLES / 'info-about.json')!r}); "
        "print(sorted(m for m in sys.modules if m.startswith('scipy.')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
