"""Offscreen rendering of a :class:`~azee_mj.markers.Clip`: frames with ``mujoco.Renderer``
on ``scene.xml``, encoded to video (.mp4), an animated .gif, a still or a contact sheet of
the key postures (.png).

Importing this module needs no display: the GL backend is chosen by :func:`gl_backend` the
first time something renders. Units: metres, seconds.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import subprocess
import sys
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from azee_mj import score as sc
from azee_mj.errors import AzeeError
from azee_mj.markers import Clip, Marker, Targets, add_markers, markers
from azee_mj.model import SCENE_PATH

#: The fixed cameras of ``scene.xml``, in the order ``C`` cycles them in the viewer.
CAMERAS = ("front", "side", "three-quarter", "top", "face")
#: Close-up cameras: drawn without shadows (the key light's shadow map, sized for the whole
#: signer, leaves jagged shadow edges across the face) and with every facet of the round
#: geoms (the face is made of them).
CLOSE_UPS = ("face",)
#: Backends tried, in order, when ``MUJOCO_GL`` is unset.
GL_BACKENDS = ("egl", "osmesa")
#: Default image size [px].
DEFAULT_SIZE = (640, 480)
#: Shadow map size of offscreen renders [px].
SHADOW_SIZE = 1024
#: Tessellation of capsules, spheres and ellipsoids in offscreen renders: (slices, stacks).
TESSELLATION = (16, 10)
#: Multisampling (samples per pixel) of :func:`scene_model` for callers that render with
#: ``mujoco.Renderer`` themselves.
MULTISAMPLES = 4
#: Antialiasing by supersampling: an antialiased frame is rendered this many times larger in
#: each direction (without multisampling) and scaled down with a bicubic filter. In software
#: GL this costs about two thirds of what 4x multisampling does, and is as close to a
#: 4x-supersampled reference (docs/benchmarks.md, "Rendering speed").
SUPERSAMPLE = 1.5
#: Encoded frames waiting for the encoder thread, at most.
QUEUE_FRAMES = 8
#: Frames handed to each render worker and not yet taken from it, at most (its shared-memory
#: slots).
WORKER_SLOTS = 3
#: Videos shorter than this many frames are rendered in this process only (starting a
#: worker costs about as much as rendering this many frames).
MIN_WORKER_FRAMES = 24

RENDER_HINT = "pip install azee_mj[render]"


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
        r = subprocess.run(
            [sys.executable, "-c", _PROBE, backend],
            env=env,
            check=False,
            capture_output=True,
            timeout=60,
        )
    except (OSError, subprocess.TimeoutExpired):
        return False
    return r.returncode == 0


def gl_backend(probe: Callable[[str], bool] | None = None) -> str:
    """The OpenGL backend for offscreen rendering, set up for ``mujoco.Renderer``.

    ``MUJOCO_GL`` is respected when set; otherwise ``egl`` then ``osmesa`` are tried (each
    in a short subprocess, since a failed attempt cannot be undone in this one) and the
    first that works is written to ``MUJOCO_GL``. Raises :class:`AzeeError` when none does.
    The choice is made once per process; a ``probe`` (backend -> works?) replaces the
    subprocess test and forces a new choice.
    """
    global _BACKEND
    if _BACKEND is not None and probe is None:
        return _BACKEND
    env = os.environ.get("MUJOCO_GL", "").strip().lower()
    if env:
        backend = env
    else:
        backend = next((b for b in GL_BACKENDS if (probe or _probe)(b)), "")
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


def scene_model(
    width: int = 0, height: int = 0, *, multisample: bool = True, close_up: bool = False
) -> mujoco.MjModel:
    """The signer on its floor with lights and cameras, with an offscreen buffer of exactly
    ``width`` x ``height`` (when given), set up for software GL (see docs/rendering.md).
    ``multisample``: 4x multisampling for a ``mujoco.Renderer`` on it (:class:`FrameRenderer`
    turns it off and supersamples instead); ``close_up``: every facet of the round geoms
    (for the :data:`CLOSE_UPS` cameras)."""
    m = mujoco.MjModel.from_xml_path(str(SCENE_PATH))
    if width and height:  # no larger than the image: memory
        m.vis.global_.offwidth, m.vis.global_.offheight = width, height
    q = m.vis.quality
    # Each looks the same at these sizes and costs less in software GL: a 1024 shadow map
    # (not 4096), and 16 x 10 facets per round geom (not 28 x 16; every geom is drawn in
    # several passes a frame, for the shadow map and the lights).
    q.shadowsize = min(q.shadowsize, SHADOW_SIZE)
    if not close_up:
        q.numslices = min(q.numslices, TESSELLATION[0])
        q.numstacks = min(q.numstacks, TESSELLATION[1])
    q.offsamples = min(q.offsamples, MULTISAMPLES) if multisample else 0
    return m


def render_size(size: tuple[int, int], antialias: bool = True) -> tuple[int, int]:
    """The (W, H) actually rendered for an image of ``size``: :data:`SUPERSAMPLE` times
    larger (rounded to even numbers) when antialiased, ``size`` otherwise."""
    if not antialias:
        return size
    return tuple(2 * round(v * SUPERSAMPLE / 2) for v in size)  # type: ignore[return-value]


def downscale(img: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """``img`` (H, W, 3) uint8 scaled to ``size`` (W, H) with a bicubic filter (Pillow's,
    which widens the filter when shrinking, so every rendered pixel counts)."""
    if (img.shape[1], img.shape[0]) == tuple(size):
        return img
    from PIL import Image

    return np.asarray(Image.fromarray(img).resize(tuple(size), Image.Resampling.BICUBIC))


def camera_id(model: mujoco.MjModel, camera: str) -> int:
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


class Decorations:
    """The markers drawn over each frame of ``clip`` (:func:`~azee_mj.markers.markers`)
    when ``targets`` is on, none otherwise; computed on a scene model of its own, so that
    they can be handed to a renderer in another process."""

    def __init__(self, clip: Clip, targets: bool = False):
        self.clip, self.on = clip, targets
        if targets:
            self.model = scene_model()
            self.data = mujoco.MjData(self.model)
            self.targets = Targets(clip.score) if clip.score is not None else None

    def __call__(self, frame: int | None) -> tuple[Marker, ...]:
        if not self.on or frame is None:
            return ()
        return tuple(markers(self.model, self.data, self.clip, frame, self.targets))


class FrameRenderer:
    """Renders postures of the signer offscreen from one camera (a ``mujoco.Renderer`` on
    ``scene.xml``, reused for every frame); ``targets`` adds the constraint markers of
    ``clip``. ``antialias`` renders :data:`SUPERSAMPLE` times larger (``render_size``) and
    scales down; ``antialias=False`` renders at ``size`` (about 1.5 times as fast in
    software GL, with jagged edges). Use as a context manager."""

    def __init__(
        self,
        clip: Clip | None = None,
        *,
        camera: str = "front",
        size=DEFAULT_SIZE,
        targets: bool = False,
        antialias: bool = True,
    ):
        gl_backend()
        self.size = (int(size[0]), int(size[1]))
        self.render_size = render_size(self.size, antialias)
        w, h = self.render_size
        self.model = scene_model(w, h, multisample=False, close_up=camera in CLOSE_UPS)
        self.cam = camera_id(self.model, camera)
        self.data = mujoco.MjData(self.model)
        self.clip = clip
        self.decorations = Decorations(clip, targets) if clip is not None else None
        self._full = np.empty((h, w, 3), np.uint8)
        try:
            self.r = mujoco.Renderer(self.model, height=h, width=w)
        except Exception as e:  # noqa: BLE001  (GL errors come in several types)
            raise AzeeError(f"offscreen rendering failed with MUJOCO_GL={_BACKEND}: {e}") from None
        # The floor's mirror image of the signer (reflectance 0.1) cannot be seen from the
        # fixed cameras, and drawing it costs a whole extra pass of the scene.
        self.r.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
        self.r.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = camera not in CLOSE_UPS
        # A context's first frame is not always its later frames bit for bit (software GL
        # at some sizes: one pixel off, measured); drawn once here, a frame is the same
        # whichever renderer draws it, first or not. This also compiles the shaders.
        self.draw(self.model.qpos0, out=self._full)

    def draw(
        self, q: np.ndarray, items: Sequence[Marker] = (), out: np.ndarray | None = None
    ) -> np.ndarray:
        """(H, W, 3) uint8 image of posture ``q`` with ``items`` drawn over it, at
        ``render_size`` (written into ``out`` if given)."""
        d = self.data
        d.qpos[:] = q
        mujoco.mj_forward(self.model, d)
        self.r.update_scene(d, camera=self.cam)
        if items:
            add_markers(self.r.scene, items)
        return self.r.render(out=out)

    def render(
        self, q: np.ndarray, frame: int | None = None, out: np.ndarray | None = None
    ) -> np.ndarray:
        """(H, W, 3) uint8 image of posture ``q`` at ``size`` (written into ``out`` if
        given); markers of clip frame ``frame`` if any."""
        items = self.decorations(frame) if self.decorations is not None else ()
        if self.render_size == self.size:
            return self.draw(q, items, out)
        img = downscale(self.draw(q, items, self._full), self.size)
        if out is None:
            return img
        out[:] = img
        return out

    def close(self) -> None:
        self.r.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def key_frames(clip: Clip) -> list[tuple[str, int]]:
    """(label, frame) of the key postures: the middle of each cstr block in time order, on
    the clip's clock (after the lead-in from rest; blocks with the same middle frame share
    one, their names joined), or without a score six evenly spaced frames labelled by their
    time."""
    if clip.score is not None:
        root = clip.score.root.path
        blocks = [b for b in clip.score.blocks() if b.kind is sc.BlockKind.CSTR]
        blocks.sort(key=lambda b: (0.5 * (b.start + b.end), b.path))
        byframe: dict[int, list[str]] = {}  # blocks sharing a middle frame share a tile
        for b in blocks:
            name = b.path[len(root) + 1 :] if b.path.startswith(root + ".") else b.path
            middle = clip.score_start + 0.5 * (b.start + b.end)
            byframe.setdefault(clip.frame_at(middle), []).append(name)
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


def check_render_options(out, size, fps, time, workers: int | None = None) -> None:
    """Raise :class:`AzeeError` for an output or option render cannot honour."""
    suffix = Path(out).suffix.lower()
    if suffix not in OUTPUT_SUFFIXES:
        raise AzeeError(
            f"-o: unknown output type {Path(out).suffix or '(none)'!r} of {out}; "
            f"valid: {', '.join(OUTPUT_SUFFIXES)}"
        )
    if suffix == ".mp4" and (size[0] % 2 or size[1] % 2):
        raise AzeeError(f"--size: an .mp4 needs an even width and height, got {size[0]}x{size[1]}")
    if fps is not None and not (0 < fps <= 240):
        raise AzeeError(f"--fps: must be in (0, 240], got {fps:g}")
    if time is not None and suffix != ".png":
        raise AzeeError(f"--time: only for a .png still, not {suffix}")
    if workers is not None and workers < 1:
        raise AzeeError(f"--jobs: must be at least 1, got {workers}")


def _need(module: str):
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError:
        raise AzeeError(
            f"rendering needs the package {module.split('.')[0]!r}: {RENDER_HINT}"
        ) from None


def render(
    clip: Clip,
    out: str | os.PathLike,
    *,
    camera: str = "front",
    size: tuple[int, int] = DEFAULT_SIZE,
    fps: float | None = None,
    time: float | None = None,
    targets: bool = False,
    antialias: bool = True,
    workers: int | None = None,
    progress: Callable[[float], None] | None = None,
) -> Path:
    """Render ``clip`` to ``out`` by its suffix, atomically.

    ``.mp4`` / ``.gif``: the video at ``fps`` (default: the clip's). ``.png``: the frame at
    ``time`` [s], or without it a contact sheet of :func:`key_frames`, labelled.
    ``antialias`` supersamples (:data:`SUPERSAMPLE`); ``antialias=False`` is about 1.5 times
    as fast in software GL, with visibly jagged edges. Video frames are rendered by
    ``workers`` processes (default :func:`video_workers`), each rendering every
    ``workers``-th frame, and encoded in order in a thread (an .mp4 is scaled down to
    ``size`` by the encoder). Raises :class:`AzeeError` for bad options (before anything is
    written) and when rendering fails; the output is then absent.
    """
    from azee_mj.files import atomic_path

    out = Path(out)
    check_render_options(out, size, fps, time, workers)
    if camera not in CAMERAS:
        raise AzeeError(f"--camera: unknown camera {camera!r}; valid: {', '.join(CAMERAS)}")
    if time is not None and not (-1e-9 <= time <= clip.duration + 1e-9):
        raise AzeeError(
            f"--time: {time:g} s is outside the rollout, which spans 0..{clip.duration:g} s"
        )
    suffix = out.suffix.lower()
    tick = progress or (lambda f: None)
    if suffix == ".mp4":
        _need("imageio_ffmpeg")
    imageio: Any = _need("imageio.v2") if suffix == ".mp4" else None
    pil: Any = _need("PIL.Image") if suffix in (".gif", ".png") else None
    if suffix == ".png":
        return _render_png(clip, out, camera, size, time, targets, antialias, tick, pil)
    vfps = float(fps or clip.fps)
    times, qs = resample(clip, vfps)
    deco = Decorations(clip, targets)
    items = [deco(clip.frame_at(t)) for t in times] if targets else None
    jobs = video_workers(len(qs), workers)
    opts = {"camera": camera, "size": size, "antialias": antialias, "workers": jobs}
    with atomic_path(out) as tmp:
        if suffix == ".mp4":
            _write_mp4(tmp, imageio, qs, items, vfps, opts, tick)
        else:
            _write_gif(tmp, pil, qs, items, vfps, opts, tick)
    return out


def _render_png(clip, out, camera, size, time, targets, antialias, tick, pil) -> Path:
    """The frame at ``time`` [s], or a labelled contact sheet, written as a PNG."""
    from azee_mj.files import atomic_path

    with FrameRenderer(clip, camera=camera, size=size, targets=targets, antialias=antialias) as fr:
        if time is not None:
            f = clip.frame_at(time)
            img = pil.fromarray(fr.render(clip.qpos[f], f))
        else:
            img = _contact_sheet(fr, clip, size, tick)
    with atomic_path(out) as tmp:
        img.save(tmp, format="PNG", optimize=True)
    tick(1.0)
    return out


def _write_mp4(tmp, imageio, qs, items, vfps: float, opts: dict, tick) -> None:
    """Encode the frames of ``qs`` to an H.264 .mp4 at ``vfps`` frames per second."""
    size = opts["size"]
    n = len(qs)
    rw, rh = render_size(size, opts["antialias"])
    # x264's veryfast preset: half the encoding CPU of its default, same quality.
    params = ["-preset", "veryfast"]
    if (rw, rh) != tuple(size):  # supersampled: ffmpeg scales down, in its process
        params += ["-vf", f"scale={size[0]}:{size[1]}:flags=bicubic"]
    w = imageio.get_writer(
        tmp,
        format="FFMPEG",
        fps=vfps,
        codec="libx264",
        quality=7,
        macro_block_size=2,
        ffmpeg_log_level="error",
        output_params=params,
    )
    with Encoder(w.append_data, (rh, rw, 3), close=w.close) as enc:
        for k, img in enumerate(render_frames(qs, items, **opts, buffer=enc.buffer)):
            enc.put(img)
            tick((k + 1) / n)


def _write_gif(tmp, pil, qs, items, vfps: float, opts: dict, tick) -> None:
    """Write the frames of ``qs``, downscaled and quantized, as a looping GIF."""
    n = len(qs)
    frames = []
    quantize = pil.Quantize.MEDIANCUT
    for k, img in enumerate(render_frames(qs, items, **opts)):
        im = pil.fromarray(downscale(img, opts["size"]))
        frames.append(im.quantize(colors=128, method=quantize))
        tick((k + 1) / n)
    frames[0].save(
        tmp,
        format="GIF",
        save_all=True,
        append_images=frames[1:],
        duration=round(1000.0 / vfps),
        loop=0,
        optimize=True,
    )


# ---------------------------------------------------------------------------------------
# Frames rendered by several processes
# ---------------------------------------------------------------------------------------


def video_workers(frames: int, workers: int | None = None) -> int:
    """Processes that render a video of ``frames`` frames: ``workers`` if given, else 2
    where 2 cores are usable; 1 (this process) for a video shorter than
    :data:`MIN_WORKER_FRAMES` or on one core."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cores = os.cpu_count() or 1
    if workers is None:
        workers = 1 if frames < MIN_WORKER_FRAMES else min(2, cores)
    return max(1, min(workers, frames))


def render_frames(
    qs: Sequence[np.ndarray] | np.ndarray,
    items: Sequence[Sequence[Marker]] | None = None,
    *,
    camera: str = "front",
    size: tuple[int, int] = DEFAULT_SIZE,
    antialias: bool = True,
    workers: int = 1,
    buffer: Callable[[], np.ndarray] | None = None,
) -> Iterator[np.ndarray]:
    """The images of postures ``qs`` (with markers ``items[k]`` over frame ``k``), in order,
    at :func:`render_size` (H, W, 3) uint8.

    ``workers`` > 1: this process and ``workers - 1`` worker processes, each with its own
    renderer, share the frames. This process renders from the start; a worker, once its
    renderer is up, is handed the next frames (up to :data:`WORKER_SLOTS` at once, into
    shared memory), while this process renders the frames after those. The frames are the
    same, bit for bit, whoever renders them. ``buffer()`` gives the array each frame is
    written into (a new one each time by default). A worker's error is raised here as
    :class:`AzeeError`; closing the generator early (or an error) stops the workers.

    The workers start with ``forkserver`` (``spawn`` where there is none) without running
    the caller's main script again: no ``if __name__ == "__main__":`` guard is needed.
    """
    n = len(qs)
    items = items if items is not None else [()] * n
    rw, rh = render_size(size, antialias)
    new = buffer or (lambda: np.empty((rh, rw, 3), np.uint8))
    if workers <= 1:
        with FrameRenderer(camera=camera, size=size, antialias=antialias) as fr:
            for q, it in zip(qs, items, strict=True):
                yield fr.draw(q, it, out=new())
        return
    with (
        _Workers(workers - 1, camera, size, antialias) as pool,
        FrameRenderer(camera=camera, size=size, antialias=antialias) as fr,
    ):
        here: dict[int, np.ndarray] = {}  # frames rendered here ahead of their turn
        nxt = 0  # the first frame not yet rendered here nor handed to a worker
        for k in range(n):
            while k not in here and not pool.has(k):
                nxt = pool.hand_out(nxt, min(n, k + AHEAD), lambda j: (qs[j], items[j]))
                if k in pool.sent:
                    if pool.poll(k):  # without waiting
                        break
                    if nxt < min(n, k + AHEAD):  # work here while the worker renders k
                        here[nxt] = fr.draw(qs[nxt], items[nxt], out=new())
                        nxt += 1
                    else:
                        pool.wait(k)
                else:  # k == nxt: no worker free for it
                    here[k] = fr.draw(qs[k], items[k], out=new())
                    nxt = k + 1
            if k in here:
                yield here.pop(k)
            else:
                img = new()
                pool.take(k, img)
                yield img


#: Frames a video's renderers may be ahead of the frame the encoder waits for, at most.
#: Fewer than the encoder's buffers (QUEUE_FRAMES + 2): the frames this process renders
#: ahead hold one each until their turn.
AHEAD = 9


@contextlib.contextmanager
def _main_not_rerun():
    """While a worker starts, hide the main module's file and spec from multiprocessing, so
    that the worker does not run the caller's script again (it needs only this module):
    a script without an ``if __name__ == "__main__":`` guard, or one read from standard
    input, starts workers as safely as ``python -c`` does."""
    main = sys.modules.get("__main__")
    hidden = {k: main.__dict__.pop(k) for k in ("__file__",) if main and k in main.__dict__}
    spec = getattr(main, "__spec__", None)
    if main is not None:
        main.__spec__ = None
    try:
        yield
    finally:
        if main is not None:
            main.__dict__.update(hidden)
            main.__spec__ = spec


class _Workers:
    """Render worker processes for :func:`render_frames`, each with :data:`WORKER_SLOTS`
    shared-memory frame slots; this process hands each frame to one worker and a free slot
    of it."""

    def __init__(self, count: int, camera: str, size, antialias: bool):
        from azee_mj.lifeline import worker_context

        ctx: Any = worker_context(["azee_mj.render"])
        w, h = render_size(size, antialias)
        job = _WorkerJob(gl_backend(), camera, (int(size[0]), int(size[1])), antialias)
        self.procs, self.todo, self.done, self.views = [], [], [], []
        self.up = [False] * count  # the worker's renderer is ready
        self.free = [list(range(WORKER_SLOTS)) for _ in range(count)]
        self.sent: dict[int, tuple[int, int]] = {}  # frame -> (worker, slot)
        self.ready: set[int] = set()  # frames rendered by workers, not taken yet
        for i in range(count):
            slots = ctx.RawArray("B", WORKER_SLOTS * w * h * 3)
            self.views.append(np.frombuffer(slots, np.uint8).reshape(WORKER_SLOTS, h, w, 3))
            todo_r, todo_w = ctx.Pipe(duplex=False)
            done_r, done_w = ctx.Pipe(duplex=False)
            self.todo.append(todo_w)
            self.done.append(done_r)
            p = ctx.Process(
                target=_render_worker,
                daemon=True,
                name=f"azee-mj render {i + 1}",
                args=(job, slots, todo_r, done_w),
            )
            with _main_not_rerun():
                p.start()
            self.procs.append(p)
            todo_r.close()  # the worker's ends: a worker that dies closes its pipes
            done_w.close()

    def hand_out(self, nxt: int, stop: int, task: Callable[[int], tuple]) -> int:
        """Send frames ``nxt``, ``nxt + 1``, ... (before ``stop``; ``task(frame)`` gives its
        posture and markers) to workers that are up and have a free slot; the first frame
        not sent."""
        self._drain()
        for i in range(len(self.procs)):
            while self.up[i] and self.free[i] and nxt < stop:
                slot = self.free[i].pop()
                q, items = task(nxt)
                self.todo[i].send((nxt, slot, np.asarray(q, float), tuple(items)))
                self.sent[nxt] = (i, slot)
                nxt += 1
        return nxt

    def has(self, j: int) -> bool:
        return j in self.ready

    def poll(self, j: int) -> bool:
        """Whether frame ``j`` (sent) is rendered, without waiting."""
        self._drain()
        return j in self.ready

    def wait(self, j: int) -> None:
        """Wait until frame ``j`` (sent) is rendered."""
        i = self.sent[j][0]
        while j not in self.ready:
            if self.done[i].poll(0.5):
                self._receive(i)
            elif self.procs[i].exitcode is not None:
                raise AzeeError(
                    f"render worker {i + 1} stopped (exit code {self.procs[i].exitcode})"
                )

    def take(self, j: int, out: np.ndarray) -> None:
        """Copy frame ``j`` into ``out`` and free its slot."""
        i, slot = self.sent.pop(j)
        self.ready.discard(j)
        out[:] = self.views[i][slot]
        self.free[i].append(slot)

    def _drain(self) -> None:
        for i in range(len(self.procs)):
            while self.done[i].poll():
                self._receive(i)

    def _receive(self, i: int) -> None:
        msg = self.done[i].recv()
        if msg == "up":
            self.up[i] = True
        elif isinstance(msg, int):
            self.ready.add(msg)
        else:
            raise AzeeError(str(msg))

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        for c in self.todo:
            with contextlib.suppress(OSError):
                c.send(None)
        for p in self.procs:
            p.join(timeout=0 if exc[0] is not None else 5)
            if p.is_alive():
                p.terminate()
                p.join()
        for c in self.todo + self.done:
            c.close()


@dataclasses.dataclass(frozen=True)
class _WorkerJob:
    backend: str
    camera: str
    size: tuple[int, int]
    antialias: bool


def _render_worker(job: _WorkerJob, slots, todo, done) -> None:
    """One render worker: ``up`` on the pipe ``done`` once its renderer works, then for
    each ``(frame, slot, q, items)`` from the pipe ``todo`` the image into ``slot`` and
    ``frame`` on ``done`` (or an error message, then it stops), until ``None``."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C: the parent stops the workers
    try:
        os.environ["MUJOCO_GL"] = job.backend
        with FrameRenderer(camera=job.camera, size=job.size, antialias=job.antialias) as fr:
            w, h = fr.render_size
            views = np.frombuffer(slots, np.uint8).reshape(WORKER_SLOTS, h, w, 3)
            done.send("up")
            while (task := todo.recv()) is not None:
                j, slot, q, items = task
                fr.draw(q, items, out=views[slot])
                done.send(j)
    except EOFError:  # the parent is gone
        pass
    except Exception as e:  # noqa: BLE001  (reported to the parent, which raises it)
        with contextlib.suppress(OSError):
            done.send(
                str(e) if isinstance(e, AzeeError) else f"rendering failed: {type(e).__name__}: {e}"
            )


class Encoder:
    """Feeds frames to ``write`` (e.g. a video writer's ``append_data``) in a thread, so
    encoding overlaps rendering. Frames go through a bounded queue in reused buffers of
    ``shape`` (uint8): :meth:`buffer` hands out a free one (waiting while ``queue`` frames
    are in flight), :meth:`put` queues it. Leaving the ``with`` block waits for the last
    frame and calls ``close``; an error of ``write`` is raised in the caller's thread."""

    def __init__(
        self,
        write: Callable[[np.ndarray], Any],
        shape: tuple[int, ...],
        close: Callable[[], Any] | None = None,
        queue: int = QUEUE_FRAMES,
    ):
        import queue as q
        import threading

        self._write, self._close = write, close
        self._todo: q.Queue = q.Queue(maxsize=queue)
        self._free: q.Queue = q.Queue()
        for _ in range(queue + 2):
            self._free.put(np.empty(shape, np.uint8))
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name="azee-mj encoder", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while (frame := self._todo.get()) is not None:
            if self._error is None:
                try:
                    self._write(frame)
                except BaseException as e:  # noqa: BLE001  (re-raised in the caller)
                    self._error = e
            self._free.put(frame)

    def buffer(self) -> np.ndarray:
        """A free frame buffer to render into."""
        self._raise()
        return self._free.get()

    def put(self, frame: np.ndarray) -> None:
        """Queue ``frame`` (a buffer from :meth:`buffer`) for writing."""
        self._raise()
        self._todo.put(frame)

    def _raise(self) -> None:
        if self._error is not None:
            raise self._error

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self._todo.put(None)
        self._thread.join()
        if exc[0] is not None:  # failing, interrupted or terminated: that error wins
            with contextlib.suppress(Exception):
                if self._close is not None:
                    self._close()
            return
        try:
            if self._close is not None:
                self._close()
        finally:
            self._raise()


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
