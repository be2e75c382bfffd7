"""Viewer decorations (no window), offscreen rendering (pixels, frame counts) and the real
viewer under Xvfb."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import mujoco
import numpy as np
import pytest

from azee_mj import cli
from azee_mj import markers as mk
from azee_mj import render as rd
from azee_mj import score as sc
from azee_mj import viewer as v
from azee_mj.cli import main
from azee_mj.errors import AzeeError

GOOD = Path(__file__).parent / "data" / "good.json"
SMALL = (160, 120)


@pytest.fixture(scope="module")
def rollout():
    from azee_mj.timeline import realize

    return realize(GOOD)


@pytest.fixture(scope="module")
def clip(rollout) -> mk.Clip:
    return mk.Clip.from_rollout(rollout, sc.load_score(GOOD), "good")


# ---------------------------------------------------------------------------------------
# Decorations, without a window
# ---------------------------------------------------------------------------------------


def _expected_targets(clip: mk.Clip, frame: int):
    """Targets of the K1 block evaluated directly from the score's expressions."""
    from azee_mj.kinematics import Kinematics, compile_point, compile_vector
    from azee_mj.sites import DEFAULT_MAP

    m = rd.scene_model()
    d = mujoco.MjData(m)
    d.qpos[:] = clip.qpos[frame]
    mujoco.mj_kinematics(m, d)

    k1 = clip.score.block("GOOD.K1")
    place, orient = k1.constraints
    kin = Kinematics(m, d)
    p = kin.value(compile_point(place.at, DEFAULT_MAP))
    vec = kin.value(compile_vector(orient.vector, DEFAULT_MAP))
    body = orient.bone.model_body(DEFAULT_MAP)
    origin = d.xpos[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, body)].copy()
    return p, origin, vec / np.linalg.norm(vec)


def test_markers_inside_k1_are_the_targets(clip):
    frame = clip.frame_at(
        clip.score_start + 0.2
    )  # inside K1 [0, 0.4); PERM (morphs only) draws nothing
    m = rd.scene_model()
    d = mujoco.MjData(m)
    ms = mk.markers(m, d, clip, frame, mk.Targets(clip.score))
    targets = [x for x in ms if x.kind != "contact"]
    assert [(x.kind, x.label) for x in targets] == [("sphere", "GOOD.K1#1"), ("arrow", "GOOD.K1#2")]
    p, origin, direction = _expected_targets(clip, frame)
    np.testing.assert_allclose(targets[0].pos, p, atol=1e-9)
    np.testing.assert_allclose(targets[1].pos, origin, atol=1e-9)
    np.testing.assert_allclose(
        targets[1].end - targets[1].pos, mk.ARROW_LENGTH * direction, atol=1e-9
    )


def test_marker_colours_follow_the_residual_traces(clip, rollout):
    rollout_traces = {(t.block, t.index): t for t in rollout.traces}
    m = rd.scene_model()
    d = mujoco.MjData(m)
    tg = mk.Targets(clip.score)
    for frame in (clip.frame_at(clip.score_start + 0.1), clip.frame_at(clip.score_start + 1.0)):
        for x in mk.markers(m, d, clip, frame, tg):
            if x.kind == "contact":
                assert x.violated and x.residual > mk.PENETRATION
                continue
            block, index = x.label.split("#")
            tr = rollout_traces[(block, int(index))]
            assert x.residual == pytest.approx(tr.values[frame], abs=1e-9)
            assert x.violated == (tr.values[frame] > tr.tol)


def test_no_targets_without_a_score(clip):
    bare = mk.Clip(clip.time, clip.qpos, clip.fps, {}, None)
    m = rd.scene_model()
    d = mujoco.MjData(m)
    assert all(x.kind == "contact" for x in mk.markers(m, d, bare, 10, None))
    assert rd.key_frames(bare)[0] == ("t = 0.00 s", 0)


def test_add_markers_builds_geoms(clip):
    m = rd.scene_model()
    d = mujoco.MjData(m)
    ms = mk.markers(m, d, clip, clip.frame_at(clip.score_start + 0.2), mk.Targets(clip.score))
    scn = mujoco.MjvScene(m, maxgeom=50)
    assert mk.add_markers(scn, ms) == len(ms) == scn.ngeom
    g = scn.geoms[0]
    assert g.type == mujoco.mjtGeom.mjGEOM_SPHERE
    np.testing.assert_allclose(g.pos, ms[0].pos, atol=1e-6)
    assert scn.geoms[1].type == mujoco.mjtGeom.mjGEOM_ARROW
    full = mujoco.MjvScene(m, maxgeom=1)
    assert mk.add_markers(full, ms) == 1  # never overflows the scene


def test_overlay_text_names_time_and_active_blocks(clip):
    left, right = mk.frame_text(clip, clip.frame_at(clip.score_start + 0.2))
    rows = dict(zip(left.split("\n"), right.split("\n")))
    assert rows["time"].startswith(f"{clip.score_start + 0.2:.3f}")  # the rollout's clock
    assert rows["arm_R"] == "GOOD.K1"
    assert rows["hand_R"] == "GOOD.PERM"
    assert rows["arm_L"] == "-"


def test_player_keys():
    p = v.Player(10)
    p.key(32)
    assert p.paused
    p.key(262), p.key(262), p.key(263)
    assert p.step == 1
    p.key(265)
    assert p.speed == 2.0
    p.key(264), p.key(45)
    assert p.speed == 0.5
    p.key(67)
    assert p.camera_steps == 1


# ---------------------------------------------------------------------------------------
# Offscreen rendering
# ---------------------------------------------------------------------------------------


def _png(path) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(path).convert("RGB")).astype(float)


@pytest.mark.extra("render")
def test_still_shows_the_signer_and_frames_differ(clip, gl, tmp_path):
    a, b = tmp_path / "a.png", tmp_path / "b.png"
    rd.render(clip, a, time=0.2, size=(320, 240))
    rd.render(clip, b, time=1.0, size=(320, 240))
    ia, ib = _png(a), _png(b)
    assert ia.shape == (240, 320, 3)
    assert ia.std() > 10, "blank image"
    centre = ia[60:180, 120:200]  # the signer's torso, where the front camera looks
    sky = ia[:25, :40]  # background, above the signer's head at the left
    assert np.abs(centre.mean(axis=(0, 1)) - sky.mean(axis=(0, 1))).max() > 20
    assert np.abs(ia - ib).mean() > 0.5, "the hands moved but the frames are equal"
    assert np.abs(ia - ib)[:, :160].sum() > np.abs(ia - ib)[:, 240:].sum()  # signer's right


@pytest.mark.extra("render")
def test_mp4_has_the_expected_frames_and_duration(clip, gl, tmp_path):
    import imageio.v3 as iio

    out = tmp_path / "g.mp4"
    rd.render(clip, out, size=SMALL, fps=25)
    frames = iio.imread(out, plugin="FFMPEG")
    n = int(np.floor(clip.duration * 25 + 1e-9)) + 1
    assert frames.shape == (n, SMALL[1], SMALL[0], 3)
    meta = iio.immeta(out, plugin="FFMPEG")
    assert meta["fps"] == pytest.approx(25)
    assert meta["duration"] == pytest.approx(n / 25, abs=0.05)
    assert np.abs(frames[0].astype(float) - frames[n // 2]).mean() > 0.5


@pytest.mark.extra("render")
def test_software_gl_settings_look_like_the_full_quality_scene(clip, gl):
    """16 x 10 facets and no floor reflection against scene.xml's 28 x 16 facets and
    reflection (both with a 1024 shadow map, both supersampled and scaled down alike): the
    same picture up to a few edge pixels, from every camera. The face close-up keeps every
    facet and draws no shadows (the reference neither); its floor reflection, which the
    renderer never draws, shows below the head (the reference draws none there)."""
    f = clip.frame_at(clip.score_start + 0.6)
    for cam in rd.CAMERAS:
        with rd.FrameRenderer(clip, camera=cam, size=(320, 240)) as fr:
            w, h = fr.render_size
            full = mujoco.MjModel.from_xml_path(str(rd.SCENE_PATH))
            full.vis.quality.shadowsize = rd.SHADOW_SIZE
            full.vis.quality.offsamples = 0
            full.vis.global_.offwidth, full.vis.global_.offheight = w, h
            d = mujoco.MjData(full)
            d.qpos[:] = clip.qpos[f]
            mujoco.mj_forward(full, d)
            with mujoco.Renderer(full, height=h, width=w) as ref:
                close_up = cam in rd.CLOSE_UPS
                ref.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = not close_up
                ref.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = not close_up
                ref.update_scene(d, camera=cam)
                want = rd.downscale(ref.render(), fr.size).astype(float)
                diff = np.abs(want - fr.render(clip.qpos[f]))
                assert diff.mean() < 1.0, cam  # of 255 levels
                assert (diff.max(axis=2) > 32).mean() < 0.01, cam  # under 1 % of the pixels


def test_encoder_writes_every_frame_in_order_and_raises_writer_errors():
    written = []
    with rd.Encoder(lambda a: written.append(int(a[0, 0, 0])), (2, 2, 3), queue=2) as enc:
        for k in range(20):
            buf = enc.buffer()
            buf[:] = k
            enc.put(buf)
    assert written == list(range(20))

    def fail(a):
        raise OSError("disk full")

    with pytest.raises(OSError, match="disk full"), rd.Encoder(fail, (2, 2, 3), queue=2) as enc:
        for _ in range(20):
            enc.put(enc.buffer())

    def broken_close():
        raise BrokenPipeError("the encoder is gone")

    # Stopped from outside (Ctrl-C, SIGTERM, a render error): that error wins over close's.
    with (
        pytest.raises(KeyboardInterrupt),
        rd.Encoder(written.append, (2, 2, 3), close=broken_close) as enc,
    ):
        enc.put(enc.buffer())
        raise KeyboardInterrupt


@pytest.mark.extra("render")
def test_sigterm_while_encoding_an_mp4_exits_143_and_leaves_nothing(rollout, gl, tmp_path):
    from azee_mj.rollout_io import save_rollout

    src = tmp_path / "good.npz"
    save_rollout(src, rollout)
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parent.parent))
    p = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "azee_mj.cli",
            "render",
            str(src),
            "-o",
            str(tmp_path / "o.mp4"),
            "--fps",
            "240",
        ],
        env=env,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 120

    def encoding() -> bool:  # the temporary video has data: frames are going through ffmpeg
        tmp = [f for f in tmp_path.iterdir() if f.name.startswith(".o.mp4.")]
        return any(os.path.getsize(f) > 0 for f in tmp if f.exists())

    while not encoding() and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    assert p.poll() is None, "rendering ended before it could be stopped"
    p.send_signal(signal.SIGTERM)
    _, err = p.communicate(timeout=60)
    assert (p.returncode, err) == (143, "azee-mj: terminated\n")
    assert [f.name for f in tmp_path.iterdir()] == ["good.npz"]


@pytest.mark.extra("render")
def test_mp4_frames_are_the_rendered_frames(clip, gl, tmp_path):
    import imageio.v3 as iio

    out = tmp_path / "g.mp4"
    rd.render(clip, out, size=SMALL)
    video = iio.imread(out, plugin="FFMPEG").astype(float)
    with rd.FrameRenderer(clip, size=SMALL) as fr:
        for k in (0, len(clip.qpos) // 2, len(clip.qpos) - 1):
            assert np.abs(video[k] - fr.render(clip.qpos[k])).mean() < 3.0  # H.264 loss


@pytest.mark.extra("render")
def test_gif_frames_and_timing(clip, gl, tmp_path):
    from PIL import Image

    out = tmp_path / "g.gif"
    rd.render(clip, out, size=SMALL, fps=10)
    with Image.open(out) as im:
        assert im.size == SMALL
        total = 0
        for k in range(im.n_frames):  # Pillow merges identical frames (holds) into one
            im.seek(k)
            total += im.info["duration"]
            assert im.info["duration"] % 100 == 0
    n = round(clip.duration * 10) + 1  # 0.0 .. the clip's end at 10 fps
    assert 2 < im.n_frames <= n
    assert total == 100 * n


def test_key_frames_are_the_middles_of_their_blocks_on_the_clips_clock(clip):
    # the clip starts with a lead-in from rest: the score's time 0 is not the clip's
    assert clip.score_start > 0.0
    root = clip.score.root.path
    for label, f in rd.key_frames(clip):
        spans = [i for v in clip.schedule.values() for i in v if i.block == f"{root}.{label}"]
        assert spans, label
        middle = 0.5 * (spans[0].start + spans[0].end)
        assert abs(clip.time[f] - middle) <= 0.5 / clip.fps


@pytest.mark.extra("render")
def test_contact_sheet_of_key_postures(clip, gl, tmp_path):
    out = tmp_path / "sheet.png"
    rd.render(clip, out, size=SMALL, targets=True)
    img = _png(out)
    assert [k for k, _ in rd.key_frames(clip)] == ["K1", "PERM", "K2"]
    assert img.shape == (SMALL[1], 3 * SMALL[0], 3)
    tiles = [img[:, i * SMALL[0] : (i + 1) * SMALL[0]] for i in range(3)]
    assert np.abs(tiles[0] - tiles[2]).mean() > 0.5


@pytest.mark.extra("render")
def test_cli_render_from_npz_with_score(gl, tmp_path, capsys):
    npz = tmp_path / "g.npz"
    assert main(["realize", str(GOOD), "-o", str(npz)]) == 0
    out = tmp_path / "t.png"
    assert (
        main(
            [
                "render",
                str(npz),
                "--score",
                str(GOOD),
                "-o",
                str(out),
                "--time",
                "0.2",
                "--size",
                "160x120",
                "--targets",
                "--camera",
                "three-quarter",
            ]
        )
        == 0
    )
    assert _png(out).shape == (120, 160, 3)


@pytest.mark.parametrize(
    "args, message",
    [
        (["-o", "OUT.avi"], "-o: unknown output type '.avi'"),
        (["-o", "OUT.png", "--size", "640by480"], "--size: expected WxH"),
        (["-o", "OUT.png", "--size", "8x8"], "--size: width and height must be 16..4096"),
        (["-o", "OUT.mp4", "--size", "161x120"], "--size: an .mp4 needs an even"),
        (["-o", "OUT.png", "--time", "5"], "--time: 5 s is outside the rollout"),
        (["-o", "OUT.gif", "--time", "0.1"], "--time: only for a .png"),
        (["-o", "OUT.png", "--fps", "-1"], "--fps"),
    ],
)
def test_cli_bad_render_options(args, message, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["render", str(GOOD), *args]) == 2
    err = capsys.readouterr().err
    assert err.startswith("azee-mj: error: ") and message in err
    assert err.count("\n") == 1
    assert list(tmp_path.iterdir()) == []  # nothing written, no temp file left


def test_missing_input_suffix(tmp_path):
    with pytest.raises(AzeeError, match="expected a SCORE.json or a ROLLOUT.npz"):
        cli.load_clip(tmp_path / "x.txt")


# ---------------------------------------------------------------------------------------
# The real viewer, under Xvfb
# ---------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def display():
    if os.environ.get("DISPLAY"):
        yield os.environ["DISPLAY"]
        return
    xvfb = shutil.which("Xvfb")
    if not xvfb:
        pytest.skip("no DISPLAY and no Xvfb to make one")
    n = next(k for k in range(99, 200) if not os.path.exists(f"/tmp/.X{k}-lock"))
    proc = subprocess.Popen(
        [xvfb, f":{n}", "-screen", "0", "800x600x24", "-nolisten", "tcp"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    for _ in range(50):
        if os.path.exists(f"/tmp/.X11-unix/X{n}"):
            break
        time.sleep(0.1)
    yield f":{n}"
    proc.terminate()
    proc.wait(timeout=10)


def test_preview_opens_plays_and_closes(display):
    env = dict(os.environ, DISPLAY=display, MUJOCO_GL="glfw")
    r = subprocess.run(
        [sys.executable, "-m", "azee_mj.cli", "preview", str(GOOD), "--max-frames", "4"],
        env=env,
        capture_output=True,
        text=True,
        timeout=90,
        check=False,
    )
    assert r.returncode == 0, r.stderr
    assert "preview: 4 viewer updates" in r.stdout


def test_preview_without_display_is_a_clear_error(monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert main(["preview", str(GOOD), "--max-frames", "1"]) == 2
    assert "preview needs a display" in capsys.readouterr().err


def test_no_gl_backend_is_a_clear_error(monkeypatch):
    monkeypatch.delenv("MUJOCO_GL", raising=False)
    tried = []
    with pytest.raises(
        AzeeError,
        match="no OpenGL backend for offscreen rendering: tried "
        "MUJOCO_GL=egl .* and MUJOCO_GL=osmesa",
    ):
        rd.gl_backend(probe=lambda b: tried.append(b) or False)
    assert tried == ["egl", "osmesa"]
    assert "MUJOCO_GL" not in os.environ
