"""The live MuJoCo viewer: :func:`preview` plays a :class:`~azee_mj.markers.Clip` in
``mujoco.viewer.launch_passive``, looping in real time, with the markers of
:mod:`azee_mj.markers` drawn over it. Needs a display. Units: seconds.
"""

from __future__ import annotations

import os
import sys
import threading
import time as _time

from azee_mj.errors import AzeeError
from azee_mj.markers import Clip, Targets, add_markers, frame_text, markers
from azee_mj.render import CAMERAS, camera_id, scene_model

# ---------------------------------------------------------------------------------------
# Interactive preview
# ---------------------------------------------------------------------------------------

# GLFW key codes
_SPACE, _RIGHT, _LEFT, _DOWN, _UP = 32, 262, 263, 264, 265
_MINUS, _EQUAL, _KP_SUB, _KP_ADD, _KEY_C = 45, 61, 333, 334, 67
SPEEDS = (0.1, 0.25, 0.5, 1.0, 2.0)

KEYS = (
    ("space", "pause / play"),
    ("right / left", "next / previous frame (pauses)"),
    ("up or + / down or -", "faster / slower (0.1x to 2x)"),
    ("C", "cycle the cameras: free, front, side, three-quarter, top, face"),
)


class Player:
    """Play state changed by the viewer's key callback (runs on the viewer's thread)."""

    def __init__(self, n_frames: int):
        self.n = n_frames
        self.paused = False
        self.speed_i = SPEEDS.index(1.0)
        self.step = 0
        self.camera_steps = 0

    @property
    def speed(self) -> float:
        return SPEEDS[self.speed_i]

    def key(self, code: int) -> None:
        if code == _SPACE:
            self.paused = not self.paused
        elif code in (_RIGHT, _LEFT):
            self.paused = True
            self.step += 1 if code == _RIGHT else -1
        elif code in (_UP, _EQUAL, _KP_ADD):
            self.speed_i = min(self.speed_i + 1, len(SPEEDS) - 1)
        elif code in (_DOWN, _MINUS, _KP_SUB):
            self.speed_i = max(self.speed_i - 1, 0)
        elif code == _KEY_C:
            self.camera_steps += 1


def _require_display() -> None:
    """Fail with a clear message when no display is available on Linux."""
    if (
        sys.platform.startswith("linux")
        and not os.environ.get("DISPLAY")
        and not os.environ.get("WAYLAND_DISPLAY")
    ):
        raise AzeeError(
            "preview needs a display (DISPLAY is unset); run it under "
            "'xvfb-run', or use 'azee-mj render' for a video"
        )


def _advance(clip: Clip, player: Player, clock: float, last: float, now: float) -> float:
    """The looping playback clock (seconds) after one viewer update at time ``now``."""
    if not player.paused:
        clock += (now - last) * player.speed
    if player.step:
        clock += player.step / clip.fps
        player.step = 0
    period = clip.duration + 1.0 / clip.fps
    return clock % period


def _apply_camera(handle, cams: list[int], cam_i: int) -> None:
    """Point the viewer at ``cams[cam_i]`` (-1: the free camera)."""
    import mujoco

    if cams[cam_i] < 0:
        handle.cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    else:
        handle.cam.type = mujoco.mjtCamera.mjCAMERA_FIXED
        handle.cam.fixedcamid = cams[cam_i]


def _set_texts(handle, clip: Clip, frame: int, player: Player, camera_name: str) -> None:
    """Write the frame overlay and the key help into the viewer."""
    import mujoco

    left, right = frame_text(clip, frame, player.speed, player.paused)
    handle.set_texts(
        [
            (
                mujoco.mjtFontScale.mjFONTSCALE_150,
                mujoco.mjtGridPos.mjGRID_TOPLEFT,
                left + "\ncamera",
                right + "\n" + camera_name,
            ),
            (
                mujoco.mjtFontScale.mjFONTSCALE_150,
                mujoco.mjtGridPos.mjGRID_BOTTOMLEFT,
                "keys",
                "space pause, <- -> step, up/down speed, C camera",
            ),
        ]
    )


def preview(
    clip: Clip,
    *,
    targets: bool = True,
    max_frames: int | None = None,
    camera: str | None = None,
) -> int:
    """Play ``clip`` in the MuJoCo viewer in real time, looping, until the window closes
    (or after ``max_frames`` viewer updates). Returns the number of updates."""
    import mujoco.viewer

    _require_display()
    model = scene_model()
    data = mujoco.MjData(model)
    tg = Targets(clip.score) if targets and clip.score is not None else None
    player = Player(len(clip.time))
    cams = [-1] + [camera_id(model, c) for c in CAMERAS]
    cam_i = cams.index(camera_id(model, camera)) if camera else 0
    data.qpos[:] = clip.qpos[0]
    before = set(threading.enumerate())
    try:
        handle = mujoco.viewer.launch_passive(model, data, key_callback=player.key)
    except Exception as e:  # noqa: BLE001
        raise AzeeError(f"cannot open the MuJoCo viewer: {e}") from None
    n, clock, last = 0, 0.0, _time.perf_counter()
    applied_cam, applied_steps = None, 0
    try:
        while handle.is_running() and (max_frames is None or n < max_frames):
            now = _time.perf_counter()
            clock = _advance(clip, player, clock, last, now)
            last = now
            frame = min(int(clock * clip.fps + 1e-9), len(clip.time) - 1)
            if player.camera_steps != applied_steps:
                cam_i = (cam_i + player.camera_steps - applied_steps) % len(cams)
                applied_steps = player.camera_steps
            with handle.lock():
                items = markers(model, data, clip, frame, tg)
                mujoco.mj_forward(model, data)
                scn = handle.user_scn
                if scn is not None:
                    scn.ngeom = 0
                    add_markers(scn, items)
                if cam_i != applied_cam:
                    _apply_camera(handle, cams, cam_i)
                    applied_cam = cam_i
                # C is also MuJoCo's contact-point shortcut; keep that display off.
                handle.opt.flags[mujoco.mjtVisFlag.mjVIS_CONTACTPOINT] = 0
            name = CAMERAS[cam_i - 1] if cams[cam_i] >= 0 else "free"
            _set_texts(handle, clip, frame, player, name)
            handle.sync()
            n += 1
            _time.sleep(max(0.0, 1.0 / 60 - (_time.perf_counter() - now)))
    finally:
        handle.close()
        # Let the viewer's thread destroy its window before the interpreter exits (GLFW
        # terminates in an atexit hook, which must not race the window teardown).
        for th in set(threading.enumerate()) - before:
            th.join(timeout=10.0)
    return n
