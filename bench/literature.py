"""Literature signs (issue 6): realize the bundled examples beside the published figures.

    python bench/literature.py            # writes bench/results/literature.json
    python bench/literature.py --markdown # also prints the docs table

Every example is realized in both modes (``multitrack`` and ``flattened``) at 50 fps with
one shared :class:`azee_mj.ik.Solver`, and reported with: postures solved
(``stats.key_problems``, the papers' "IK problems", and all ``problems`` including the
in-between frames), LM iterations, wall time, real-time factor (score duration / realize
time), worst residuals (mm, degrees), penetrations over 1 mm outside contact pairs, and the
flattened mode's known defect measured as the joint motion (total path length, radians) of
the tracks that no block drives under multitrack.

Published figures (Blender iTaSC, 1 cm / 5 degree thresholds): Nunnari, Filhol & Heloir 2018
(i7-3635QM, one core): tree 11 IK problems in 2.76 s; the two-sign sentence 152 IK problems
in 9.97 s (the sentence is 'the cinema is/was good', sec. 5.2: our info-about example). The later Blender version's timings (arbre 0.63 s, bien 1.03 s, armoire 8.6 s)
are the figures quoted in issue 6 for Sharma & Filhol 2022; they are not in the extracted
text of that paper.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import time

import mujoco
import numpy as np
from machine import machine

from azee_mj.check import check_poses
from azee_mj.model import load_model
from azee_mj.schedule import contact_pairs, make_solver
from azee_mj.score import load_score
from azee_mj.sites import DEFAULT_MAP
from azee_mj.timeline import realize

ROOT = pathlib.Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples"
OUT = ROOT / "bench" / "results" / "literature.json"
FPS = 50.0

#: Published figures: example -> (source, IK problems or None, seconds, accuracy).
PUBLISHED = {
    "arbre": [
        ("Nunnari et al. 2018 (tree)", 11, 2.76, "1 cm / 5 deg"),
        ("later Blender version (issue 6)", None, 0.63, "n/a"),
    ],
    # The 2018 paper's two-sign sentence is "the cinema is/was good" (sec. 5.2: info-about
    # with cinema and good), i.e. our info-about example, not nicht-sondern.
    "info-about": [("Nunnari et al. 2018 (cinema + good sentence)", 152, 9.97, "1 cm / 5 deg")],
    "bien": [("later Blender version (issue 6)", None, 1.03, "n/a")],
    "armoire": [("later Blender version (issue 6)", None, 8.6, "n/a")],
}


def undriven_motion(rollout, schedule, solver) -> float:
    """Total joint path length [rad] of the tracks with no interval in ``schedule``."""
    m = solver.model
    total = 0.0
    for track, joints in DEFAULT_MAP.tracks.items():
        if schedule.get(track):
            continue
        adr = [
            m.jnt_qposadr[solver.joint_id(j)]
            for j in joints
            if m.jnt_type[solver.joint_id(j)] == mujoco.mjtJoint.mjJNT_HINGE
        ]
        if adr:
            total += float(np.abs(np.diff(rollout.qpos[:, adr], axis=0)).sum())
    return total


def run_one(name: str, mode: str, solver, model) -> tuple[dict, object]:
    path = EXAMPLES / f"{name}.json"
    score = load_score(str(path))
    t0 = time.perf_counter()
    r = realize(score, fps=FPS, mode=mode, solver=solver)
    wall = time.perf_counter() - t0
    place = [t.worst for t in r.traces if t.unit == "m"]
    ang = [t.worst for t in r.traces if t.unit == "rad"]
    rep = check_poses(
        model, r.qpos, allowed=contact_pairs(score, r.time, score_start=r.score_start)
    )
    duration = float(r.time[-1])
    return {
        "mode": mode,
        "duration_s": duration,
        "frames": len(r.time),
        "key_problems": r.stats.key_problems,
        "problems": r.stats.problems,
        "iterations": r.stats.iterations,
        "not_converged": r.stats.not_converged,
        "solve_time_s": r.stats.solve_time,
        "total_time_s": wall,
        "realtime_factor": duration / wall,
        "worst_place_mm": 1000.0 * max(place, default=0.0),
        "worst_angle_deg": float(np.degrees(max(ang, default=0.0))),
        "constraints_ok": sum(t.ok for t in r.traces),
        "constraints": len(r.traces),
        "penetrations": len(rep.penetrations),
        "deepest_mm": 1000.0 * float(rep.max_depth.max(initial=0.0)),
        "range_violations": len(rep.range_violations),
    }, r


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--markdown", action="store_true", help="print the markdown table")
    ap.add_argument("--out", default=str(OUT))
    args = ap.parse_args(argv)
    solver, model = make_solver(), load_model()
    names = sorted(p.stem for p in EXAMPLES.glob("*.json"))
    # Warm-up (imports, first compile of the row plans) outside the timings.
    realize(str(EXAMPLES / "bien.json"), fps=10, solver=solver)
    results = {}
    for name in names:
        row = {}
        multi, r_multi = run_one(name, "multitrack", solver, model)
        flat, r_flat = run_one(name, "flattened", solver, model)
        sched = r_multi.schedule
        multi["undriven_motion_rad"] = undriven_motion(r_multi, sched, solver)
        flat["undriven_motion_rad"] = undriven_motion(r_flat, sched, solver)
        row["undriven_tracks"] = sorted(t for t, v in sched.items() if not v)
        row["multitrack"], row["flattened"] = multi, flat
        row["published"] = [
            {
                "source": s,
                "ik_problems": n,
                "time_s": t,
                "accuracy": a,
                "speedup_multitrack": t / multi["total_time_s"],
                "speedup_flattened": t / flat["total_time_s"],
            }
            for s, n, t, a in PUBLISHED.get(name, [])
        ]
        results[name] = row
        print(
            f"{name:14s} multitrack {multi['total_time_s']:6.2f} s {multi['key_problems']:3d}/"
            f"{multi['problems']:4d} problems, {multi['constraints_ok']}/{multi['constraints']} ok"
            f" | flattened {flat['total_time_s']:6.2f} s {flat['key_problems']:3d}/"
            f"{flat['problems']:4d}, {flat['constraints_ok']}/{flat['constraints']} ok"
        )
    out = {
        "machine": machine(),
        "fps": FPS,
        "tolerances": "1 mm / 1 deg (defaults)",
        "solver": "one shared azee_mj.ik.Solver for every run",
        "examples": results,
    }
    pathlib.Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    pathlib.Path(args.out).write_text(
        json.dumps(out, indent=1, default=lambda o: o.item() if hasattr(o, "item") else str(o))
        + "\n"
    )
    print(f"wrote {args.out}")
    if args.markdown:
        print(markdown(out))
    return 0


def markdown(out: dict) -> str:
    mc = out["machine"]
    lines = [
        (
            f"Machine: {mc['cpu']}, {mc['cores']} cores; Python {mc['python']}, MuJoCo {mc['mujoco']}. "
            f"{out['fps']:g} fps, default tolerances (1 mm / 1 degree), one shared solver."
        ),
        "",
        "| example | mode | postures (key / all) | iterations | time [s] | real-time factor | worst place [mm] | worst angle [deg] | within tol | penetrations | undriven-track motion [rad] |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for name, row in out["examples"].items():
        for mode in ("multitrack", "flattened"):
            r = row[mode]
            lines.append(
                f"| {name} | {mode} | {r['key_problems']} / {r['problems']} | {r['iterations']} | "
                f"{r['total_time_s']:.2f} | {r['realtime_factor']:.2f} | {r['worst_place_mm']:.2f} | "
                f"{r['worst_angle_deg']:.2f} | {r['constraints_ok']}/{r['constraints']} | "
                f"{r['penetrations']} | {r['undriven_motion_rad']:.3f} |"
            )
    lines += [
        "",
        (
            "| example | published | their IK problems | their time [s] | their accuracy | "
            "our time multitrack / flattened [s] | speed-up multitrack / flattened | our worst (multitrack) |"
        ),
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for name, row in out["examples"].items():
        for p in row["published"]:
            m, f = row["multitrack"], row["flattened"]
            n = "n/a" if p["ik_problems"] is None else p["ik_problems"]
            lines.append(
                f"| {name} | {p['source']} | {n} | {p['time_s']} | {p['accuracy']} | "
                f"{m['total_time_s']:.2f} / {f['total_time_s']:.2f} | "
                f"{p['speedup_multitrack']:.1f}x / {p['speedup_flattened']:.1f}x | "
                f"{m['worst_place_mm']:.1f} mm / {m['worst_angle_deg']:.1f} deg |"
            )
    return "\n".join(lines)


if __name__ == "__main__":
    raise SystemExit(main())
