"""Rollout records: constraint traces against the geometry, site positions, stats."""

from __future__ import annotations

import numpy as np
import pytest
from scores import cstr, envelope, sync

from azee_mj import ik
from azee_mj.ikadapter import IKAdapter
from azee_mj.motion import Mode, Motion
from azee_mj.rollout import ResidualTable, constraint_traces, site_positions, solve_stats
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


def test_a_residual_table_names_the_frames_out_of_tolerance_and_measures_changes(schedule, solver):
    """The frames the realizer solves again are those its own check finds
    (``Motion.misses``), and the traces after it are those measured afresh."""
    q = _frames(solver)
    times = np.arange(len(q)) / 50.0
    _, c, place, _ = ResidualTable(schedule, q, 50.0).items[0]
    q[[6, 10]] = solver.solve(ik.IKProblem((place,)), solver.natural).qpos  # two frames meet it
    table = ResidualTable(schedule, q, 50.0)
    (trace,) = table.traces()
    far = [f for f in range(5, 15) if not trace.active[f - 5] <= trace.tol]
    assert list(table.misses()) == far == [5, 7, 8, 9, 11, 12, 13, 14]
    tracks = schedule.comp.tracks_of(c)
    assert all(m == [(place, tracks)] for m in table.misses().values())
    check = Motion(IKAdapter(schedule), Mode.MULTITRACK, 50.0).misses(q, times)
    assert table.misses() == check
    q[[7, 9]] = solver.natural  # two frames moved: measured again only once said
    table.update(q, [7, 9])
    fresh = ResidualTable(schedule, q, 50.0)
    np.testing.assert_array_equal(table.values[0], fresh.values[0])
    assert table.misses() == fresh.misses()
    (again,) = constraint_traces(schedule, q, np.arange(len(q)) / 50.0, 50.0)
    np.testing.assert_array_equal(again.active, table.traces()[0].active)


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
