"""Export time: the 10-sign sentence of bench/realize.py to every export format.

    python bench/export.py [--repeats N]

Realizes the sentence once at 50 fps, then writes it to .glb, .gltf, .bvh, .pose, .csv and
.html (the web player), best of N runs each (default 3), with the file sizes; writes
bench/results/export.json.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import mujoco
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from realize import SIGNS, _cpu, sentence

from azee_mj import timeline
from azee_mj.export import FORMATS, Motion, export
from azee_mj.export.motion import schedule_tuples
from azee_mj.model import load_model
from azee_mj.score import load_score

ROOT = Path(__file__).resolve().parent.parent


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    names = [SIGNS[i % len(SIGNS)] for i in range(10)]
    score = load_score(sentence(names))
    t0 = time.perf_counter()
    r = timeline.realize(score, fps=50)
    realize_s = time.perf_counter() - t0
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
