"""Memory and time of ``azee-mj realize`` (and ``azee-mj check``) on long scores.

    python bench/memory.py [--durations 60 300 900 1800 3600] [--check] [--markdown]

Builds scores of about the given durations [s] by chaining the bundled examples (each
example's root becomes a ``sync`` child, 0.1 s apart, repeated), realizes each at 50 fps in
a fresh process (``python -m azee_mj.cli realize``, which also saves the rollout) and reads
that process's peak resident set size (``/usr/bin/time -f %M`` where it exists, else
``wait4``: the same kernel figure) and its realization time (the summary line's); with
``--check``, also ``azee-mj check`` on the rollout. The load average before and after
each run is kept: on a shared machine it says how much of a core the run had. Reports the real-time
factor (seconds of score per second of realization), the growth of the peak per minute of
score between the first duration of about 300 s or more and the last, and writes
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
sys.path.insert(0, str(ROOT / "bench"))

from machine import machine

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


TIME = Path("/usr/bin/time")


def _run(argv: list[str]) -> tuple[int, float, float, float, str]:
    """Exit status, peak RSS [MB], wall time [s], CPU time (user + system) [s] and first
    output line of a fresh process."""
    env = dict(os.environ, PYTHONPATH=str(ROOT), OMP_NUM_THREADS="1")
    cmd = [sys.executable, "-m", "azee_mj.cli", *argv]
    timed = TIME.exists()
    if timed:  # GNU time prints the peak [kB] as the last line of its standard error
        cmd = [str(TIME), "-f", "%M %U %S", *cmd]
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    out, err = p.communicate()
    wall = time.perf_counter() - t0
    peak, cpu = float("nan"), float("nan")
    if timed:
        kb, user, system = err.strip().splitlines()[-1].split()
        peak, cpu = float(kb) / 1024, float(user) + float(system)
    lines = out.splitlines()
    errors = [x for x in err.splitlines() if "error" in x]
    return p.returncode, peak, wall, cpu, lines[0] if lines else (errors[0] if errors else "")


def measure(duration: float, tmp: Path, check: bool) -> dict:
    score = long_score(duration)
    path = tmp / f"long{duration:g}.json"
    path.write_text(json.dumps(score))
    out = tmp / f"long{duration:g}.npz"
    load = os.getloadavg()[0]
    code, peak, wall, cpu, line = _run(["realize", str(path), "-o", str(out)])
    m = re.search(r"in ([0-9.]+) s;", line)
    realize_s = float(m.group(1)) if m else float("nan")
    row = {
        "duration_s": score["root"]["end"],
        "exit": code,
        "peak_rss_mb": peak,
        "wall_s": wall,
        "realize_s": realize_s,
        "real_time_factor": score["root"]["end"] / realize_s,
        # the whole process's CPU time (start-up, saving and the verdict included): what
        # other work on a shared machine changes least
        "cpu_s": cpu,
        "real_time_factor_cpu": score["root"]["end"] / cpu,
        "file_mb": out.stat().st_size / 1e6 if out.exists() else None,
        "summary": line,
        "load_before": load,
        "load_after": os.getloadavg()[0],
    }
    if check:
        code, peak, wall, _, _ = _run(["check", str(out)])
        row |= {"check_exit": code, "check_peak_rss_mb": peak, "check_wall_s": wall}
    out.unlink(missing_ok=True)
    return row


def main():
    ap = argparse.ArgumentParser()
    # 3590 s: the lead-in from rest and the return to it must fit the 1-hour frame limit
    ap.add_argument("--durations", type=float, nargs="+", default=[300, 900, 1800, 3590])
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
                f"{r['wall_s']:6.1f} s, CPU {r['cpu_s']:6.1f} s, exit {r['exit']}, load {r['load_before']:.1f} -> "
                f"{r['load_after']:.1f}"
                + (
                    f"; check {r['check_peak_rss_mb']:.0f} MB {r['check_wall_s']:.1f} s"
                    if args.check
                    else ""
                ),
                flush=True,
            )
    rows.sort(key=lambda r: r["duration_s"])
    long = [r for r in rows if r["duration_s"] >= 290]  # (the 5-minute score is 297.8 s)
    growth = None
    if len(long) >= 2:
        a, b = long[0], long[-1]
        growth = (b["peak_rss_mb"] - a["peak_rss_mb"]) / ((b["duration_s"] - a["duration_s"]) / 60)
    rtf = [r["real_time_factor"] for r in rows]
    rtf_cpu = [r["real_time_factor_cpu"] for r in rows]
    result = {
        "machine": machine(load_average_after=os.getloadavg()),
        "rows": rows,
        "growth_mb_per_score_minute": growth,
        "rtf_last_over_first": rtf[-1] / rtf[0] if rtf else None,
        "rtf_cpu_last_over_first": rtf_cpu[-1] / rtf_cpu[0] if rtf_cpu else None,
    }
    Path(args.out).parent.mkdir(exist_ok=True)
    Path(args.out).write_text(json.dumps(result, indent=1) + "\n")
    print(
        f"growth {growth} MB per minute of score; real-time factor last/first "
        f"{result['rtf_last_over_first']} (by CPU time {result['rtf_cpu_last_over_first']})"
    )
    if args.markdown:
        print(
            "| score [s] | peak RSS [MB] | realize [s] | x real time | CPU [s] | x real time "
            "(CPU) | file [MB] | load |"
        )
        print("| --- | --- | --- | --- | --- | --- | --- | --- |")
        for r in rows:
            print(
                f"| {r['duration_s']:.1f} | {r['peak_rss_mb']:.0f} | {r['realize_s']:.1f} | "
                f"{r['real_time_factor']:.2f} | {r['cpu_s']:.1f} | {r['real_time_factor_cpu']:.2f} | "
                f"{r['file_mb'] or 0:.1f} | "
                f"{r['load_before']:.1f} -> {r['load_after']:.1f} |"
            )


if __name__ == "__main__":
    main()
