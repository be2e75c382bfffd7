"""Front-end speed: compile and realize a composed expression of 10 rule applications.

    python bench/azee_text.py [--repeats N]

Compiles :data:`EXPRESSION` (10 rules over 12 sign applications) with
``azee_mj.azee.compile_text`` (median of N runs, the lexicon read once as a user would by
passing a :class:`~azee_mj.azee.Lexicon`, and once more with a fresh lexicon each time),
then realizes the score at 50 fps on one core, and writes bench/results/azee_text.json and
the markdown row of docs/benchmarks.md.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

from azee_mj import schedule, timeline
from azee_mj.azee import Lexicon, compile_text
from azee_mj.score import load_score

ROOT = Path(__file__).resolve().parent.parent

#: seq, info-about, tens-units, in-context, decidedly, nicht-sondern, each-of, instance-of,
#: side-info, tens-units: 10 rule applications.
EXPRESSION = """\
:seq
  :info-about
    'topic :arbre
    'info :tens-units(.nb-5, .nb-2)
  :in-context(:cinema, :decidedly(:penser))
  :nicht-sondern(:bien, :each-of(:nb-1, :nb-2))
  :instance-of(:armoire, :side-info(:bien, :arbre))
  :tens-units(.nb-3, .nb-4)
  'gap 0.1
"""


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=20)
    a = p.parse_args()
    lex = Lexicon()
    compile_text(EXPRESSION, lexicon=lex)  # warm: signs read and checked once
    warm, cold = [], []
    for _ in range(a.repeats):
        t0 = time.perf_counter()
        score = compile_text(EXPRESSION, lexicon=lex)
        warm.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        compile_text(EXPRESSION)
        cold.append(time.perf_counter() - t0)
    loaded = load_score(score)
    t0 = time.perf_counter()
    r = timeline.realize(loaded, fps=50, solver=schedule.make_solver())
    realize_s = time.perf_counter() - t0
    ok = sum(t.ok for t in r.traces)
    bad = [t.describe() for t in r.traces if not t.ok]
    blocks = sum(1 for b in loaded.blocks() if b.kind.value != "sync")
    out = {
        "expression": EXPRESSION,
        "rules": 10,
        "duration_s": loaded.duration,
        "blocks": blocks,
        "compile_ms_median_warm": 1000 * statistics.median(warm),
        "compile_ms_median_fresh_lexicon": 1000 * statistics.median(cold),
        "realize_s": realize_s,
        "realtime_factor": loaded.duration / realize_s,
        "frames": len(r.time),
        "within_tolerance": f"{ok}/{len(r.traces)}",
        "not_within": bad,
        "machine": platform.processor() or platform.machine(),
        "python": platform.python_version(),
    }
    path = ROOT / "bench" / "results" / "azee_text.json"
    path.write_text(json.dumps(out, indent=1) + "\n")
    print(json.dumps(out, indent=1))
    print(
        f"| 10 rules, {loaded.duration:.2f} s, {blocks} blocks | "
        f"{out['compile_ms_median_warm']:.1f} / {out['compile_ms_median_fresh_lexicon']:.1f} | "
        f"{realize_s:.2f} | {out['realtime_factor']:.1f} | {ok}/{len(r.traces)} |"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
