"""The face rig measured: the 52 ARKit shapes at weight 1, and what the face costs a realization.

    python bench/face.py [--no-realize]

For each shape: the largest displacement of a point of the face's visual geometry from the
rest face [mm], the bodies that move more than 0.5 mm (largest first), the eyelid apertures
(right / left), the lip aperture on the midline and the right cheek's bulge [mm], all
measured on the model by :mod:`azee_mj.face`. Then the 10-sign sentence of
``bench/realize.py`` realized without and with automatic blinks (seed 1), best of 3.
Prints a markdown table and writes ``bench/results/face.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import mujoco

sys.path.insert(0, str(Path(__file__).resolve().parent))

from machine import machine

from azee_mj import face
from azee_mj.arkit import ARKIT_SHAPES
from azee_mj.model import load_model

ROOT = Path(__file__).resolve().parent.parent


def shape_rows(model: mujoco.MjModel) -> list[dict]:
    d = mujoco.MjData(model)
    rest = face.morph_posture(model, {})
    d.qpos[:] = rest
    mujoco.mj_kinematics(model, d)
    depth = {s: face.skin_depth(model, d, s) for s in "LR"}
    rows = []
    for name in ("neutral", *ARKIT_SHAPES):
        q = face.morph_posture(model, {} if name == "neutral" else {name: 1.0})
        d.qpos[:] = q
        mujoco.mj_kinematics(model, d)
        moved = face.displacement(model, rest, q)
        rows.append(
            {
                "shape": name,
                "largest_mm": 1000 * moved.largest,
                "moves": moved.moved(),
                "eyelids_mm": [1000 * face.eyelid_aperture(model, d, s) for s in "RL"],
                "lips_mm": 1000 * face.lip_aperture(model, d),
                "cheek_R_mm": 1000 * face.cheek_bulge(model, d, "R", depth["R"]),
            }
        )
    return rows


def realize_cost(repeats: int = 3) -> dict:
    from realize import SIGNS, sentence

    from azee_mj.blinks import add_blinks
    from azee_mj.schedule import make_solver
    from azee_mj.score import load_score
    from azee_mj.timeline import realize

    score = load_score(sentence([SIGNS[i % len(SIGNS)] for i in range(10)]))
    blinked = add_blinks(score, 1)
    n = sum(1 for b in blinked.root.children if b.name.startswith("BLINK")) // 3
    out = {"duration_s": score.duration, "blinks": n}
    for key, s in (("without_face_s", score), ("with_blinks_s", blinked)):
        best = float("inf")
        for _ in range(repeats):
            solver = make_solver()
            t0 = time.perf_counter()
            realize(s, fps=50, solver=solver)
            best = min(best, time.perf_counter() - t0)
        out[key] = best
    return out


def table(rows: list[dict]) -> str:
    lines = [
        "| shape | largest [mm] | eyelids R / L [mm] | lips [mm] | cheek [mm] | what moves |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    for r in rows:
        lids = " / ".join(f"{x:.1f}" for x in r["eyelids_mm"])
        moves = ", ".join(r["moves"]) or "-"
        lines.append(
            f"| `{r['shape']}` | {r['largest_mm']:.1f} | {lids} | {r['lips_mm']:.1f} | "
            f"{r['cheek_R_mm']:.1f} | {moves} |"
        )
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--no-realize", action="store_true", help="the shape table only")
    args = ap.parse_args()
    model = load_model()
    rows = shape_rows(model)
    print(table(rows))
    result = {"machine": machine(), "shapes": rows}
    if not args.no_realize:
        cost = realize_cost()
        result["realize"] = cost
        print(
            f"\nsentence ({cost['duration_s']:.1f} s): {cost['without_face_s']:.2f} s without "
            f"the face, {cost['with_blinks_s']:.2f} s with {cost['blinks']} automatic blinks"
        )
    out = ROOT / "bench" / "results" / "face.json"
    out.write_text(json.dumps(result, indent=1) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
