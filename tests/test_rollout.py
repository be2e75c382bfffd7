"""Rollout records: constraint traces against the geometry, site positions, stats."""

from __future__ import annotations

import numpy as np
import pytest
from scores import cstr, envelope, sync

from azee_mj import ik
from azee_mj.rollout import constraint_traces, site_positions, solve_stats
from azee_mj.schedule import Schedule
from azee_mj.score import load_score
from azee_mj.sites import DEFAULT_MAP

TARGET = [0.3, -0.15, 1.2]


@pytest.fixture(scope="module")
def schedule(solver) -> Schedule:
    tip = {"type": "place", "site": "@I_TIP(s)", "at": TARGET}
    flat = {"type": "morph", "id": "flat", "side": "s", "weight": 1.0}
    score = load_score(envelope(sync("S", 0.4, cstr("R", 0.1, 0.3, tip, flat), start=0.0)))
    return Schedule(score, solver)


def _frames(solver, n=20, seed=0):
    rng = np.random.default_rng(seed)
    return solver.natural + 0.05 * rng.normal(size=(n, solver.model.nq))


def test_traces_measure_each_placement_over_its_blocks_frames(schedule, solver):
    q = _frames(solver)
    times = np.arange(len(q)) / 50.0
    (trace,) = constraint_traces(schedule, q, times, 50.0, {"S.R#1": "out of reach"})
    assert (trace.block, trace.index, trace.kind, trace.unit) == ("S.R", 1, "place", "m")
    assert (trace.first, len(trace.active), trace.frames) == (5, 10, 20)
    sid = solver.site_id("I_TIP_R")
    want = [np.linalg.norm(solver.at(q[f]).d.site_xpos[sid] - TARGET) for f in range(5, 15)]
    np.testing.assert_allclose(trace.active, want, atol=1e-12)
    assert np.isnan(trace.values[:5]).all() and np.isnan(trace.values[15:]).all()
    assert trace.worst == pytest.approx(max(want)) and not trace.ok
    assert trace.reason == "out of reach" and "out of reach" in trace.describe()


def test_site_positions_are_the_sites_of_each_frame(solver):
    q = _frames(solver, 3, seed=1)
    pos = site_positions(solver, DEFAULT_MAP, q)
    assert pos.shape == (3, len(DEFAULT_MAP.sites), 3)
    names = list(DEFAULT_MAP.sites.values())
    for f in range(3):
        d = solver.at(q[f]).d
        for i in (0, len(names) // 2, len(names) - 1):
            np.testing.assert_array_equal(pos[f, i], d.site_xpos[solver.site_id(names[i])])


def test_solve_stats_add_up_the_results():
    def res(iterations, converged, time):
        return ik.IKResult(np.zeros(1), converged, (), 0.0, iterations, 0, time, np.zeros(0))

    stats = solve_stats([res(3, True, 0.01), res(7, False, 0.02), res(1, True, 0.005)], 2, 1.5)
    assert (stats.problems, stats.key_problems, stats.iterations, stats.not_converged) == (
        3,
        2,
        11,
        1,
    )
    assert stats.solve_time == pytest.approx(0.035) and stats.total_time == 1.5
    np.testing.assert_array_equal(stats.per_problem_iterations, [3, 7, 1])
