"""Memory and time of ``azee-mj realize`` (and ``azee-mj check``) on long scores.

    python bench/memory.py [--durations 60 300 900 1800 3600] [--check] [--markdown]

Builds scores of about the given durations [s] by chaining the bundled examples (each
example's root becomes a ``sync`` child, 0.1 s apart, repeated), realizes each at 50 fps in
a fresh process (``python -m azee_mj.cli realize``, which also saves the rollout) and reads
that process's peak resident set size (``wait4``) and its realization time (the summary
line's); with ``--check``, also ``azee-mj check`` on the rollout. Reports the real-time
factor (seconds of score per second of realization), the growth of the peak per minute of
score between the first duration of 300 s or more and the last, and writes
bench/results/memory.json. Targets (issue 25): a 60-minute score under 400 MB peak, growth
<= 5 MB per minute of score from 5 to 60 minutes, and the real-time factor of 60 minutes
within 20 % of one minute's.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SIGNS = ["bien", "pointing", "arbre", "armoire", "info-about", "penser", "nicht-sondern"]


def long_score(duration: float) -> dict:
    """A score chaining the examples as long as it lasts at most ``duration`` [s] (one hour,
    the longest score, fits)."""
    children, t, i = [], 0.0, 0
    while True:
        s = json.loads((ROOT / "examples" / f"{SIGNS[i % len(SIGNS)]}.json").read_text())
        root = s["root"]
        d = root["end"] - root["start"]
        if t + d > duration:
            break
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
            "end": round(t - 0.1, 6),
            "children": children,
        },
    }


def _run(argv: list[str]) -> tuple[int, float, float, str]:
    """Exit status, peak RSS [MB], wall time [s] and first output line of a fresh process."""
    env = dict(os.environ, PYTHONPATH=str(ROOT), OMP_NUM_THREADS="1")
    t0 = time.perf_counter()
    p = subprocess.Popen(
        [sys.executable, "-m", "azee_mj.cli", *argv], env=env, stdout=subprocess.PIPE, text=True
    )
    _, status, usage = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t0
    out = p.stdout.read().splitlines() if p.stdout else []
    return os.waitstatus_to_exitcode(status), usage.ru_maxrss / 1024, wall, out[0] if out else ""


def measure(duration: float, tmp: Path, check: bool) -> dict:
    score = long_score(duration)
    path = tmp / f"long{duration:g}.json"
    path.write_text(json.dumps(score))
    out = tmp / f"long{duration:g}.npz"
    code, peak, wall, line = _run(["realize", str(path), "-o", str(out)])
    m = re.search(r"in ([0-9.]+) s;", line)
    realize_s = float(m.group(1)) if m else float("nan")
    row = {
        "duration_s": score["root"]["end"],
        "exit": code,
        "peak_rss_mb": peak,
        "wall_s": wall,
        "realize_s": realize_s,
        "real_time_factor": score["root"]["end"] / realize_s,
        "file_mb": out.stat().st_size / 1e6 if out.exists() else None,
        "summary": line,
    }
    if check:
        code, peak, wall, _ = _run(["check", str(out)])
        row |= {"check_exit": code, "check_peak_rss_mb": peak, "check_wall_s": wall}
    out.unlink(missing_ok=True)
    return row


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--durations", type=float, nargs="+", default=[60, 300, 900, 1800, 3600])
    ap.add_argument("--check", action="store_true", help="also time azee-mj check")
    ap.add_argument("--markdown", action="store_true")
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "memory.json"))
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for dur in args.durations:
            rows.append(measure(dur, Path(d), args.check))
            r = rows[-1]
            print(
                f"{r['duration_s']:7.1f} s: peak {r['peak_rss_mb']:6.1f} MB, realized in "
                f"{r['realize_s']:6.1f} s ({r['real_time_factor']:.2f}x real time), wall "
                f"{r['wall_s']:6.1f} s, exit {r['exit']}"
                + (
                    f"; check {r['check_peak_rss_mb']:.0f} MB {r['check_wall_s']:.1f} s"
                    if args.check
                    else ""
                ),
                flush=True,
            )
    rows.sort(key=lambda r: r["duration_s"])
    long = [r for r in rows if r["duration_s"] >= 300]
    growth = None
    if len(long) >= 2:
        a, b = long[0], long[-1]
        growth = (b["peak_rss_mb"] - a["peak_rss_mb"]) / ((b["duration_s"] - a["duration_s"]) / 60)
    rtf = [r["real_time_factor"] for r in rows]
    result = {
        "machine": {"load_average_after": os.getloadavg()},
        "rows": rows,
        "growth_mb_per_score_minute": growth,
        "rtf_last_over_first": rtf[-1] / rtf[0] if rtf else None,
    }
    Path(args.out).parent.mkdir(exist_ok=True)
    Path(args.out).write_text(json.dumps(result, indent=1) + "\n")
    print(
        f"growth {growth} MB per minute of score; real-time factor last/first "
        f"{result['rtf_last_over_first']}"
    )
    if args.markdown:
        print("| score [s] | peak RSS [MB] | realize [s] | x real time | rollout file [MB] |")
        print("| --- | --- | --- | --- | --- |")
        for r in rows:
            print(
                f"| {r['duration_s']:.1f} | {r['peak_rss_mb']:.0f} | {r['realize_s']:.1f} | "
                f"{r['real_time_factor']:.2f} | {r['file_mb']:.1f} |"
            )


if __name__ == "__main__":
    main()
