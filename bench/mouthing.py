"""Cost of the face: a sentence with mouthing and facial rules against the same signs
without the face.

    python bench/mouthing.py [--repeats N] [--quick]

Compiles and realizes at 50 fps, multitrack, on one core, :data:`FACED` (every sign
mouthed or carrying a question, mouth gesture or corpus expression) and :data:`PLAIN`
(the same signs in sequence), best of N realizations each; writes
bench/results/mouthing.json and prints the markdown rows of docs/benchmarks.md.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

from machine import machine

from azee_mj import schedule, timeline
from azee_mj.azee import compile_text
from azee_mj.score import load_score

ROOT = Path(__file__).resolve().parent.parent

#: Five signs, each mouthed or with a facial rule (15 non-manual blocks and more).
FACED = """\
:seq
  :mouthing(:arbre, "arbre")
  :yes-no-question(:mouthing(:bien, "bien"))
  :mouth-gesture(:penser, "pah")
  :with-surprise(:mouthing(:armoire, "armoire"))
  :wh-question(:mouthing(:cinema, "cinéma"))
"""
#: The same signs, no face.
PLAIN = ":seq(:arbre, :bien, :penser, :armoire, :cinema)"


def run(text: str, repeats: int) -> dict:
    t0 = time.perf_counter()
    raw = compile_text(text)
    compile_s = time.perf_counter() - t0  # the first: espeak-ng's voices load once
    t0 = time.perf_counter()
    compile_text(text)
    warm_s = time.perf_counter() - t0
    score = load_score(raw)
    solver = schedule.make_solver()
    best, r = float("inf"), None
    for _ in range(repeats):
        t0 = time.perf_counter()
        r = timeline.realize(score, fps=50, solver=solver)
        best = min(best, time.perf_counter() - t0)
    blocks = sum(1 for b in score.blocks() if b.kind.value != "sync")
    return {
        "duration_s": score.duration,
        "blocks": blocks,
        "compile_ms_first": 1000 * compile_s,
        "compile_ms": 1000 * warm_s,
        "realize_s_best": best,
        "frames": len(r.time),
        "within_tolerance": f"{sum(t.ok for t in r.traces)}/{len(r.traces)}",
        "not_within": [t.describe() for t in r.traces if not t.ok],
    }


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--quick", action="store_true", help="one realization each")
    a = p.parse_args()
    repeats = 1 if a.quick else a.repeats
    out = {
        "faced": {"expression": FACED, **run(FACED, repeats)},
        "plain": {"expression": PLAIN, **run(PLAIN, repeats)},
        "machine": machine(),
    }
    f, pl = out["faced"], out["plain"]
    out["cost_ratio"] = f["realize_s_best"] / pl["realize_s_best"]
    path = ROOT / "bench" / "results" / "mouthing.json"
    path.write_text(json.dumps(out, indent=1, ensure_ascii=False) + "\n")
    print(json.dumps(out, indent=1, ensure_ascii=False))
    for label, r in (("with the face", f), ("signs only", pl)):
        print(
            f"| {label} | {r['duration_s']:.2f} s, {r['blocks']} blocks | "
            f"{r['compile_ms_first']:.1f} / {r['compile_ms']:.1f} | "
            f"{r['realize_s_best']:.2f} | {r['duration_s'] / r['realize_s_best']:.1f}x | "
            f"{r['within_tolerance']} |"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
