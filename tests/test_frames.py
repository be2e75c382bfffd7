"""Frames never whole in memory (issue 25): site positions computed a block at a time, a
rollout written a block at a time and read back lazily, equal to the in-memory arrays."""

from __future__ import annotations

import zipfile
from pathlib import Path

import mujoco
import numpy as np
import pytest

from azee_mj.errors import InputFileError
from azee_mj.files import save_npz
from azee_mj.frames import BLOCK, NpzFrames, SitePositions, nonfinite_frames
from azee_mj.rollout_io import load_rollout, rollout_arrays, save_rollout
from azee_mj.timeline import realize

DATA = Path(__file__).parent / "data"
ROOT = Path(__file__).resolve().parent.parent


def _sites_by_hand(model, qpos, sids) -> np.ndarray:
    d = mujoco.MjData(model)
    out = np.empty((len(qpos), len(sids), 3))
    for f, q in enumerate(qpos):
        d.qpos[:] = q
        mujoco.mj_forward(model, d)
        out[f] = d.site_xpos[sids]
    return out


def test_site_positions_are_forward_kinematics_a_block_at_a_time(model):
    rng = np.random.default_rng(0)
    T = BLOCK + 37  # two blocks, the second short
    lo, hi = model.jnt_range[:, 0], model.jnt_range[:, 1]
    qpos = np.tile(model.qpos0, (T, 1))
    for j in range(model.njnt):
        if model.jnt_limited[j]:
            qpos[:, model.jnt_qposadr[j]] = rng.uniform(lo[j], hi[j], T)
    sids = [0, 3, model.nsite - 1]
    lazy = SitePositions(model, qpos, sids)
    whole = _sites_by_hand(model, qpos, sids)
    assert lazy.shape == whole.shape and len(lazy) == T and lazy.ndim == 3
    assert np.array_equal(np.asarray(lazy), whole)
    assert [(s, len(b)) for s, b in lazy.blocks()] == [(0, BLOCK), (BLOCK, 37)]
    assert np.array_equal(lazy[BLOCK + 5], whole[BLOCK + 5])
    assert np.array_equal(lazy[-1], whole[-1])
    assert np.array_equal(lazy[10 : BLOCK + 20], whole[10 : BLOCK + 20])
    assert np.array_equal(lazy[::97, 1], whole[::97, 1])
    assert np.array_equal(lazy[7, 2], whole[7, 2])
    assert np.array_equal(lazy - 2 * lazy, -whole) and np.abs(lazy).max() == np.abs(whole).max()
    with pytest.raises(IndexError):
        lazy[T]


def test_nonfinite_frames_are_found_a_block_at_a_time_as_in_the_whole_array(model):
    qpos = np.tile(model.qpos0, (2 * BLOCK + 9, 1))
    bad = [3, BLOCK, BLOCK + 1, 2 * BLOCK + 8]
    qpos[bad] = np.nan
    lazy = SitePositions(model, qpos, [0, model.nsite - 1])
    whole = np.asarray(lazy)
    assert (~np.isfinite(whole[bad])).any(axis=(1, 2)).all()
    assert np.isfinite(np.delete(whole, bad, 0)).all()
    assert nonfinite_frames(lazy).tolist() == bad
    assert nonfinite_frames(whole).tolist() == bad
    assert nonfinite_frames(np.zeros((5, 2))).tolist() == []


def test_a_streamed_rollout_reads_back_equal_to_the_in_memory_one(tmp_path):
    rollout = realize(ROOT / "examples" / "info-about.json", fps=50)
    assert isinstance(rollout.site_pos, SitePositions)  # nothing of it computed yet
    arrays = rollout_arrays(rollout)
    whole = {k: np.asarray(v) for k, v in arrays.items()}
    streamed, in_memory = tmp_path / "streamed.npz", tmp_path / "whole.npz"
    save_rollout(streamed, rollout)
    save_npz(in_memory, whole)
    assert streamed.read_bytes() == in_memory.read_bytes()
    back = load_rollout(streamed, rollout.qpos.shape[1])
    assert isinstance(back.site_pos, NpzFrames)
    assert np.array_equal(np.asarray(back.site_pos), whole["site_pos"])
    for k, v in rollout_arrays(back).items():
        if k != "stats":  # solve times are not stored
            assert np.array_equal(np.asarray(v), whole[k]), k
    # Read back a frame at a time, in order and out of it.
    for f in (0, 1, 60, len(back.time) - 1, 3):
        assert np.array_equal(back.site_pos[f], whole["site_pos"][f])
    with np.load(streamed) as z:  # still an ordinary .npz
        assert np.array_equal(z["site_pos"], whole["site_pos"])


def test_a_rollout_whose_site_positions_are_cut_short_is_refused(tmp_path, model):
    rollout = realize(DATA / "good.json", fps=25)
    arrays = {k: np.asarray(v) for k, v in rollout_arrays(rollout).items()}
    good = tmp_path / "good.npz"
    save_npz(good, arrays)
    # the member's data cut after its header and two frames, its sizes left as they were
    cut = tmp_path / "cut.npz"
    with zipfile.ZipFile(good) as src, zipfile.ZipFile(cut, "w") as dst:
        for info in src.infolist():
            data = src.read(info)
            if info.filename == "site_pos.npy":
                data = data[: len(data) - arrays["site_pos"][2:].nbytes]
            dst.writestr(info.filename, data)
    with pytest.raises(InputFileError) as e:
        load_rollout(cut, model.nq)
    assert str(e.value).startswith(f"{cut}: array 'site_pos.npy' announces shape ")
    nan = dict(arrays, site_pos=arrays["site_pos"].copy())
    nan["site_pos"][5:, 0, 1] = np.nan
    bad = tmp_path / "nan.npz"
    save_npz(bad, nan)
    with pytest.raises(InputFileError) as e:
        load_rollout(bad, model.nq)
    frames = len(arrays["time"])
    assert (
        str(e.value) == f"{bad}: site_pos is not finite at {frames - 5} frame(s), first at frame 5"
    )
