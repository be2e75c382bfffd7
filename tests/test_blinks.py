"""Automatic blinks: seeded, at a natural rate, never over a constrained eyelid, and the lids
shut and open again on the real model."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scores import cstr, envelope, sync

from azee_mj import blinks
from azee_mj.cli import main
from azee_mj.schedule import make_solver
from azee_mj.score import load_score
from azee_mj.sites import DEFAULT_MAP
from azee_mj.timeline import realize


def _score(duration: float, children=()) -> dict:
    return envelope(sync("S", duration, *children))


def _morph(name, start, end, mid, weight=1.0):
    return cstr(name, start, end, {"type": "morph", "id": mid, "weight": weight})


def _blink_blocks(score):
    return [b for b in score.root.children if b.name.startswith("BLINK")]


def test_same_seed_same_blinks_and_a_natural_rate():
    a, b = blinks.blink_times(600.0, 7), blinks.blink_times(600.0, 7)
    assert a == b and a != blinks.blink_times(600.0, 8)
    per_min = len(a) / 10.0
    assert 0.8 * blinks.RATE_PER_MIN < per_min < 1.2 * blinks.RATE_PER_MIN
    assert min(np.diff(a)) >= blinks.MIN_INTERVAL
    assert len(blinks.blink_times(600.0, 7, rate=6.0)) < len(a) / 2


def test_no_blink_over_a_block_that_constrains_an_eyelid():
    held = {"name": "KEEP", "kind": "hold", "start": 12.0, "end": 16.0, "of": "WIDE2"}
    score = load_score(
        _score(
            30.0,
            [
                _morph("WIDE", 3.0, 9.0, "eyes_wide"),
                _morph("SQUINT", 20.0, 24.0, "eyeSquint"),
                _morph("BROWS", 0.0, 30.0, "brows_raise"),  # no eyelid: blinks go over it
                _morph("WIDE2", 10.0, 12.0, "eyeWideLeft"),
                held,
            ],
        )
    )
    busy = blinks.eyelid_intervals(score)
    assert busy == [(3.0, 9.0), (10.0, 12.0), (12.0, 16.0), (20.0, 24.0)]
    for seed in range(20):
        out = blinks.add_blinks(score, seed)
        for b in _blink_blocks(out):
            for s, e in busy:
                assert b.end + blinks.MARGIN <= s + 1e-9 or b.start - blinks.MARGIN >= e - 1e-9
    assert any(_blink_blocks(blinks.add_blinks(score, seed)) for seed in range(20))


def test_blinks_are_three_blocks_named_apart_from_the_score():
    score = load_score(_score(20.0, [_morph("BLINK0", 0.0, 0.1, "smile")]))
    out = blinks.add_blinks(score, 1)
    names = [b.name for b in _blink_blocks(out)]
    assert names.count("BLINK0") == 1  # the score's own block, kept
    assert len(names) > 3 and (len(names) - 1) % 3 == 0
    shut = [b for b in _blink_blocks(out) if b.name[5:].isdigit() and b.name != "BLINK0"]
    for b in shut:
        assert b.duration == pytest.approx(blinks.SHUT)
        assert b.constraints[0].id == blinks.MORPH and b.constraints[0].weight == 1.0
        assert out.block(f"S.{b.name}_OPEN").end == pytest.approx(b.start)
        assert out.block(f"S.{b.name}_REOPEN").start == pytest.approx(b.end)
    short = load_score(_score(0.5))
    assert blinks.add_blinks(short, 1) is short  # no room for a blink


def test_the_lids_shut_and_open_again_on_the_model():
    solver = make_solver()
    score = blinks.add_blinks(load_score(_score(5.0)), 2)
    times = [b.start for b in _blink_blocks(score) if b.name[5:].isdigit()]
    assert times
    r = realize(score, fps=50, solver=solver)
    lid = solver.model.jnt_qposadr[solver.joint_id("lid_R_close")]
    shut = DEFAULT_MAP.morphs[blinks.MORPH]
    closed = shut.joint_changes("R")["lid_R_close"]
    for t in times:
        f = round(t * 50)
        assert r.qpos[f, lid] == pytest.approx(closed, abs=0.02)
        after = round((t + blinks.SHUT + blinks.REOPEN) * 50) - 1
        assert abs(r.qpos[after, lid]) < 0.02
        # shut and open again within 0.4 s
        assert np.all(np.abs(r.qpos[f - 12 : f - 9, lid]) < 0.05)


def test_cli_blinks(tmp_path, capsys):
    src = tmp_path / "s.json"
    src.write_text(json.dumps(_score(10.0)))
    out = tmp_path / "r.npz"
    report = tmp_path / "r.json"
    assert (
        main(["realize", str(src), "-o", str(out), "--blinks", "2", "--report", str(report)]) == 0
    )
    face = json.loads(report.read_text())["schedule"]["face"]
    expected = blinks.add_blinks(load_score(_score(10.0)), 2)
    assert len(face) == len(_blink_blocks(expected)) > 0
    capsys.readouterr()
    one = tmp_path / "one.json"
    one.write_text(json.dumps({**_score(4.0), "root": _morph("K", 0, 4.0, "smile")}, indent=1))
    assert main(["realize", str(one), "-o", str(tmp_path / "x.npz"), "--blinks", "1"]) == 2
    err = capsys.readouterr().err
    assert err == (
        "azee-mj: error: --blinks: the root block 'K' is a cstr block; automatic blinks "
        "need a sync root to add their blocks to\n"
    )
    assert not (tmp_path / "x.npz").exists()
    assert main(["realize", str(src), "-o", str(out), "--blinks", "1", "--blink-rate", "0"]) == 2
    assert capsys.readouterr().err == (
        "azee-mj: error: --blink-rate: the blink rate must be positive, got 0.0\n"
    )
