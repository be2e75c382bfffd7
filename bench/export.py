"""Export time: the 10-sign sentence of bench/realize.py to every export format.

    python bench/export.py [--repeats N]
    python bench/export.py --long 100000 [--formats .glb .gltf]

Realizes the sentence once at 50 fps, then writes it to .glb, .gltf, .bvh, .pose, .csv and
.html (the web player), best of N runs each (default 3), with the file sizes; writes
bench/results/export.json. ``--long FRAMES``: the sentence's frames repeated to FRAMES
frames, each format written once in a fresh process, with its wall time and the growth of
that process's peak resident memory while writing (the streamed formats stay flat);
writes bench/results/export_long.json (``--out``). ``--formats``: only these suffixes.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import mujoco
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from machine import cpu as _cpu
from realize import SIGNS, sentence

from azee_mj import timeline
from azee_mj.export import FORMATS, Motion, export
from azee_mj.export.motion import schedule_tuples
from azee_mj.model import load_model
from azee_mj.score import load_score

ROOT = Path(__file__).resolve().parent.parent


_ONE = """
import resource, sys, time
import numpy as np
from azee_mj.export import Motion, export
from azee_mj.model import load_model
import azee_mj.export.bvh, azee_mj.export.csv, azee_mj.export.gltf, azee_mj.export.player
import azee_mj.export.pose, pygltflib, pose_format
model = load_model()
q = np.load(sys.argv[1])
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
t0 = time.perf_counter()
try:
    export(Motion(q, 50.0, {}, "long"), sys.argv[2], model=model)
    what = "written"
except Exception as e:
    what = str(e)
wall = time.perf_counter() - t0
after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(wall, (after - before) / 1024, before / 1024, what, sep="\t")
"""


#: ``/usr/bin/time -f %M``: the peak resident memory [KB] of the whole process.
_TIME = ["/usr/bin/time", "-f", "%M"] if Path("/usr/bin/time").exists() else []


def long_exports(qpos: np.ndarray, frames: int, formats=FORMATS) -> list[dict]:
    """Each of ``formats`` for a ``frames``-frame motion (``qpos`` repeated) in a fresh
    process: wall time, peak memory growth while writing [MB], the process's peak resident
    memory [MB] (``/usr/bin/time -f %M``), file size."""
    rows = []
    reps = -(-frames // len(qpos))
    q = np.tile(qpos, (reps, 1))[:frames]
    with tempfile.TemporaryDirectory() as tmp:
        np.save(Path(tmp) / "q.npy", q)
        for suffix in formats:
            out = Path(tmp) / f"long{suffix}"
            p = subprocess.run(
                [*_TIME, sys.executable, "-c", _ONE, str(Path(tmp) / "q.npy"), str(out)],
                capture_output=True,
                text=True,
                check=True,
            )
            wall, grown, base, what = p.stdout.strip().split("\t", 3)
            peak = int(p.stderr.split()[-1]) / 1024 if _TIME else float(base) + float(grown)
            size = out.stat().st_size if out.exists() else 0
            rows.append(
                {
                    "format": suffix,
                    "export_s": float(wall),
                    "peak_growth_mb": float(grown),
                    "base_rss_mb": float(base),
                    "peak_rss_mb": peak,
                    "bytes": size,
                    "outcome": what,
                }
            )
            print(
                f"{suffix:6s} {float(wall):7.1f} s  +{float(grown):7.0f} MB  "
                f"peak {peak:7.0f} MB  "
                f"{size / 1e6:8.1f} MB  {what[:60]}",
                flush=True,
            )
            out.unlink(missing_ok=True)
    return rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--long", type=int, help="frames of a long motion (see the docstring)")
    ap.add_argument("--formats", nargs="+", default=list(FORMATS), help="with --long")
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "export_long.json"))
    args = ap.parse_args()
    names = [SIGNS[i % len(SIGNS)] for i in range(10)]
    score = load_score(sentence(names))
    t0 = time.perf_counter()
    r = timeline.realize(score, fps=50)
    realize_s = time.perf_counter() - t0
    if args.long:
        rows = long_exports(r.qpos, args.long, args.formats)
        Path(args.out).parent.mkdir(exist_ok=True)
        Path(args.out).write_text(
            json.dumps({"frames": args.long, "cpu": _cpu(), "rows": rows}, indent=1)
        )
        return
    motion = Motion(r.qpos, r.fps, schedule_tuples(r.schedule), "sentence")
    model = load_model()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for suffix in FORMATS:
            out = Path(tmp) / f"sentence{suffix}"
            best = np.inf
            for _ in range(args.repeats):
                t0 = time.perf_counter()
                export(motion, out, model=model)
                best = min(best, time.perf_counter() - t0)
            rows.append({"format": suffix, "export_s": best, "bytes": out.stat().st_size})
            print(f"{suffix:6s} {best:7.3f} s {out.stat().st_size / 1e6:7.2f} MB")
    out = {
        "machine": {
            "cpu": _cpu(),
            "cores": os.cpu_count(),
            "python": platform.python_version(),
            "mujoco": mujoco.__version__,
            "numpy": np.__version__,
        },
        "signs": names,
        "duration_s": score.duration,
        "frames": len(r.time),
        "fps": r.fps,
        "realize_s": realize_s,
        "repeats": args.repeats,
        "rows": rows,
    }
    (ROOT / "bench" / "results").mkdir(exist_ok=True)
    (ROOT / "bench" / "results" / "export.json").write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
