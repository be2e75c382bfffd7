"""Offscreen rendering speed: frames per second of 640x480 MP4 renders, end to end.

    MUJOCO_GL=egl python bench/render.py [--runs 3] [--examples bien arbre pointing]

Each example is realized once (not timed), then rendered to an .mp4 at its own 50 fps with
these settings, interleaved in every run so that they share the machine's load:

- ``before``: the settings and loop this package used before issue 11 (scene.xml's 28 x 16
  facets, floor reflection, 1024 shadow map, 4x multisampling; each frame copied, then
  written to the encoder in the rendering thread);
- ``msaa, 1 process``: the default before supersampling and render workers (16 x 10
  facets, no reflection, 4x multisampling, one process, frames encoded in a thread);
- ``default``: :func:`azee_mj.render.render` as it is now (supersampled 1.5x without
  multisampling, scaled down by the encoder; two render worker processes on 2 cores);
- ``supersampled, 1 process``: the same in this process only (``workers=1``);
- ``no-antialias`` and ``no-antialias, 1 process``: the same two with ``antialias=False``.

Reports the median over runs of frames per second (wall clock, from the call to the closed
file, worker start-up included) and of CPU time per frame (this process's threads, the
encoder and the render workers), and writes bench/results/render.json. The target (issue
11): at least 20 frames per second at 640x480.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import statistics
import tempfile
import time
from pathlib import Path

import mujoco
import numpy as np
from machine import cpu as cpu_model

from azee_mj import render as rd
from azee_mj.cli import load_clip

ROOT = Path(__file__).resolve().parent.parent
SIZE = (640, 480)


def mp4_writer(out: Path, fps: float, **extra):
    """The imageio H.264 writer both earlier settings used, with ``extra`` options."""
    import imageio.v2 as imageio

    return imageio.get_writer(
        out,
        format="FFMPEG",
        fps=fps,
        codec="libx264",
        quality=7,
        macro_block_size=2,
        ffmpeg_log_level="error",
        **extra,
    )


def render_before(clip, out: Path) -> None:
    """The MP4 loop and scene settings of the package before issue 11, for comparison."""
    w, h = SIZE
    m = mujoco.MjModel.from_xml_path(str(rd.SCENE_PATH))
    m.vis.global_.offwidth, m.vis.global_.offheight = (
        max(m.vis.global_.offwidth, w),
        max(m.vis.global_.offheight, h),
    )
    m.vis.quality.shadowsize = min(m.vis.quality.shadowsize, 1024)
    d = mujoco.MjData(m)
    cam = rd.camera_id(m, "front")
    with mujoco.Renderer(m, height=h, width=w) as r:
        writer = mp4_writer(out, clip.fps)
        try:
            for q in clip.qpos:
                d.qpos[:] = q
                mujoco.mj_forward(m, d)
                r.update_scene(d, camera=cam)
                writer.append_data(r.render().copy())
        finally:
            writer.close()


def render_msaa(clip, out: Path) -> None:
    """The default of the package before supersampling and render workers: 4x
    multisampling, one process, frames rendered into reused buffers and encoded in a thread."""
    w, h = SIZE
    m = rd.scene_model(w, h)  # 4x multisampling
    d = mujoco.MjData(m)
    cam = rd.camera_id(m, "front")
    with mujoco.Renderer(m, height=h, width=w) as r:
        r.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
        writer = mp4_writer(out, clip.fps, output_params=["-preset", "veryfast"])
        with rd.Encoder(writer.append_data, (h, w, 3), close=writer.close) as enc:
            for q in clip.qpos:
                d.qpos[:] = q
                mujoco.mj_forward(m, d)
                r.update_scene(d, camera=cam)
                enc.put(r.render(out=enc.buffer()))


VARIANTS = {
    "before": render_before,
    "msaa, 1 process": render_msaa,
    "default": lambda clip, out: rd.render(clip, out, size=SIZE),
    "supersampled, 1 process": lambda clip, out: rd.render(clip, out, size=SIZE, workers=1),
    "no-antialias": lambda clip, out: rd.render(clip, out, size=SIZE, antialias=False),
    "no-antialias, 1 process": lambda clip, out: rd.render(
        clip, out, size=SIZE, antialias=False, workers=1
    ),
}


def cpu_seconds() -> float:
    """CPU time of this process (all threads), of its finished children (the encoder) and of
    its live children with their finished children (the forkserver and its render workers)
    [s]."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    total = own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime
    tick = os.sysconf("SC_CLK_TCK")
    for task in Path(f"/proc/{os.getpid()}/task").iterdir():
        for pid in (task / "children").read_text().split():
            try:  # utime, stime, cutime, cstime: fields 14 to 17, after the ")" of the name
                f = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
            except OSError:  # ended meanwhile
                continue
            total += sum(int(x) for x in f[11:15]) / tick
    return total


def measure(fn, clip, tmp: Path) -> tuple[float, float]:
    """(frames per second, CPU seconds per frame) of one render of ``clip``."""
    out = tmp / "bench.mp4"
    c0, t0 = cpu_seconds(), time.perf_counter()
    fn(clip, out)
    wall, cpu = time.perf_counter() - t0, cpu_seconds() - c0
    out.unlink()
    n = len(clip.qpos)
    return n / wall, cpu / n


def gl_renderer() -> str:
    """The OpenGL renderer string (e.g. llvmpipe for Mesa's software rasterizer)."""
    rd.gl_backend()
    m = rd.scene_model(64, 64, multisample=False)
    with mujoco.Renderer(m, height=64, width=64) as r:
        r.render()
        try:
            from OpenGL import GL

            return GL.glGetString(GL.GL_RENDERER).decode()
        except Exception as e:  # noqa: BLE001  (report, don't fail the benchmark)
            return f"unknown ({e})"


def machine() -> dict:
    return {
        "cpu": cpu_model(),
        "cores": len(os.sched_getaffinity(0)),
        "load_average": os.getloadavg(),
        "python": platform.python_version(),
        "mujoco": mujoco.__version__,
        "MUJOCO_GL": rd.gl_backend(),
        "gl_renderer": gl_renderer(),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--examples", nargs="+", default=["bien", "arbre", "pointing"])
    ap.add_argument(
        "--variants",
        nargs="+",
        choices=list(VARIANTS),
        default=list(VARIANTS),
        metavar="NAME",
        help="settings to run (default: all; 'before' is the base)",
    )
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "render.json"))
    args = ap.parse_args()
    variants = {v: VARIANTS[v] for v in VARIANTS if v in args.variants or v == "before"}
    info = machine()
    clips = {n: load_clip(ROOT / "examples" / f"{n}.json") for n in args.examples}
    samples: dict[str, dict[str, list]] = {v: {"fps": [], "cpu": [], "load": []} for v in variants}
    with tempfile.TemporaryDirectory() as tmp:
        for run in range(args.runs):
            for v, fn in variants.items():
                frames, wall, cpu = 0, 0.0, 0.0
                for clip in clips.values():
                    fps, cpf = measure(fn, clip, Path(tmp))
                    n = len(clip.qpos)
                    frames, wall, cpu = frames + n, wall + n / fps, cpu + cpf * n
                samples[v]["fps"].append(frames / wall)
                samples[v]["cpu"].append(cpu / frames)
                samples[v]["load"].append(os.getloadavg()[0])
                print(
                    f"run {run + 1}: {v:24s} {frames / wall:5.1f} fps, "
                    f"{1e3 * cpu / frames:6.1f} ms CPU a frame, load {os.getloadavg()[0]:.1f}",
                    flush=True,
                )
    info["load_average_after"] = os.getloadavg()
    result = {
        "machine": info,
        "size": SIZE,
        "examples": args.examples,
        "runs": args.runs,
        "frames": int(sum(len(c.qpos) for c in clips.values())),
        "variants": {},
    }
    base = statistics.median(samples["before"]["fps"])
    for v, s in samples.items():
        fps, cpu = statistics.median(s["fps"]), statistics.median(s["cpu"])
        result["variants"][v] = {
            "fps_median": fps,
            "fps_runs": s["fps"],
            "cpu_ms_per_frame_median": 1e3 * cpu,
            "cpu_ms_per_frame_runs": [1e3 * c for c in s["cpu"]],
            "load_average_1min_runs": s["load"],
            "speedup_vs_before": fps / base,
        }
    print(json.dumps(result, indent=1))
    Path(args.out).write_text(json.dumps(result, indent=1) + "\n")
    print("| settings | frames per second (median) | runs | CPU per frame [ms] | vs before |")
    print("| --- | --- | --- | --- | --- |")
    for v, r in result["variants"].items():
        runs = ", ".join(f"{x:.1f}" for x in r["fps_runs"])
        print(
            f"| {v} | {r['fps_median']:.1f} | {runs} | {r['cpu_ms_per_frame_median']:.0f} | "
            f"{r['speedup_vs_before']:.2f}x |"
        )


if __name__ == "__main__":
    np.set_printoptions(precision=3)
    main()
