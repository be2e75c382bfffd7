"""Realizer speed: real-time factor of a sentence, and how cost grows with duration/blocks.

    python bench/realize.py [--quick] [--repeat 3]

Builds sentences by chaining the bundled examples (each example's root becomes a `sync`
child, one after the other), realizes them at 50 fps on one core (the best wall-clock and
the best CPU time of ``--repeat`` runs each) and writes bench/results/realize.json. The
target (issue 4): at least 20x faster than real time for a sentence of several signs with
both hands, holds and transpaths; cost linear in duration and in blocks. The CPU time of
the same sentence side by side with other commits: ``bench/realize_cpu.py``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import mujoco
import numpy as np
from machine import cpu

from azee_mj import timeline
from azee_mj.ergonomics import ergonomics
from azee_mj.schedule import make_solver
from azee_mj.score import load_score

ROOT = Path(__file__).resolve().parent.parent
SIGNS = ["bien", "pointing", "arbre", "info-about", "penser"]


def sentence(names: list[str]) -> dict:
    """A score chaining the examples ``names`` (strong side R), 0.1 s apart."""
    children, t = [], 0.0
    for i, n in enumerate(names):
        s = json.loads((ROOT / "examples" / f"{n}.json").read_text())
        root = s["root"]
        d = root["end"] - root["start"]
        children.append({**root, "name": f"S{i}_{root['name']}", "start": t, "end": t + d})
        t += d + 0.1
    return {
        "format": "azee-score",
        "version": 1,
        "strong_side": "R",
        "root": {"name": "SENTENCE", "kind": "sync", "start": 0.0, "end": t, "children": children},
    }


def count_blocks(score) -> int:
    return sum(1 for b in score.blocks() if b.kind.value != "sync")


def run(names, solver, repeats=1):
    score = load_score(sentence(names))
    best = cpu = None
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        r = timeline.realize(score, fps=50, solver=solver)
        dt, dc = time.perf_counter() - t0, time.process_time() - c0
        best = dt if best is None else min(best, dt)
        cpu = dc if cpu is None else min(cpu, dc)
    return {
        "signs": names,
        "duration_s": score.duration,
        "blocks": count_blocks(score),
        "frames": len(r.time),
        "realize_s": best,
        # the process's CPU time: on a shared machine the wall-clock time is mostly waiting
        "realize_cpu_s": cpu,
        "realtime_factor": score.duration / best,
        "ik_problems": r.stats.problems,
        "key_problems": r.stats.key_problems,
        "iterations": r.stats.iterations,
        "not_converged": r.stats.not_converged,
        "constraints_ok": int(sum(bool(t.ok) for t in r.traces)),
        "constraints": len(r.traces),
        **naturalness(r, solver),
        "ms_per_frame": 1e3 * best / len(r.time),
        "cpu_ms_per_frame": 1e3 * cpu / len(r.time),
        "iterations_per_frame": r.stats.iterations / len(r.time),
    }


def naturalness(r, solver) -> dict:
    """Fastest joint [rad/s] and the worst trunk and head angles from upright [deg] over the
    rollout (every 5th frame), by ``azee_mj.ergonomics``."""
    speed = float(np.abs(np.diff(r.qpos, axis=0)).max() * r.fps) if len(r.time) > 1 else 0.0
    e = [ergonomics(solver.model, q) for q in r.qpos[::5]]
    return {
        "max_joint_speed": speed,
        "worst_trunk_deg": float(np.degrees(max(x.trunk_angle for x in e))),
        "worst_head_deg": float(np.degrees(max(x.head_angle for x in e))),
    }


def mirror_error(names, solver) -> float:
    """Worst site distance [m] between the left-handed sentence and the mirror of the
    right-handed one."""
    from azee_mj.mirror import mirror_name

    s = sentence(names)
    right = timeline.realize(load_score(s), fps=50, solver=solver)
    left = timeline.realize(load_score({**s, "strong_side": "L"}), fps=50, solver=solver)
    idx = [list(right.site_names).index(mirror_name(n)) for n in left.site_names]
    return float(np.abs(right.site_pos[:, idx] * np.array([1.0, -1.0, 1.0]) - left.site_pos).max())


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument(
        "--repeat",
        type=int,
        default=3,
        help="realizations of each sentence; its time is the best (a noisy machine)",
    )
    args = ap.parse_args()
    solver = make_solver()
    rows = []
    lengths = [1, 2] if args.quick else [1, 2, 3, 4, 5, 6, 8, 10]
    for n in lengths:
        names = [SIGNS[i % len(SIGNS)] for i in range(n)]
        rows.append(run(names, solver, args.repeat))
        r = rows[-1]
        print(
            f"{n:2d} signs {r['duration_s']:5.2f} s {r['blocks']:3d} blocks: {r['realize_s']:6.3f} s"
            f" ({r['realtime_factor']:5.1f}x real time; {r['realize_cpu_s']:6.3f} s CPU),"
            f" {r['ik_problems']} IK problems,"
            f" {r['constraints_ok']}/{r['constraints']} ok, {r['ms_per_frame']:.2f} ms and"
            f" {r['iterations_per_frame']:.1f} iterations per frame, fastest joint"
            f" {r['max_joint_speed']:.1f} rad/s, trunk / head up to {r['worst_trunk_deg']:.1f} /"
            f" {r['worst_head_deg']:.1f} deg"
        )
    d = np.array([r["duration_s"] for r in rows])
    c = np.array([r["realize_s"] for r in rows])
    fit = np.polyfit(d, c, 1)
    resid = c - np.polyval(fit, d)
    # pointing names the right and left loci (^Rssp, ^Lssp): not the same sign mirrored
    mirrorable = [n for n in rows[-1]["signs"] if n != "pointing"]
    mirror_mm = 1000.0 * mirror_error(mirrorable, solver)
    print(f"{len(mirrorable)} signs left-handed vs the mirror of right-handed: {mirror_mm:.3f} mm")
    out = {
        "repeat": args.repeat,
        "left_handed_mirror_mm": mirror_mm,
        "machine": {
            "cpu": cpu(),
            "cores": os.cpu_count(),
            "python": platform.python_version(),
            "mujoco": mujoco.__version__,
            "numpy": np.__version__,
        },
        "rows": rows,
        "linear_fit": {
            "seconds_per_score_second": float(fit[0]),
            "intercept_s": float(fit[1]),
            "r2": 1 - float(resid @ resid) / float(((c - c.mean()) ** 2).sum()),
        },
    }
    (ROOT / "bench" / "results").mkdir(exist_ok=True)
    (ROOT / "bench" / "results" / "realize.json").write_text(json.dumps(out, indent=1))
    print(f"linear fit: {fit[0]:.3f} s per score second, r2 {out['linear_fit']['r2']:.3f}")


if __name__ == "__main__":
    main()
