"""Realization CPU time side by side: this checkout against others, in alternating rounds.

    python bench/realize_cpu.py --against DIR [--against DIR ...] [--rounds 4] [--repeat 5]
        [--no-examples] [--out bench/results/realize_cpu.json]

Each DIR is a checkout of the package with its compiled core built in place (e.g. a detached
git worktree of an older commit). Every round runs every checkout in turn, each in a fresh
process importing the package from its own directory; a process realizes the 10-sign
sentence of ``bench/realize.py`` (its examples read from this checkout, so every checkout
realizes the same score) and every bundled example of that checkout, ``--repeat`` times
each, and reports the best CPU time (``time.process_time``) of one realization. The table
keeps the best of the rounds: on a shared machine the best is the run least disturbed.
The issue 23 target: the sentence within 10 % of the commit before the motion work.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SENTENCE_SIGNS = 10


def child(root: Path, repeat: int, examples: bool) -> dict:
    """Best CPU seconds and frames of one realization per score, with the package imported
    from wherever ``PYTHONPATH`` points (the checkout being measured)."""
    from realize import SIGNS, sentence

    from azee_mj import timeline
    from azee_mj.schedule import make_solver
    from azee_mj.score import load_score

    solver = make_solver()
    scores = {"sentence": load_score(sentence([SIGNS[i % 5] for i in range(SENTENCE_SIGNS)]))}
    if examples:
        for p in sorted((root / "examples").glob("*.json")):
            scores[p.stem] = load_score(json.loads(p.read_text()))
    out = {}
    for name, score in scores.items():
        best, frames = None, 0
        for _ in range(repeat):
            c0 = time.process_time()
            r = timeline.realize(score, fps=50, solver=solver)
            dc = time.process_time() - c0
            best = dc if best is None else min(best, dc)
            frames = len(r.time)
        out[name] = {"cpu_s": best, "frames": frames}
    return out


def measure(root: Path, repeat: int, examples: bool) -> dict:
    """One child process over checkout ``root``."""
    env = {**os.environ, "PYTHONPATH": str(root), "OMP_NUM_THREADS": "1"}
    cmd = [sys.executable, __file__, "--child", str(root), "--repeat", str(repeat)]
    if not examples:
        cmd.append("--no-examples")
    res = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
    return json.loads(res.stdout.strip().splitlines()[-1])


def describe(root: Path) -> str:
    """The checkout's commit (short hash, '+' when its tree has changes)."""

    def git(*args: str) -> str:
        cmd = ["git", "-C", str(root), *args]
        return subprocess.run(cmd, capture_output=True, text=True, check=True).stdout.strip()

    dirty = git("status", "--porcelain", "-uno")
    return git("rev-parse", "--short", "HEAD") + ("+" if dirty else "")


def table(labels: list[str], best: dict) -> str:
    """Markdown rows: each checkout's CPU s and frames, and each against the first."""
    names = list(best[labels[0]])
    head = " | ".join(f"{x}: CPU s, frames" for x in labels)
    ratio = " | ".join(f"{x} / {labels[0]}: per score, per frame" for x in labels[1:])
    lines = [f"| score | {head} | {ratio} |", "|" + " --- |" * (1 + 2 * len(labels) - 1)]
    for n in names:
        cells = [f"{best[x][n]['cpu_s']:.3f}, {best[x][n]['frames']}" for x in labels]
        b = best[labels[0]][n]
        for x in labels[1:]:
            c = best[x].get(n)
            if c is None:
                cells.append("-")
                continue
            per_frame = (c["cpu_s"] / c["frames"]) / (b["cpu_s"] / b["frames"])
            cells.append(f"{c['cpu_s'] / b['cpu_s']:.2f}, {per_frame:.2f}")
        lines.append(f"| {n} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--against", action="append", default=[], type=Path, help="a checkout")
    ap.add_argument("--rounds", type=int, default=4)
    ap.add_argument("--repeat", type=int, default=5, help="realizations per score and process")
    ap.add_argument("--no-examples", action="store_true", help="the sentence only")
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--child", type=Path, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child is not None:
        print(json.dumps(child(args.child, args.repeat, not args.no_examples)))
        return
    roots = [r.resolve() for r in args.against] + [ROOT]
    labels = [describe(r) for r in roots[:-1]] + [f"this ({describe(ROOT)})"]
    best: dict = {x: {} for x in labels}
    loads = []
    for k in range(args.rounds):
        for label, root in zip(labels, roots):
            loads.append(os.getloadavg()[0])
            got = measure(root, args.repeat, not args.no_examples)
            for n, v in got.items():
                if n not in best[label] or v["cpu_s"] < best[label][n]["cpu_s"]:
                    best[label][n] = v
            print(f"round {k + 1} {label}: sentence {got['sentence']['cpu_s']:.3f} s CPU")
    print(table(labels, best))
    print(f"load average (1 min) {min(loads):.1f} to {max(loads):.1f} on {os.cpu_count()} cores")
    if args.out:
        from machine import cpu

        out = {
            "rounds": args.rounds,
            "repeat": args.repeat,
            "checkouts": labels,
            "best": best,
            "load_average": [min(loads), max(loads)],
            "machine": {"cpu": cpu(), "cores": os.cpu_count(), "python": platform.python_version()},
        }
        args.out.write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
