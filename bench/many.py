"""Throughput of realizing many scores: one process against two, in the same run.

    python bench/many.py [--copies 2] [--runs 3]

Realizes every bundled example ``--copies`` times (``copies x 7`` scores at 50 fps, each
written to its own .npz) with :func:`azee_mj.batch.realize_many`, the function behind
``azee-mj realize A.json B.json ... -o DIR/``: with ``workers=1`` (in this process) and
``workers=2`` (a pool of two worker processes, start-up included), alternating in every run
so that both see the same load. Reports scores per second and the ratio of the medians, and
writes bench/results/many.json. The target (issue 11): two processes >= 1.8x one.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import statistics
import tempfile
import time
from pathlib import Path

import machine
import mujoco

from azee_mj.batch import plan, realize_many, usable_cores

ROOT = Path(__file__).resolve().parent.parent


def scores(copies: int, tmp: Path) -> list[Path]:
    """``copies`` copies of every bundled example, each with its own name."""
    out = []
    for k in range(copies):
        for src in sorted((ROOT / "examples").glob("*.json")):
            dst = tmp / "in" / f"{src.stem}-{k}.json"
            dst.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(src, dst)
            out.append(dst)
    return out


def one_run(paths: list[Path], workers: int, tmp: Path) -> tuple[float, float, float]:
    """Scores per second of realizing ``paths`` with ``workers`` processes, and the seconds
    of CPU and elapsed time the scores took inside the workers, summed."""
    out = tmp / f"out-{workers}"
    out.mkdir()  # the output rule: an output's directory must exist
    t0 = time.perf_counter()
    outcomes = realize_many(plan(paths, out), workers=workers)
    dt = time.perf_counter() - t0
    if not all(o.ok for o in outcomes):
        raise SystemExit("; ".join(o.error for o in outcomes if not o.ok))
    shutil.rmtree(out)
    return len(paths) / dt, sum(o.cpu for o in outcomes), sum(o.wall for o in outcomes)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--copies", type=int, default=2)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "many.json"))
    args = ap.parse_args()
    info = {
        "cpu": machine.cpu(),
        "cores": usable_cores(),
        "load_average_before": os.getloadavg(),
        "python": platform.python_version(),
        "mujoco": mujoco.__version__,
    }
    rates: dict[int, list[float]] = {1: [], 2: []}
    cpu: dict[int, list[float]] = {1: [], 2: []}
    busy: dict[int, list[float]] = {1: [], 2: []}
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        paths = scores(args.copies, tmp)
        for run in range(args.runs):
            for w in (1, 2):
                rate, c, b = one_run(paths, w, tmp)
                rates[w].append(rate)
                cpu[w].append(c)
                busy[w].append(b)
                print(
                    f"run {run + 1}: {w} process(es): {rate:.2f} scores/s; in the workers "
                    f"{c:.2f} s CPU, {b:.2f} s elapsed",
                    flush=True,
                )
    info["load_average_after"] = os.getloadavg()
    m1, m2 = statistics.median(rates[1]), statistics.median(rates[2])
    result = {
        "machine": info,
        "scores": len(paths),
        "fps": 50,
        "runs": args.runs,
        "scores_per_s": {"1": rates[1], "2": rates[2]},
        "median_1": m1,
        "median_2": m2,
        "ratio_2_over_1": m2 / m1,
        "ratio_per_run": [b / a for a, b in zip(rates[1], rates[2], strict=True)],
        "worker_cpu_s": {"1": cpu[1], "2": cpu[2]},
        "worker_elapsed_s": {"1": busy[1], "2": busy[2]},
        "cpu_share_1": statistics.median(c / b for c, b in zip(cpu[1], busy[1], strict=True)),
    }
    Path(args.out).write_text(json.dumps(result, indent=1) + "\n")
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
