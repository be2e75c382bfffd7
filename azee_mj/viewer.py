"""MuJoCo viewer preview and offscreen rendering of rollouts.

Three layers, from pure to windowed:

- :func:`markers` lists what to draw over one frame (constraint targets, red where a
  constraint is over its tolerance, penetrating contacts) as :class:`Marker` records, and
  :func:`add_markers` turns them into ``mjvGeom`` s of an ``mjvScene``; neither needs a
  window or a GL context.
- :func:`render_frames` / :func:`render` draw a :class:`Clip` offscreen with
  ``mujoco.Renderer`` on ``scene.xml`` to video, a still or a contact sheet of key postures.
- :func:`preview` plays a clip in ``mujoco.viewer.launch_passive``.

Importing this module needs no display: the GL backend is chosen by :func:`gl_backend` the
first time something renders. Units: metres, seconds.
"""

from __future__ import annotations

import dataclasses
import math
import os
import subprocess
import sys
import threading
import time as _time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from azee_mj import ik
from azee_mj import score as sc
from azee_mj.errors import AzeeError
from azee_mj.model import SCENE_PATH

#: The fixed cameras of ``scene.xml``, in the order ``C`` cycles them in the viewer.
CAMERAS = ("front", "side", "three-quarter", "top")
#: Backends tried, in order, when ``MUJOCO_GL`` is unset.
GL_BACKENDS = ("egl", "osmesa")
#: Default image size [px].
DEFAULT_SIZE = (640, 480)
#: Contacts deeper than this are drawn red [m] (the IK solver's penetration limit).
PENETRATION = ik.PENETRATION_LIMIT
#: Shadow map size of offscreen renders [px].
SHADOW_SIZE = 1024
#: Length of an orientation arrow [m].
ARROW_LENGTH = 0.12

_GREEN = (0.15, 0.85, 0.25, 0.7)
_BLUE = (0.2, 0.45, 1.0, 0.8)
_YELLOW = (1.0, 0.85, 0.1, 0.8)
_RED = (1.0, 0.1, 0.1, 0.9)

RENDER_HINT = "pip install azee_mj[render]"


# ---------------------------------------------------------------------------------------
# What is played: a rollout, with or without its score
# ---------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Clip:
    """A motion to show.

    Attributes:
      time: (T,) frame times [s]; ``qpos`` (T, nq) postures; ``fps`` frames per second.
      schedule: per track, ``(block, start, end)`` intervals (empty without a score).
      score: the realized score, or None (then no targets are drawn).
      name: a label (the input file's stem).
    """

    time: np.ndarray
    qpos: np.ndarray
    fps: float
    schedule: Mapping[str, tuple[tuple[str, float, float], ...]]
    score: sc.Score | None = None
    name: str = ""

    @property
    def duration(self) -> float:
        """Time of the last frame [s]."""
        return float(self.time[-1]) if len(self.time) else 0.0

    @classmethod
    def from_rollout(cls, rollout, score: sc.Score | None = None, name: str = "") -> Clip:
        """A clip of a :class:`~azee_mj.timeline.Rollout`."""
        sched = {t: tuple((i.block, i.start, i.end) for i in v)
                 for t, v in rollout.schedule.items()}  # fmt: skip
        return cls(rollout.time, rollout.qpos, float(rollout.fps), sched, score, name)

    def frame_at(self, t: float) -> int:
        """Index of the frame nearest to time ``t`` [s]."""
        return int(np.clip(round(t * self.fps), 0, len(self.time) - 1))

    def active_blocks(self, frame: int) -> dict[str, str]:
        """Per track, the block driving it at ``frame`` ('' when none)."""
        t = float(self.time[frame])
        out = {}
        for track, ivs in self.schedule.items():
            names = [b for b, s, e in ivs if s - 1e-9 <= t < e - 1e-9 or (t >= e - 1e-9 and
                     e >= self.duration - 1e-9 and s <= t)]  # fmt: skip
            out[track] = names[-1] if names else ""
        return out


def _schedule_of(score: sc.Score, fps: float) -> dict:
    """The per-track schedule of a score without solving it (reuses the realizer's)."""
    from azee_mj import timeline

    sched = timeline.schedule(score, _solver())
    return {t: tuple((i.block, i.start, i.end) for i in v) for t, v in sched.items()}


_SOLVER: ik.Solver | None = None


def _solver() -> ik.Solver:
    global _SOLVER
    if _SOLVER is None:
        _SOLVER = ik.Solver()
    return _SOLVER


def load_clip(
    path: str | os.PathLike,
    *,
    score: str | os.PathLike | None = None,
    fps: float = 50.0,
    progress: Callable[[float], None] | None = None,
) -> Clip:
    """A clip from ``SCORE.json`` (realized at ``fps``) or ``ROLLOUT.npz`` (with an optional
    ``score`` for targets and the schedule)."""
    from azee_mj.files import load_rollout_arrays
    from azee_mj.model import load_model
    from azee_mj.timeline import realize

    path = Path(path)
    if path.suffix.lower() == ".json":
        s = sc.load_score(path)
        rollout = realize(s, fps=fps, solver=_solver(), progress=progress)
        return Clip.from_rollout(rollout, s, path.stem)
    if path.suffix.lower() != ".npz":
        raise AzeeError(f"{path}: expected a SCORE.json or a ROLLOUT.npz, got suffix "
                        f"{path.suffix!r}")  # fmt: skip
    a = load_rollout_arrays(path)
    nq = load_model().nq
    if a["qpos"].shape[1] != nq:
        raise AzeeError(f"{path}: qpos has {a['qpos'].shape[1]} columns; the bundled signer "
                        f"has nq={nq}")  # fmt: skip
    rfps = float(a["fps"])
    given = sc.load_score(Path(score)) if score else None
    sched = _schedule_of(given, rfps) if given is not None else {}
    return Clip(a["time"], a["qpos"], rfps, sched, given, path.stem)


# ---------------------------------------------------------------------------------------
# Decorations: pure functions, no window
# ---------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Marker:
    """One thing drawn over a frame.

    Attributes:
      kind: ``sphere`` (a place target), ``arrow`` (an orient vector, from the bone's
        origin), ``line`` (gaze, from between the eyes to the looked-at point) or
        ``contact`` (a penetrating contact).
      label: ``BLOCK#index`` of the constraint, or ``geom1|geom2`` of a contact.
      pos: (3,) sphere centre, or where the arrow / line starts [m].
      end: (3,) where the arrow / line ends (None for spheres) [m].
      residual: the constraint's error in its unit ([m] or [rad]); a contact's depth [m].
      violated: over tolerance (drawn red).
    """

    kind: str
    label: str
    pos: np.ndarray
    end: np.ndarray | None
    residual: float
    violated: bool


@dataclasses.dataclass(frozen=True)
class _Target:
    block: str
    index: int
    start: float
    end: float
    con: ik.Place | ik.Orient | ik.Look


class Targets:
    """The place / orient / look constraints of a score, as IK constraints with their
    blocks' intervals (compiled once by the realizer's ``_Compiler``)."""

    def __init__(self, score: sc.Score, solver: ik.Solver | None = None):
        from azee_mj.timeline import _Compiler

        self.solver = solver or _solver()
        comp = _Compiler(self.solver.model, self.solver.signer_map)
        out = []
        for b in score.blocks():
            if b.kind is not sc.BlockKind.CSTR:
                continue
            for c in b.constraints:
                ic = comp.constraint(c, f"{b.path}#{c.index}")
                if ic is not None:
                    out.append(_Target(b.path, c.index, b.start, b.end, ic))
        self.items: tuple[_Target, ...] = tuple(out)
        self.duration = score.duration

    def active(self, t: float) -> list[_Target]:
        """Targets whose block holds at time ``t`` [s] (the last frame keeps its blocks)."""
        eps = 1e-9
        return [x for x in self.items
                if x.start - eps <= t < x.end - eps
                or (t >= self.duration - eps and x.end >= self.duration - eps)]  # fmt: skip


def markers(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    clip: Clip,
    frame: int,
    targets: Targets | None = None,
) -> list[Marker]:
    """What to draw over ``frame``: one marker per active constraint target, then one per
    penetrating contact. Sets ``data.qpos`` to the frame and runs kinematics and collision
    on ``model`` (the scene); targets are evaluated on ``targets.solver``'s own data."""
    q = clip.qpos[frame]
    out: list[Marker] = []
    if targets is not None:
        s = targets.solver
        s.data.qpos[:] = q
        mujoco.mj_kinematics(s.model, s.data)
        kin = ik._Kin(s)
        for x in targets.active(float(clip.time[frame])):
            c = x.con
            res = c.residual(kin)
            bad = res > c.tol
            label = f"{x.block}#{x.index}"
            if isinstance(c, ik.Place):
                p = kin.eval(c.target, jac=False)[0]
                out.append(Marker("sphere", label, p, None, res, bad))
            elif isinstance(c, ik.Orient):
                v = kin.eval(ik.Unit(c.vector), jac=False)[0]
                if c.rel is ik.Rel.OPP:
                    v = -v
                o = s.data.xpos[s.body_id(c.body)].copy()
                out.append(Marker("arrow", label, o, o + ARROW_LENGTH * v, res, bad))
            else:  # Look
                eyes = np.mean([s.data.xpos[s.body_id(b)] for b, _ in c.eyes], axis=0)
                p = kin.eval(c.target, jac=False)[0]
                out.append(Marker("line", label, eyes, p, res, bad))
    data.qpos[:] = q
    mujoco.mj_kinematics(model, data)
    mujoco.mj_collision(model, data)
    for i in range(data.ncon):
        con = data.contact[i]
        if con.dist < -PENETRATION:
            g1 = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, con.geom[0]) or str(con.geom[0])
            g2 = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, con.geom[1]) or str(con.geom[1])
            out.append(Marker("contact", f"{g1}|{g2}", con.pos.copy(), None, -float(con.dist),
                              True))  # fmt: skip
    return out


def add_markers(scn: mujoco.MjvScene, items: Sequence[Marker]) -> int:
    """Append ``mjvGeom`` s for ``items`` to ``scn`` (while it has room); returns how many."""
    n = 0
    for mk in items:
        if scn.ngeom >= scn.maxgeom:
            break
        g = scn.geoms[scn.ngeom]
        if mk.kind in ("sphere", "contact"):
            size = 0.012 if mk.kind == "sphere" else 0.008
            rgba = _RED if mk.violated else (_GREEN if mk.kind == "sphere" else _RED)
            mujoco.mjv_initGeom(g, mujoco.mjtGeom.mjGEOM_SPHERE, np.array([size, 0, 0]),
                                np.asarray(mk.pos, float), np.eye(3).ravel(),
                                np.array(rgba, np.float32))  # fmt: skip
        else:
            rgba = _RED if mk.violated else (_BLUE if mk.kind == "arrow" else _YELLOW)
            typ = mujoco.mjtGeom.mjGEOM_ARROW if mk.kind == "arrow" else mujoco.mjtGeom.mjGEOM_LINE
            mujoco.mjv_initGeom(g, typ, np.zeros(3), np.zeros(3), np.eye(3).ravel(),
                                np.array(rgba, np.float32))  # fmt: skip
            width = 0.006 if mk.kind == "arrow" else 3.0
            mujoco.mjv_connector(g, typ, width, np.asarray(mk.pos, float),
                                 np.asarray(mk.end, float))  # fmt: skip
        g.category = mujoco.mjtCatBit.mjCAT_DECOR
        scn.ngeom += 1
        n += 1
    return n


def frame_text(clip: Clip, frame: int, speed: float = 1.0, paused: bool = False) -> tuple[str, str]:
    """The overlay of a frame: (left column, right column), one line per row."""
    left = ["time", "frame"]
    right = [f"{clip.time[frame]:.3f} / {clip.duration:.3f} s",
             f"{frame} / {len(clip.time) - 1}"]  # fmt: skip
    left.append("speed")
    right.append(f"{speed:g}x" + (" (paused)" if paused else ""))
    for track, block in clip.active_blocks(frame).items():
        left.append(track)
        right.append(block or "-")
    return "\n".join(left), "\n".join(right)


# ---------------------------------------------------------------------------------------
# GL backend
# ---------------------------------------------------------------------------------------

_BACKEND: str | None = None
_PROBE = (
    "import os, sys; os.environ['MUJOCO_GL'] = sys.argv[1]; import mujoco; "
    "c = mujoco.GLContext(32, 32); c.make_current(); "
    "m = mujoco.MjModel.from_xml_string('<mujoco/>'); mujoco.MjrContext(m, 150); c.free()"
)


def _probe(backend: str) -> bool:
    env = {k: v for k, v in os.environ.items() if k != "PYOPENGL_PLATFORM"}
    try:
        r = subprocess.run([sys.executable, "-c", _PROBE, backend], env=env, check=False,
                           capture_output=True, timeout=60)  # fmt: skip
    except (OSError, subprocess.TimeoutExpired):
        return False
    return r.returncode == 0


def gl_backend() -> str:
    """The OpenGL backend for offscreen rendering, set up for ``mujoco.Renderer``.

    ``MUJOCO_GL`` is respected when set; otherwise ``egl`` then ``osmesa`` are tried (each
    in a short subprocess, since a failed attempt cannot be undone in this one) and the
    first that works is written to ``MUJOCO_GL``. Raises :class:`AzeeError` when none does.
    """
    global _BACKEND
    if _BACKEND is not None:
        return _BACKEND
    env = os.environ.get("MUJOCO_GL", "").strip().lower()
    if env:
        backend = env
    else:
        backend = next((b for b in GL_BACKENDS if _probe(b)), "")
        if not backend:
            raise AzeeError(
                "no OpenGL backend for offscreen rendering: tried MUJOCO_GL=egl (needs "
                "libegl1) and MUJOCO_GL=osmesa (needs libosmesa6); install one, or set "
                "MUJOCO_GL=glfw with a display"
            )
        os.environ["MUJOCO_GL"] = backend
    # mujoco chose its GLContext when it was imported; point it at this backend.
    from mujoco.rendering.classic import gl_context

    try:
        if backend == "egl":
            from mujoco.egl import GLContext
        elif backend == "osmesa":
            from mujoco.osmesa import GLContext
        elif backend in ("glfw", "glx"):
            from mujoco.glfw import GLContext
        else:
            raise AzeeError(f"MUJOCO_GL={backend!r} is not a backend; use egl, osmesa or glfw")
    except ImportError as e:
        raise AzeeError(f"MUJOCO_GL={backend}: cannot load the backend ({e})") from None
    gl_context.GLContext = GLContext
    _BACKEND = backend
    return backend


# ---------------------------------------------------------------------------------------
# Offscreen rendering
# ---------------------------------------------------------------------------------------


def scene_model(width: int = 0, height: int = 0) -> mujoco.MjModel:
    """The signer on its floor with lights and cameras, with room for a ``width`` x
    ``height`` offscreen buffer."""
    m = mujoco.MjModel.from_xml_path(str(SCENE_PATH))
    m.vis.global_.offwidth = max(m.vis.global_.offwidth, width)
    m.vis.global_.offheight = max(m.vis.global_.offheight, height)
    # A 1024 shadow map looks the same at these sizes and renders 2x faster in software GL.
    m.vis.quality.shadowsize = min(m.vis.quality.shadowsize, SHADOW_SIZE)
    return m


def _camera_id(model: mujoco.MjModel, camera: str) -> int:
    cid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, camera)
    if cid < 0:
        raise AzeeError(f"--camera: unknown camera {camera!r}; valid: {', '.join(CAMERAS)}")
    return cid


def resample(clip: Clip, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """Times ``k / fps`` over the clip and their postures (T', nq), linearly interpolated."""
    n = math.floor(clip.duration * fps + 1e-9) + 1
    t = np.arange(n) / fps
    if abs(fps - clip.fps) < 1e-9:
        return t, clip.qpos[:n]
    x = np.clip(t * clip.fps, 0, len(clip.time) - 1)
    i0 = np.floor(x).astype(int)
    i1 = np.minimum(i0 + 1, len(clip.time) - 1)
    w = (x - i0)[:, None]
    return t, (1 - w) * clip.qpos[i0] + w * clip.qpos[i1]


class FrameRenderer:
    """Renders postures of the signer offscreen from one camera (a ``mujoco.Renderer`` on
    ``scene.xml``); ``targets`` adds the constraint markers. Use as a context manager."""

    def __init__(self, clip: Clip, *, camera: str = "front", size=DEFAULT_SIZE,
                 targets: bool = False):  # fmt: skip
        gl_backend()
        w, h = size
        self.model = scene_model(w, h)
        self.cam = _camera_id(self.model, camera)
        self.data = mujoco.MjData(self.model)
        self.clip = clip
        self.targets = Targets(clip.score) if targets and clip.score is not None else None
        self.decorate = targets
        try:
            self.r = mujoco.Renderer(self.model, height=h, width=w)
        except Exception as e:  # noqa: BLE001  (GL errors come in several types)
            raise AzeeError(f"offscreen rendering failed with MUJOCO_GL={_BACKEND}: {e}") from None

    def render(self, q: np.ndarray, frame: int | None = None) -> np.ndarray:
        """(H, W, 3) uint8 image of posture ``q``; markers of clip frame ``frame`` if any."""
        d = self.data
        items = []
        if self.decorate and frame is not None:
            items = markers(self.model, d, self.clip, frame, self.targets)
        d.qpos[:] = q
        mujoco.mj_forward(self.model, d)
        self.r.update_scene(d, camera=self.cam)
        if items:
            add_markers(self.r.scene, items)
        return self.r.render().copy()

    def close(self) -> None:
        self.r.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def key_frames(clip: Clip) -> list[tuple[str, int]]:
    """(label, frame) of the key postures: the middle of each cstr block in time order
    (blocks with the same middle frame share one, their names joined), or without a score
    six evenly spaced frames labelled by their time."""
    if clip.score is not None:
        root = clip.score.root.path
        blocks = [b for b in clip.score.blocks() if b.kind is sc.BlockKind.CSTR]
        blocks.sort(key=lambda b: (0.5 * (b.start + b.end), b.path))
        byframe: dict[int, list[str]] = {}  # blocks sharing a middle frame share a tile
        for b in blocks:
            name = b.path[len(root) + 1:] if b.path.startswith(root + ".") else b.path
            byframe.setdefault(clip.frame_at(0.5 * (b.start + b.end)), []).append(name)
        if byframe:
            return [(", ".join(names), f) for f, names in byframe.items()]
    idx = np.linspace(0, len(clip.time) - 1, min(6, len(clip.time))).round().astype(int)
    return [(f"t = {clip.time[i]:.2f} s", int(i)) for i in idx]


def parse_size(text: str) -> tuple[int, int]:
    """``WxH`` -> (W, H); AzeeError naming ``--size`` otherwise."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise AzeeError(f"--size: expected WxH in pixels (e.g. 640x480), got {text!r}") from None
    if not (16 <= w <= 4096 and 16 <= h <= 4096):
        raise AzeeError(f"--size: width and height must be 16..4096 pixels, got {text!r}")
    return w, h


OUTPUT_SUFFIXES = (".mp4", ".gif", ".png")


def check_render_options(out, size, fps, time) -> None:
    """Raise :class:`AzeeError` for an output or option render cannot honour."""
    suffix = Path(out).suffix.lower()
    if suffix not in OUTPUT_SUFFIXES:
        raise AzeeError(f"-o: unknown output type {Path(out).suffix or '(none)'!r} of {out}; "
                        f"valid: {', '.join(OUTPUT_SUFFIXES)}")  # fmt: skip
    if suffix == ".mp4" and (size[0] % 2 or size[1] % 2):
        raise AzeeError(f"--size: an .mp4 needs an even width and height, got "
                        f"{size[0]}x{size[1]}")  # fmt: skip
    if fps is not None and not (0 < fps <= 240):
        raise AzeeError(f"--fps: must be in (0, 240], got {fps:g}")
    if time is not None and suffix != ".png":
        raise AzeeError(f"--time: only for a .png still, not {suffix}")


def _need(module: str):
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError:
        raise AzeeError(f"rendering needs the package {module.split('.')[0]!r}: "
                        f"{RENDER_HINT}") from None  # fmt: skip


def render(
    clip: Clip,
    out: str | os.PathLike,
    *,
    camera: str = "front",
    size: tuple[int, int] = DEFAULT_SIZE,
    fps: float | None = None,
    time: float | None = None,
    targets: bool = False,
    progress: Callable[[float], None] | None = None,
) -> Path:
    """Render ``clip`` to ``out`` by its suffix, atomically.

    ``.mp4`` / ``.gif``: the video at ``fps`` (default: the clip's). ``.png``: the frame at
    ``time`` [s], or without it a contact sheet of :func:`key_frames`, labelled.
    Raises :class:`AzeeError` for bad options (before anything is written).
    """
    from azee_mj.files import atomic_path

    out = Path(out)
    check_render_options(out, size, fps, time)
    if camera not in CAMERAS:
        raise AzeeError(f"--camera: unknown camera {camera!r}; valid: {', '.join(CAMERAS)}")
    if time is not None and not (-1e-9 <= time <= clip.duration + 1e-9):
        raise AzeeError(f"--time: {time:g} s is outside the rollout, which spans "
                        f"0..{clip.duration:g} s")  # fmt: skip
    suffix = out.suffix.lower()
    tick = progress or (lambda f: None)
    if suffix == ".mp4":
        _need("imageio_ffmpeg")
    imageio: Any = _need("imageio.v2") if suffix == ".mp4" else None
    pil: Any = _need("PIL.Image") if suffix in (".gif", ".png") else None
    with FrameRenderer(clip, camera=camera, size=size, targets=targets) as fr:
        if suffix == ".png":
            if time is not None:
                f = clip.frame_at(time)
                img = pil.fromarray(fr.render(clip.qpos[f], f))
            else:
                img = _contact_sheet(fr, clip, size, tick)
            with atomic_path(out) as tmp:
                img.save(tmp, format="PNG", optimize=True)
            tick(1.0)
            return out
        vfps = float(fps or clip.fps)
        times, qs = resample(clip, vfps)
        with atomic_path(out) as tmp:
            if suffix == ".mp4":
                w = imageio.get_writer(tmp, format="FFMPEG", fps=vfps, codec="libx264",
                                       quality=7, macro_block_size=2,
                                       ffmpeg_log_level="error")  # fmt: skip
                try:
                    for k, q in enumerate(qs):
                        w.append_data(fr.render(q, clip.frame_at(times[k])))
                        tick((k + 1) / len(qs))
                finally:
                    w.close()
            else:
                frames = []
                quantize = pil.Quantize.MEDIANCUT
                for k, q in enumerate(qs):
                    im = pil.fromarray(fr.render(q, clip.frame_at(times[k])))
                    frames.append(im.quantize(colors=128, method=quantize))
                    tick((k + 1) / len(qs))
                frames[0].save(tmp, format="GIF", save_all=True, append_images=frames[1:],
                               duration=round(1000.0 / vfps), loop=0, optimize=True)  # fmt: skip
    return out


def _contact_sheet(fr: FrameRenderer, clip: Clip, size, tick):
    from PIL import Image, ImageDraw

    keys = key_frames(clip)
    w, h = size
    cols = len(keys) if len(keys) <= 4 else math.ceil(math.sqrt(len(keys)))
    rows = math.ceil(len(keys) / cols)
    sheet = Image.new("RGB", (cols * w, rows * h), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    for k, (label, f) in enumerate(keys):
        x, y = (k % cols) * w, (k // cols) * h
        sheet.paste(Image.fromarray(fr.render(clip.qpos[f], f)), (x, y))
        text = f"{label}  t={clip.time[f]:.2f} s"
        draw.rectangle((x, y, x + 8 + 7 * len(text), y + 18), fill=(0, 0, 0))
        draw.text((x + 4, y + 3), text, fill=(255, 255, 255))
        tick((k + 1) / len(keys))
    return sheet


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
    ("C", "cycle the cameras: free, front, side, three-quarter, top"),
)


class _Player:
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

    if sys.platform.startswith("linux") and not os.environ.get("DISPLAY") and not \
            os.environ.get("WAYLAND_DISPLAY"):  # fmt: skip
        raise AzeeError("preview needs a display (DISPLAY is unset); run it under "
                        "'xvfb-run', or use 'azee-mj render' for a video")  # fmt: skip
    model = scene_model()
    data = mujoco.MjData(model)
    tg = Targets(clip.score) if targets and clip.score is not None else None
    player = _Player(len(clip.time))
    cams = [-1] + [_camera_id(model, c) for c in CAMERAS]
    cam_i = cams.index(_camera_id(model, camera)) if camera else 0
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
            if not player.paused:
                clock += (now - last) * player.speed
            last = now
            if player.step:
                clock += player.step / clip.fps
                player.step = 0
            period = clip.duration + 1.0 / clip.fps
            clock %= period
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
                    if cams[cam_i] < 0:
                        handle.cam.type = mujoco.mjtCamera.mjCAMERA_FREE
                    else:
                        handle.cam.type = mujoco.mjtCamera.mjCAMERA_FIXED
                        handle.cam.fixedcamid = cams[cam_i]
                    applied_cam = cam_i
                # C is also MuJoCo's contact-point shortcut; keep that display off.
                handle.opt.flags[mujoco.mjtVisFlag.mjVIS_CONTACTPOINT] = 0
            left, right = frame_text(clip, frame, player.speed, player.paused)
            name = CAMERAS[cam_i - 1] if cams[cam_i] >= 0 else "free"
            handle.set_texts([
                (mujoco.mjtFontScale.mjFONTSCALE_150, mujoco.mjtGridPos.mjGRID_TOPLEFT,
                 left + "\ncamera", right + "\n" + name),
                (mujoco.mjtFontScale.mjFONTSCALE_150, mujoco.mjtGridPos.mjGRID_BOTTOMLEFT,
                 "keys", "space pause, <- -> step, up/down speed, C camera"),
            ])  # fmt: skip
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
