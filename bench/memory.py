"""Memory and time of ``azee-mj realize`` on long scores: peak RSS and wall time.

    python bench/memory.py [--durations 30 60 150 300] [--markdown]

Builds scores of about the given durations [s] by chaining the bundled examples (each
example's root becomes a ``sync`` child, 0.1 s apart, repeated), realizes each at 50 fps in
a fresh process (``python -m azee_mj.cli realize``, which also saves the rollout) and reads
that process's peak resident set size (``wait4``). Writes bench/results/memory.json. The
target (issue 14): memory linear in the score and a 300 s score under 250 MB peak.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SIGNS = ["bien", "pointing", "arbre", "armoire", "info-about", "penser", "nicht-sondern"]


def long_score(duration: float) -> dict:
    """A score chaining the examples until it lasts at least ``duration`` [s]."""
    children, t, i = [], 0.0, 0
    while t < duration:
        s = json.loads((ROOT / "examples" / f"{SIGNS[i % len(SIGNS)]}.json").read_text())
        root = s["root"]
        d = root["end"] - root["start"]
        children.append(
            {**root, "name": f"S{i}_{root['name']}", "start": round(t, 6), "end": round(t + d, 6)}
        )
        t += d + 0.1
        i += 1
    return {
        "format": "azee-score",
        "version": 1,
        "strong_side": "R",
        "root": {
            "name": "LONG",
            "kind": "sync",
            "start": 0.0,
            "end": round(t, 6),
            "children": children,
        },
    }


def measure(duration: float, tmp: Path) -> dict:
    score = long_score(duration)
    path = tmp / f"long{duration:g}.json"
    path.write_text(json.dumps(score))
    out = tmp / f"long{duration:g}.npz"
    env = dict(os.environ, PYTHONPATH=str(ROOT), OMP_NUM_THREADS="1")
    t0 = time.perf_counter()
    p = subprocess.Popen(
        [sys.executable, "-m", "azee_mj.cli", "realize", str(path), "-o", str(out)],
        env=env,
        stdout=subprocess.PIPE,
        text=True,
    )
    _, status, usage = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t0
    line = p.stdout.read().splitlines()[0] if p.stdout else ""
    return {
        "duration_s": score["root"]["end"],
        "exit": os.waitstatus_to_exitcode(status),
        "peak_rss_mb": usage.ru_maxrss / 1024,
        "wall_s": wall,
        "file_mb": out.stat().st_size / 1e6 if out.exists() else None,
        "summary": line,
    }


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--durations", type=float, nargs="+", default=[30, 60, 150, 300])
    ap.add_argument("--markdown", action="store_true")
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for dur in args.durations:
            rows.append(measure(dur, Path(d)))
            r = rows[-1]
            print(
                f"{r['duration_s']:7.1f} s: peak {r['peak_rss_mb']:6.1f} MB, {r['wall_s']:6.1f} s"
                f" wall, exit {r['exit']}; {r['summary']}",
                flush=True,
            )
    res = ROOT / "bench" / "results"
    res.mkdir(exist_ok=True)
    (res / "memory.json").write_text(json.dumps(rows, indent=1) + "\n")
    if args.markdown:
        print("| score [s] | peak RSS [MB] | wall time [s] | rollout file [MB] |")
        print("| --- | --- | --- | --- |")
        for r in rows:
            print(
                f"| {r['duration_s']:.1f} | {r['peak_rss_mb']:.0f} | {r['wall_s']:.1f} | "
                f"{r['file_mb']:.1f} |"
            )


if __name__ == "__main__":
    main()
