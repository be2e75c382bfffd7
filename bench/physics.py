"""Kinematic and physics modes side by side, on every bundled example and a 10-sign sentence.

    python bench/physics.py [--quick] [--repeat 3]

For each score, in both modes: the worst constraint error at the holds (place [mm], orient
and look [deg]); per movement of each wrist (:func:`azee_mj.movement.segments` of the
kinematic rollout's wrist speed, the same frames for both modes), its smoothness (SPARC,
:func:`azee_mj.movement.sparc`: closer to 0 is smoother) and its peak wrist speed [m/s];
the deepest penetration outside the contacts the score asks for [mm]; the torques (the
physics mode's peak against its limit, and the torque the kinematic frames would need,
from inverse dynamics, against the same limit); the CPU and wall time and the real-time
factor of the simulation on one core. ``--quick`` runs two examples and a 3-sign sentence.

Results go to ``bench/results/physics.json``. The functions (:func:`compare`,
:func:`penetrations`, :func:`holds`, :func:`demand`, :func:`stages`) are importable for
other benches (``bench/motion.py`` can call ``compare`` for the physics columns).
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
import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from machine import machine
from realize import SIGNS, sentence

from azee_mj import movement as mv
from azee_mj import physics, timeline
from azee_mj.constraints import penetration_depth
from azee_mj.schedule import Schedule, make_solver
from azee_mj.score import load_score

ROOT = HERE.parent
EXAMPLES = ["arbre", "armoire", "bien", "info-about", "nicht-sondern", "penser", "pointing"]
WRISTS = ("WR_R", "WR_L")


def wrist_speed(r, site: str) -> np.ndarray:
    """(T,) speed of ``site`` in rollout ``r`` [m/s] (:func:`azee_mj.movement.speed`)."""
    return mv.speed(r.site_pos[:, r.site_names.index(site)], r.fps)


def penetrations(r, score, solver) -> float:
    """The deepest penetration of the rollout's frames outside the contacts the score asks
    for [m] (``score`` on the rollout's clock, :func:`on_clock`)."""
    sched = Schedule(score, solver)
    m = solver.model
    d = mujoco.MjData(m)
    worst = 0.0
    for f, t in enumerate(r.time):
        d.qpos[:] = r.qpos[f]
        worst = max(worst, penetration_depth(m, d, sched.allowed_at(float(t))))
    return worst


def holds(r, score) -> dict:
    """The worst error at the holds of the constraints with the default tolerance (1 mm,
    1 degree): place [mm], orient and look [deg], leaving out the frames a trill moves (a
    kinematic trace is measured before the trill is added, a simulated one with it); and
    whether the looser ones (a facing rule of 15 degrees, ...) are within theirs.
    ``score`` is on the rollout's clock (:func:`on_clock`)."""
    trilled = np.zeros(len(r.time), bool)
    for a, b in physics.trill_windows(score):
        trilled[(r.time >= a - 1e-9) & (r.time < b)] = True

    def worst(t) -> float:
        v = t.values[~trilled]
        return float(np.nanmax(v)) if np.isfinite(v).any() else 0.0

    tight = [t for t in r.traces if t.tol <= (1e-3 if t.unit == "m" else np.radians(1.0)) + 1e-9]
    place = [worst(t) for t in tight if t.unit == "m"]
    angle = [worst(t) for t in tight if t.unit != "m"]
    return {
        "place_mm": 1000.0 * max(place, default=0.0),
        "angle_deg": float(np.degrees(max(angle, default=0.0))),
        "loose_within_tolerance": all(worst(t) <= t.tol for t in r.traces if t not in tight),
    }


def demand(kin, score) -> tuple[float, str, list[dict]]:
    """The largest ratio of the torque the kinematic frames need (the reference's inverse
    dynamics at the simulation's steps, no contact) to the joint's limit, that joint, and
    the stretches of frames where the need is over the limit (start, end [s], peak ratio,
    joint, the block running): where the kinematic frames are not a body's motion.
    ``score`` is on the rollout's clock (:func:`on_clock`)."""
    ties = physics.ties(score)
    m = physics.actuated_model(ties)
    ref = physics.reference(m, kin, ties)
    ratio = np.abs(ref.torque_ff) / m.actuator_forcerange[:, 1]
    j = int(np.unravel_index(np.argmax(ratio), ratio.shape)[1])
    name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j)
    per_frame = ratio[:: ref.substeps]
    over = per_frame.max(axis=1) > 1.0
    spans = []
    f = 0
    while f < len(over):
        if not over[f]:
            f += 1
            continue
        g = f
        while g + 1 < len(over) and over[g + 1]:
            g += 1
        k = f + int(np.argmax(per_frame[f : g + 1].max(axis=1)))
        jj = int(np.argmax(per_frame[k]))
        spans.append(
            {
                "start": float(kin.time[f]),
                "end": float(kin.time[g]),
                "peak_ratio": float(per_frame[k, jj]),
                "joint": mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, jj),
                "block": physics.block_at(score, float(kin.time[k])),
            }
        )
        f = g + 1
    return float(ratio.max()), name, spans


def on_clock(score, r):
    """``score`` on rollout ``r``'s clock: shifted by the lead-in from rest before it."""
    return score.shifted(r.score_start) if r.score_start else score


def compare(score, solver, repeat: int = 1) -> dict:
    """Both modes of ``score`` side by side (see the module's docstring)."""
    t = time.perf_counter()
    kin = timeline.realize(score, solver=solver)
    kin_s = time.perf_counter() - t
    best, cpu, dyn = float("inf"), float("inf"), None
    for _ in range(repeat):
        c = time.process_time()
        dyn = physics.simulate(kin, score, solver=solver)
        cpu = min(cpu, time.process_time() - c)
        best = min(best, dyn.sim_seconds)
    moves = []
    for site in WRISTS:
        vk, vd = wrist_speed(kin, site), wrist_speed(dyn, site)
        for a, b in mv.segments(vk, kin.fps):
            b += 1
            moves.append(
                {
                    "site": site,
                    "start": a / kin.fps,
                    "end": b / kin.fps,
                    "sparc": [mv.sparc(vk[a:b], kin.fps), mv.sparc(vd[a:b], kin.fps)],
                    "peak_speed": [float(vk[a:b].max()), float(vd[a:b].max())],
                }
            )
    ratio = dyn.torque_peak / dyn.torque_limit
    j = int(np.unravel_index(np.argmax(ratio), ratio.shape)[1])
    score = on_clock(score, kin)  # the windows below (trills, contacts) on the frames' clock
    need, need_joint, infeasible = demand(kin, score)
    dur = float(kin.time[-1])
    return {
        "duration_s": dur,
        "holds": {"kinematic": holds(kin, score), "physics": holds(dyn, score)},
        "movements": moves,
        "penetration_mm": {
            "kinematic": 1000 * penetrations(kin, score, solver),
            "physics": 1000 * penetrations(dyn, score, solver),
        },
        "torque": {
            "physics_peak_ratio": float(ratio.max()),
            "physics_peak_joint": dyn.joints[j],
            "saturated_frames": int((ratio > 0.999).any(axis=1).sum()),
            "kinematic_demand_ratio": need,
            "kinematic_demand_joint": need_joint,
            "kinematic_over_limit": infeasible,
        },
        "tracking_site_mm": 1000 * float(dyn.tracking_site.max()),
        "energy_j": float(dyn.energy[-1]),
        "tie_force_n": float(dyn.tie_force.max()),
        "clipped_to_range": dyn.clipped,
        "kinematic_s": kin_s,
        "physics_s": best,
        "physics_cpu_s": cpu,
        "physics_real_time": dur / best,
        "physics_real_time_cpu": dur / cpu,
        "stages_cpu_s": stages(kin, score),
        "load_average": os.getloadavg()[0],
    }


def stages(kin, score) -> dict:
    """CPU seconds of the simulation's stages: building the model, the reference (inverse
    dynamics at the frames, the spline), the stepping, and the outputs (site positions and
    residual traces, by difference with a whole run)."""
    out = {}
    c = time.process_time()
    ties = physics.ties(score)
    settings = physics.Settings(timestep=physics.frame_step(kin.fps, 0.002))
    m = physics.actuated_model(ties, settings)
    out["build"] = time.process_time() - c
    c = time.process_time()
    ref = physics.reference(m, kin, ties)
    out["reference"] = time.process_time() - c
    c = time.process_time()
    physics.step(m, ref, len(kin.time), score)
    out["step"] = time.process_time() - c
    out["steps"] = len(ref.ctrl)
    out["step_us"] = 1e6 * out["step"] / len(ref.ctrl)
    return out


def side_by_side(name: str, out: Path, size=(280, 260), fps: float = 25.0, solver=None) -> None:
    """An animated GIF of example ``name``: the kinematic rollout on the left, the physics
    one on the right (front camera, ``fps`` frames per second)."""
    from PIL import Image, ImageDraw

    from azee_mj.render import FrameRenderer

    score = load_score(ROOT / "examples" / f"{name}.json")
    solver = solver or make_solver()
    kin = timeline.realize(score, solver=solver)
    dyn = physics.simulate(kin, score, solver=solver)
    step = max(1, round(kin.fps / fps))
    frames = []
    with FrameRenderer(camera="front", size=size) as fr:
        for f in range(0, len(kin.time), step):
            tiles = []
            for label, r in (("kinematic", kin), ("physics", dyn)):
                img = Image.fromarray(fr.render(r.qpos[f]))
                ImageDraw.Draw(img).text((8, 6), f"{label}  t = {r.time[f]:.2f} s", fill=(0, 0, 0))
                tiles.append(img)
            both = Image.new("RGB", (2 * size[0], size[1]))
            both.paste(tiles[0], (0, 0))
            both.paste(tiles[1], (size[0], 0))
            frames.append(both.quantize(colors=64))
    frames[0].save(out, save_all=True, append_images=frames[1:], duration=int(1000 / fps), loop=0)


def line(name: str, r: dict) -> str:
    """One row of the side-by-side table (:data:`HEADER`)."""
    h, mv, tq = r["holds"], r["movements"], r["torque"]
    sk = np.mean([m["sparc"][0] for m in mv]) if mv else float("nan")
    sd = np.mean([m["sparc"][1] for m in mv]) if mv else float("nan")
    vk = max((m["peak_speed"][0] for m in mv), default=0.0)
    vd = max((m["peak_speed"][1] for m in mv), default=0.0)
    return (
        f"| {name} | {h['kinematic']['place_mm']:.2f} / {h['physics']['place_mm']:.2f} "
        f"| {h['kinematic']['angle_deg']:.2f} / {h['physics']['angle_deg']:.2f} "
        f"| {sk:.2f} / {sd:.2f} | {vk:.2f} / {vd:.2f} "
        f"| {r['penetration_mm']['kinematic']:.2f} / {r['penetration_mm']['physics']:.2f} "
        f"| {100 * tq['kinematic_demand_ratio']:.0f}% ({tq['kinematic_demand_joint']}) "
        f"| {100 * tq['physics_peak_ratio']:.0f}% ({tq['saturated_frames']}) "
        f"| {r['tie_force_n']:.0f} | {r['physics_real_time_cpu']:.1f}x "
        f"({r['physics_real_time']:.1f}x) |"
    )


HEADER = (
    "| score | hold place mm (kin / phys) | hold angle deg | mean SPARC | peak wrist m/s "
    "| penetration mm | kinematic torque need / limit | physics peak / limit (frames at it) "
    "| equality pull N | physics x real time, CPU (wall) |\n"
    "|---|---|---|---|---|---|---|---|---|---|"
)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="two examples and a 3-sign sentence")
    ap.add_argument("--repeat", type=int, default=1, help="simulations per score (best time)")
    ap.add_argument("--gif", metavar="EXAMPLE", help="only write docs/physics-EXAMPLE.gif")
    args = ap.parse_args()
    if args.gif:
        out = ROOT / "docs" / f"physics-{args.gif}.gif"
        side_by_side(args.gif, out)
        print(f"{out}: written")
        return
    solver = make_solver()
    names = ["bien", "armoire"] if args.quick else EXAMPLES
    n_sent = 3 if args.quick else 10
    scores = {n: load_score(ROOT / "examples" / f"{n}.json") for n in names}
    scores[f"sentence-{n_sent}"] = load_score(
        sentence([SIGNS[i % len(SIGNS)] for i in range(n_sent)])
    )
    results = {}
    print(HEADER)
    for name, score in scores.items():
        results[name] = compare(score, solver, args.repeat)
        print(line(name, results[name]), flush=True)
    print("\nwhere the kinematic frames need more than the torque limits (peak >= 1.5):")
    for name, r in results.items():
        for w in r["torque"]["kinematic_over_limit"]:
            if w["peak_ratio"] >= 1.5:
                print(
                    f"  {name}: {w['start']:.2f}-{w['end']:.2f} s, {w['peak_ratio']:.1f}x "
                    f"{w['joint']} ({w['block']})"
                )
    out = HERE / "results" / ("physics-quick.json" if args.quick else "physics.json")
    doc = {"machine": machine(repeat=args.repeat), "results": results}
    out.write_text(json.dumps(doc, indent=1) + "\n")
    print(f"{out}: written")


if __name__ == "__main__":
    main()
