"""A self-contained web player: one HTML page with the signer as GLB and three.js inlined.

The page needs no network: the GLB (:mod:`azee_mj.export.gltf`) is embedded as base64 and
three.js with its GLTFLoader and OrbitControls (``vendor/three.min.js``, MIT) is inlined.
Controls: play / pause (also the space bar), speed 0.25x to 2x, a time slider, orbiting
camera (drag; wheel zooms), and the blocks driving each track at the current time.

The URL's query sets the start state, for links and tests: ``t`` (seconds), ``paused=1``,
``speed``, ``ui=0`` (hide the controls: the canvas fills the window), ``highlight=BODY``
(draw that body and its children flat magenta). The start camera is the scene's ``front``
camera (the same pose and vertical field of view as MuJoCo's). ``window.azeePlayer``
exposes ``ready``, ``error``, ``frames`` (drawn so far), ``readyFrame`` (``frames`` when
the signer was loaded), ``time()``, ``setTime(t)``,
``play()``, ``pause()``, ``playing()``, ``speed()`` and ``activeBlocks()``.
"""

from __future__ import annotations

import base64
import html
import json
import math
import os
import re
from collections.abc import Mapping
from pathlib import Path

import mujoco
import numpy as np

from azee_mj.export import gltf
from azee_mj.export import motion as mo

VENDOR = Path(__file__).parent / "vendor"
#: Most frames a page may hold: 30 minutes at 50 fps, a page of about 100 MB that headless
#: Chromium opened in 17 s; one of 180,001 frames (196 MB) did not open in 10 minutes.
MAX_PLAYER_FRAMES = 90_000
#: The scene camera the page starts from, and how far ahead of it the orbit centre is [m].
CAMERA = "front"
ORBIT_DISTANCE = 2.0


def camera_pose(name: str = CAMERA) -> dict:
    """The scene camera ``name`` in glTF's Y-up frame: ``position``, ``target`` (the orbit
    centre, :data:`ORBIT_DISTANCE` ahead) [m], ``up`` and vertical ``fovy`` [degrees]."""
    from azee_mj.model import SCENE_PATH

    scene = mujoco.MjModel.from_xml_path(str(SCENE_PATH))
    c = mujoco.mj_name2id(scene, mujoco.mjtObj.mjOBJ_CAMERA, name)
    if c < 0:
        raise mo.AzeeError(f"the scene has no camera {name!r}")
    data = mujoco.MjData(scene)
    mujoco.mj_kinematics(scene, data)
    mujoco.mj_camlight(scene, data)
    R = data.cam_xmat[c].reshape(3, 3)  # columns: camera x, y, z (it looks along -z)
    p = data.cam_xpos[c]
    target = p - ORBIT_DISTANCE * R[:, 2]
    return {
        "position": (mo.YUP @ p).tolist(),
        "target": (mo.YUP @ target).tolist(),
        "up": (mo.YUP @ R[:, 1]).tolist(),
        "fovy": float(scene.cam_fovy[c]),
    }


def build_html(
    model: mujoco.MjModel,
    qpos: np.ndarray,
    fps: float,
    schedule: Mapping[str, tuple[tuple[str, float, float], ...]] | None = None,
    title: str = "azee_mj",
) -> str:
    """The page's text (see the module docstring). ``schedule``: per track, ``(block, start,
    end)`` intervals [s] whose block names the page shows at the current time."""
    check_schedule(schedule or {})
    glb = gltf.glb_bytes(model, qpos, fps)
    three = (VENDOR / "three.min.js").read_text(encoding="utf-8")
    info = {
        "title": title,
        "fps": float(fps),
        "frames": len(qpos),
        "duration": (len(qpos) - 1) / float(fps),
        "camera": camera_pose(),
        "schedule": {
            k: [[b, float(s), float(e)] for b, s, e in v] for k, v in (schedule or {}).items()
        },
    }
    values = {
        "TITLE": html.escape(title),
        "INFO": script_json(info),
        "GLB": base64.b64encode(glb).decode("ascii"),
        "THREE": three,
    }
    # one pass over the template alone: no user string is ever scanned for placeholders
    return _PLACEHOLDER.sub(lambda m: values[m.group(1)], _TEMPLATE)


_PLACEHOLDER = re.compile("@(TITLE|INFO|GLB|THREE)@")


def script_json(value) -> str:
    """``value`` as JSON text safe inside a ``<script>`` element: ``<``, ``>`` and ``&``
    written as ``\\u003c``, ``\\u003e``, ``\\u0026`` (so no ``<!--``, ``<script`` or
    ``</script`` can end or change the element); non-finite numbers refused."""
    text = json.dumps(value, allow_nan=False)
    return text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")


def check_frames(output: str | os.PathLike, frames: int) -> None:
    """Refuse a page of more than :data:`MAX_PLAYER_FRAMES` frames (it would not open)."""
    if frames > MAX_PLAYER_FRAMES:
        raise mo.AzeeError(
            f"{output}: {frames} frames; a player page holds at most {MAX_PLAYER_FRAMES} "
            "(a larger page takes minutes to open in a browser, or never opens): export a "
            "part, a lower --fps, or .glb for a viewer"
        )


def check_schedule(schedule: Mapping[str, tuple[tuple[str, float, float], ...]]) -> None:
    """Raise :class:`~azee_mj.errors.AzeeError` for a block time that is not finite."""
    for track, ivs in schedule.items():
        for b, s, e in ivs:
            if not (math.isfinite(s) and math.isfinite(e)):
                raise mo.AzeeError(f"schedule: block {b!r} on track {track}: times must be finite")


def write_player(
    path: str | os.PathLike,
    model: mujoco.MjModel,
    qpos: np.ndarray,
    fps: float,
    schedule=None,
    title: str = "azee_mj",
) -> None:
    """Write the page to ``path`` (the caller makes it atomic)."""
    mo.check_qpos(model, qpos, fps)
    check_frames(path, len(qpos))
    Path(path).write_text(build_html(model, qpos, fps, schedule, title), encoding="utf-8")


_TEMPLATE = r"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>@TITLE@</title>
<style>
  html, body { margin: 0; height: 100%; overflow: hidden; background: #33404d;
               font: 14px system-ui, sans-serif; color: #eee; }
  #view { position: absolute; inset: 0 0 64px 0; }
  body.noui #view { inset: 0; }
  body.noui #bar, body.noui #blocks { display: none; }
  #bar { position: absolute; left: 0; right: 0; bottom: 0; height: 64px; display: flex;
         gap: 10px; align-items: center; padding: 0 12px; background: #222a33; box-sizing: border-box; }
  #bar input[type=range] { flex: 1; }
  #bar button { width: 72px; }
  #clock { font-variant-numeric: tabular-nums; min-width: 110px; }
  #blocks { position: absolute; top: 8px; left: 8px; padding: 6px 10px; background: #0008;
            border-radius: 4px; white-space: pre; font: 12px ui-monospace, monospace; }
  #title { position: absolute; top: 8px; right: 10px; opacity: 0.8; }
</style>
</head>
<body>
<div id="view"></div>
<div id="blocks"></div>
<div id="title">@TITLE@</div>
<div id="bar">
  <button id="play" title="play / pause (space)">pause</button>
  <label>speed <select id="speed">
    <option value="0.25">0.25x</option><option value="0.5">0.5x</option>
    <option value="1" selected>1x</option><option value="1.5">1.5x</option>
    <option value="2">2x</option></select></label>
  <input id="slider" type="range" min="0" step="any" value="0" aria-label="time">
  <span id="clock"></span>
</div>
<script type="application/json" id="azee-info">@INFO@</script>
<script type="application/octet-stream;base64" id="azee-glb">@GLB@</script>
<script>@THREE@</script>
<script>
(function () {
  "use strict";
  const info = JSON.parse(document.getElementById("azee-info").textContent);
  const q = new URLSearchParams(location.search);
  const player = window.azeePlayer = { ready: false, error: null, frames: 0 };
  let t = Math.min(Math.max(parseFloat(q.get("t") || "0") || 0, 0), info.duration);
  let playing = q.get("paused") !== "1";
  let speed = parseFloat(q.get("speed") || "1") || 1;
  if (q.get("ui") === "0") document.body.classList.add("noui");

  const view = document.getElementById("view");
  const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  view.appendChild(renderer.domElement);
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0x33404d);
  scene.add(new THREE.HemisphereLight(0xffffff, 0x444444, 1.6));
  const key = new THREE.DirectionalLight(0xffffff, 1.8);
  key.position.set(-1.0, 2.2, 1.5);
  scene.add(key);
  const fill = new THREE.DirectionalLight(0xffffff, 0.6);
  fill.position.set(1.5, 1.2, 1.2);
  scene.add(fill);
  const cam = info.camera;
  const camera = new THREE.PerspectiveCamera(cam.fovy, 1, 0.01, 50);
  camera.position.fromArray(cam.position);
  camera.up.fromArray(cam.up);
  const controls = new OrbitControls(camera, renderer.domElement);
  controls.target.fromArray(cam.target);
  controls.update();

  function resize() {
    const w = view.clientWidth, h = view.clientHeight;
    renderer.setSize(w, h, false);
    renderer.domElement.style.width = w + "px";
    renderer.domElement.style.height = h + "px";
    camera.aspect = w / h;
    camera.updateProjectionMatrix();
  }
  window.addEventListener("resize", resize);
  resize();

  const slider = document.getElementById("slider");
  const clock = document.getElementById("clock");
  const blocks = document.getElementById("blocks");
  const button = document.getElementById("play");
  const speedSel = document.getElementById("speed");
  slider.max = info.duration;
  speedSel.value = String(speed);
  if (speedSel.value === "") { speedSel.value = "1"; speed = 1; }

  function active(time) {
    const lines = [];
    for (const [track, ivs] of Object.entries(info.schedule)) {
      const names = [];
      for (const [b, s, e] of ivs) {
        if ((s - 1e-9 <= time && time < e - 1e-9) ||
            (e >= info.duration - 1e-9 && s <= time && time >= e - 1e-9)) names.push(b);
      }
      if (names.length) lines.push(track.padEnd(7) + " " + names.join(", "));
    }
    return lines.join("\n");
  }

  let mixer = null;
  function show() {
    // LoopRepeat would wrap the clip's last instant to its first: stop just short of it
    if (mixer) mixer.setTime(Math.min(t, Math.max(info.duration - 1e-6, 0)));
    slider.value = t;
    clock.textContent = t.toFixed(2) + " / " + info.duration.toFixed(2) + " s";
    const text = active(t);
    blocks.textContent = text;
    blocks.style.display = text ? "" : "none";
    button.textContent = playing ? "pause" : "play";
  }
  player.time = () => t;
  player.setTime = (x) => { t = Math.min(Math.max(x, 0), info.duration); show(); };
  player.play = () => { playing = true; show(); };
  player.pause = () => { playing = false; show(); };
  player.activeBlocks = () => active(t);
  player.playing = () => playing;
  player.speed = () => speed;
  button.addEventListener("click", () => { playing = !playing; show(); });
  window.addEventListener("keydown", (e) => {
    if (e.code === "Space") { playing = !playing; show(); e.preventDefault(); }
  });
  speedSel.addEventListener("change", () => { speed = parseFloat(speedSel.value); });
  slider.addEventListener("input", () => { t = parseFloat(slider.value); show(); });

  const b64 = document.getElementById("azee-glb").textContent.trim();
  const bytes = Uint8Array.from(atob(b64), (c) => c.charCodeAt(0));
  new GLTFLoader().parse(bytes.buffer, "", (gltf) => {
    scene.add(gltf.scene);
    const hl = q.get("highlight");
    if (hl) {
      const root = gltf.scene.getObjectByName(hl);
      if (!root) throw new Error("highlight: no body named " + hl);
      const magenta = new THREE.MeshBasicMaterial({ color: 0xff00ff });
      root.traverse((o) => { if (o.isMesh) o.material = magenta; });
    }
    mixer = new THREE.AnimationMixer(gltf.scene);
    if (gltf.animations.length) {
      const action = mixer.clipAction(gltf.animations[0]);
      action.play();
    }
    show();
    player.readyFrame = player.frames;
    player.ready = true;
  }, (err) => { player.error = String(err); console.error("azee player: " + err); });

  let last = performance.now();
  function tick(now) {
    const dt = Math.min((now - last) / 1000, 0.25);
    last = now;
    if (playing && player.ready) {
      t += dt * speed;
      if (t > info.duration) t = info.duration > 0 ? t % info.duration : 0;
      show();
    }
    controls.update();
    renderer.render(scene, camera);
    player.frames += 1;
    requestAnimationFrame(tick);
  }
  show();
  requestAnimationFrame(tick);
})();
</script>
</body>
</html>
"""
