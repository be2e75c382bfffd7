"""Offscreen rendering: antialiasing by supersampling, and video frames rendered by several
processes (the same frames, in order; errors reach the caller; the output whole or absent)."""

from __future__ import annotations

import itertools
import multiprocessing
import os
from pathlib import Path

import mujoco
import numpy as np
import pytest

from azee_mj import markers as mk
from azee_mj import render as rd
from azee_mj import score as sc
from azee_mj.cli import main
from azee_mj.errors import AzeeError

GOOD = Path(__file__).parent / "data" / "good.json"
SMALL = (160, 120)


@pytest.fixture(scope="module")
def clip() -> mk.Clip:
    from azee_mj.timeline import realize

    return mk.Clip.from_rollout(realize(GOOD), sc.load_score(GOOD), "good")


def _workers_alive() -> list[str]:
    return [p.name for p in multiprocessing.active_children() if p.name.startswith("azee-mj")]


@pytest.mark.extra("render")
def test_supersampling_is_as_close_to_the_reference_as_multisampling(clip, gl):
    """Against the same scene rendered 4 times larger with 4x multisampling and averaged
    down (the reference), the supersampled frame is closer on average than the 4x
    multisampled one and than one without antialiasing, from every camera."""
    from PIL import Image

    w, h = 320, 240
    f = clip.frame_at(0.6)
    big = rd.scene_model(4 * w, 4 * h)
    d = mujoco.MjData(big)
    d.qpos[:] = clip.qpos[f]
    mujoco.mj_forward(big, d)
    with (
        mujoco.Renderer(big, height=4 * h, width=4 * w) as ref,
        mujoco.Renderer(rd.scene_model(w, h), height=h, width=w) as msaa,
        rd.FrameRenderer(clip, size=(w, h)) as ss,
        rd.FrameRenderer(clip, size=(w, h), antialias=False) as none,
    ):
        assert ss.render_size == (480, 360) and none.render_size == (w, h)
        for r in (ref, msaa):
            r.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
        # the scene's cameras (at the face close-up, 1.5x supersampling is not as close as
        # 4x multisampling: 0.91 against 0.68 levels, docs/rendering.md)
        for cam in (c for c in rd.CAMERAS if c not in rd.CLOSE_UPS):
            ss.cam = none.cam = rd.camera_id(ss.model, cam)
            ref.update_scene(d, camera=cam)
            msaa.update_scene(d, camera=cam)
            want = np.asarray(Image.fromarray(ref.render()).resize((w, h), Image.BOX), float)
            err = {
                k: np.abs(img - want).mean()
                for k, img in [
                    ("ss", ss.render(clip.qpos[f])),
                    ("msaa", msaa.render()),
                    ("none", none.render(clip.qpos[f])),
                ]
            }
            assert err["ss"] < err["msaa"] < err["none"], (cam, err)


@pytest.mark.parametrize("antialias", [True, False])
def test_a_renderers_first_frame_is_its_later_frames(clip, gl, antialias):
    # Software GL drew a context's first frame one pixel off at 480 x 360 (SMALL
    # supersampled), so a frame depended on which process drew it first.
    q = rd.resample(clip, 100.0)[1][0]
    with rd.FrameRenderer(size=SMALL, antialias=antialias) as fr:
        first, second = (fr.draw(q).copy() for _ in range(2))
    np.testing.assert_array_equal(first, second)


@pytest.mark.parametrize("antialias", [True, False])
def test_frames_are_the_same_from_one_two_and_three_processes(clip, gl, antialias):
    qs = rd.resample(clip, 100.0)[1]
    deco = rd.Decorations(clip, targets=True)
    items = [deco(clip.frame_at(k / 100.0)) for k in range(len(qs))]
    assert any(items)
    one = list(rd.render_frames(qs, items, size=SMALL, antialias=antialias, workers=1))
    shape = (*rd.render_size(SMALL, antialias)[::-1], 3)
    assert len(one) == len(qs) and all(img.shape == shape for img in one)
    # The frames change over the clip, so a frame out of order would show.
    assert sum(not np.array_equal(a, b) for a, b in itertools.pairwise(one)) > 20
    for workers in (2, 3):
        many = list(rd.render_frames(qs, items, size=SMALL, antialias=antialias, workers=workers))
        assert len(many) == len(one)
        assert all(np.array_equal(a, b) for a, b in zip(one, many)), workers
    assert _workers_alive() == []


@pytest.mark.extra("render")
def test_an_mp4_from_two_processes_is_the_mp4_from_one(clip, gl, tmp_path):
    one, two = tmp_path / "one.mp4", tmp_path / "two.mp4"
    rd.render(clip, one, size=SMALL, fps=100, workers=1)
    rd.render(clip, two, size=SMALL, fps=100, workers=2)
    assert one.read_bytes() == two.read_bytes()
    assert sorted(f.name for f in tmp_path.iterdir()) == ["one.mp4", "two.mp4"]


def test_a_failing_frame_leaves_no_output_and_no_worker(clip, gl, tmp_path):
    bad = mk.Clip(clip.time, np.zeros((len(clip.time), 3)), clip.fps, None, None, "bad")
    out = tmp_path / "bad.mp4"
    with pytest.raises((AzeeError, ValueError)):
        rd.render(bad, out, size=SMALL, fps=100, workers=2)
    assert list(tmp_path.iterdir()) == []
    assert _workers_alive() == []


def test_a_worker_error_reaches_the_caller(gl, monkeypatch):
    """A worker that cannot render reports why; the caller raises it and stops the rest.
    (The workers are told a GL backend that does not exist; this process renders on.)"""
    monkeypatch.setattr(rd, "gl_backend", lambda probe=None: "nope")
    qs = np.tile(rd.scene_model().qpos0, (3000, 1))
    with pytest.raises(AzeeError, match="MUJOCO_GL='nope' is not a backend; use egl"):
        for _ in rd.render_frames(qs, size=SMALL, workers=2):
            pass
    assert _workers_alive() == []


def test_stopping_early_stops_the_workers(clip, gl):
    qs = rd.resample(clip, 200.0)[1]
    frames = rd.render_frames(qs, size=SMALL, workers=2)
    next(frames)
    frames.close()
    assert _workers_alive() == []


def test_worker_count(monkeypatch):
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1}, raising=False)
    assert rd.video_workers(rd.MIN_WORKER_FRAMES - 1) == 1
    assert rd.video_workers(rd.MIN_WORKER_FRAMES) == 2
    assert rd.video_workers(500, 3) == 3
    assert rd.video_workers(2, 3) == 2
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0}, raising=False)
    assert rd.video_workers(500) == 1


@pytest.mark.extra("render")
def test_cli_render_jobs(gl, tmp_path, capsys):
    out = tmp_path / "g.mp4"
    assert main(["render", str(GOOD), "-o", str(out), "--size", "160x120", "--jobs", "2"]) == 0
    assert out.stat().st_size > 0
    assert main(["render", str(GOOD), "-o", str(tmp_path / "h.mp4"), "--jobs", "0"]) == 2
    err = capsys.readouterr().err
    assert err.endswith("azee-mj: error: --jobs: must be at least 1, got 0\n")
    assert sorted(f.name for f in tmp_path.iterdir()) == ["g.mp4"]
