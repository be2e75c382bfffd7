"""Motion a signer makes: speeds and smoothness of every hand movement of the realized examples.

    python bench/motion.py [--label NAME] [--plot PATH] [--examples a,b] [--no-sentence]
                           [--scores DIR] [--no-physics]

Realizes every bundled example and the 10-sign sentence of ``bench/realize.py`` at 50 fps
and measures, with :mod:`azee_mj.movement`, each wrist's movements (a movement runs between
two pauses; see ``movement.segments``): duration, path length, peak and mean speed, SPARC,
LDLJ, speed peaks and the two-thirds power-law exponent on curved paths. Each movement is
labelled ``lead-in`` (it ends by the first block's start), ``retraction`` (it starts after
the last block's end), ``relax`` (its arm has no further block: the realizer's return to
rest), ``pause-relax`` / ``pause-lead-in`` (inside a gap between two of its arm's blocks,
ending / starting with the wrist at rest: a pause at rest, ``blend.pause_between``) or
``sign``; all but the last are timed by the realizer, the last by the score. Per
rollout: the frames at which a constraint active in its block is outside its tolerance, the
fastest joint [rad/s] (overall and where the realizer chose the timing) and the findings.
``--scores DIR`` adds every ``*.json`` score of a folder (e.g. ``bench/data/motion``).

Each rollout is also simulated (the physics mode, ``azee_mj.physics``) and compared with
its kinematic frames by ``bench/physics.py``'s ``compare``: the worst constraint error at the
holds, SPARC and peak speed of each wrist movement, the torques against their limits, the
deepest penetration outside the score's contacts and the simulation's real-time factor
(CPU time, one core), kinematic / physics side by side. ``--no-physics`` skips it.

Results go to ``bench/results/motion.json`` (or ``motion-NAME.json``), so that two versions
of the realizer sit side by side: run it once per version and compare the files. ``--plot``
draws each example's wrist speed profiles (needs matplotlib).
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import json
import sys
from pathlib import Path

import mujoco
import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from machine import machine
from physics import HEADER as PHYSICS_HEADER
from physics import compare
from physics import line as physics_line
from realize import SIGNS, sentence

from azee_mj import movement as mv
from azee_mj.model import load_model
from azee_mj.physics import PhysicsError
from azee_mj.schedule import make_solver
from azee_mj.score import load_score
from azee_mj.sites import DEFAULT_MAP
from azee_mj.timeline import realize

ROOT = HERE.parent
FPS = 50.0
WRISTS = ("WR_R", "WR_L")
#: Human ranges the motion issue states: wrist speed [m/s], joint speed [rad/s], SPARC.
WRIST_MAX, JOINT_MAX, SPARC_RANGE = 3.0, 25.0, (-1.6, -1.35)


def scores(names: list[str], with_sentence: bool, extra: Path | None = None) -> dict[str, dict]:
    out = {n: json.loads((ROOT / "examples" / f"{n}.json").read_text()) for n in names}
    if with_sentence:
        out["sentence-10"] = sentence((SIGNS * 2)[:10])
    for p in sorted(extra.glob("*.json")) if extra else ():
        out[p.stem] = json.loads(p.read_text())
    return out


#: How near [m] its rest position a wrist is at the end of a pause's return to rest.
AT_REST = 5e-3


def label(
    m: mv.Movement, t: np.ndarray, first_start: float, last_end: float, arm_end: float, rest=None
) -> str:
    """The movement's phase; ``rest``: ``(gaps, at_rest)``, the ``(end, start)`` [s] of the
    gaps between its arm's blocks and (T,) whether the wrist is at its rest position."""
    slack = 2.0 / FPS  # a movement comes to rest within two frames of its block
    if t[m.last] <= first_start + slack:
        return "lead-in"
    if t[m.first] >= last_end - slack:
        return "retraction"
    if t[m.first] >= arm_end - slack:
        return "relax"
    gaps, at_rest = rest if rest is not None else ((), None)
    for a, b in gaps:
        if t[m.first] >= a - slack and t[m.last] <= b + slack:
            if at_rest[m.last] and not at_rest[m.first]:
                return "pause-relax"
            if at_rest[m.first] and not at_rest[m.last]:
                return "pause-lead-in"
    return "sign"


def rest_of(arm, pos: np.ndarray) -> tuple[list, np.ndarray]:
    """The gaps ``(end, start)`` [s] between the blocks of an arm's schedule intervals
    ``arm``, and (T,) whether its wrist positions ``pos`` are at rest (frame 0's)."""
    ivs = sorted((i.start, i.end) for i in arm)
    gaps, reach = [], None
    for s, e in ivs:
        if reach is not None and s > reach:
            gaps.append((reach, s))
        reach = e if reach is None else max(reach, e)
    return gaps, np.linalg.norm(pos - pos[0], axis=1) < AT_REST


def chosen_frames(r, first: float, last: float) -> np.ndarray:
    """Frames whose timing the realizer chose: before the first block, after the last."""
    return (r.time < first - 1e-9) | (r.time > last + 1e-9)


def leaving_frames(rollout) -> int:
    """Frames at which an active place / orient / look constraint is out of tolerance."""
    bad = np.zeros(len(rollout.time), bool)
    for tr in rollout.traces:
        a = np.asarray(tr.active)
        bad[tr.first : tr.first + len(a)] |= ~(a <= tr.tol)
    return int(bad.sum())


def out_of_range_frames(rollout) -> int:
    """Frames at which a limited joint of the bundled signer is outside its range (by more
    than ``check.check_poses``' default 1e-6 rad or m)."""
    model = load_model()
    lo = np.where(model.jnt_limited, model.jnt_range[:, 0], -np.inf)
    hi = np.where(model.jnt_limited, model.jnt_range[:, 1], np.inf)
    scalar = np.isin(model.jnt_type, (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE))
    adr = model.jnt_qposadr[scalar]
    q = np.asarray(rollout.qpos)[:, adr]
    excess = np.maximum(lo[scalar] - q, q - hi[scalar])
    return int((excess > 1e-6).any(axis=1).sum())


def side_columns(side: str) -> list[int]:
    """The qpos addresses of the bundled signer's arm and hand joints of ``side`` (R, L)."""
    model = load_model()
    names = DEFAULT_MAP.tracks[f"arm_{side}"] + DEFAULT_MAP.tracks[f"hand_{side}"]
    return [int(model.jnt_qposadr[model.joint(j).id]) for j in names]


def measure(name: str, score_dict: dict) -> tuple[dict, dict]:
    r = realize(load_score(score_dict), fps=FPS)
    spans = [(i.start, i.end) for v in r.schedule.values() for i in v]
    first = min((s for s, _ in spans), default=0.0)
    last = max((e for _, e in spans), default=float(r.time[-1]))
    moves, profiles = [], {}
    for site in WRISTS:
        pos = r.site_pos[:, r.site_names.index(site)]
        profiles[site] = mv.speed(pos, FPS)
        arm = r.schedule.get(f"arm_{site[-1]}", ())
        arm_end = max((i.end for i in arm), default=first)
        rest = rest_of(arm, pos)
        for m in mv.movements(pos, FPS):
            rec = {
                "site": site,
                "phase": label(m, r.time, first, last, arm_end, rest),
                "t0": float(r.time[m.first]),
                "t1": float(r.time[m.last]),
            }
            rec.update({k: v for k, v in vars(m).items() if k not in ("first", "last")})
            moves.append(rec)
    step = np.abs(np.diff(r.qpos, axis=0)).max(axis=1) * FPS if len(r.time) > 1 else np.zeros(1)
    joint = float(step.max())
    own = chosen_frames(r, first, last)
    own = own[1:] | own[:-1] if len(own) > 1 else own
    chosen = float(step[own].max()) if own.any() else 0.0
    for m in moves:  # a pause's movements: its arm's and hand's joints (the other signs)
        if m["phase"].startswith("pause"):
            cols = side_columns(m["site"][-1])
            f0, f1 = np.searchsorted(r.time, (m["t0"] - 1e-9, m["t1"] + 1e-9))
            turn = np.abs(np.diff(r.qpos[f0 : f1 + 1, cols], axis=0)).max() * FPS
            chosen = max(chosen, float(turn))
    rec = {
        "name": name,
        "duration_s": float(r.time[-1]),
        "frames": len(r.time),
        "score_start": float(getattr(r, "score_start", 0.0)),
        "leaving_frames": leaving_frames(r),
        "out_of_range_frames": out_of_range_frames(r),
        "max_joint_speed": joint,
        "max_joint_speed_chosen": chosen,
        "findings": [f.describe() for f in getattr(r, "findings", ())],
        "peak_wrist_speed": max((m["peak_speed"] for m in moves), default=0.0),
        "movements": moves,
    }
    start = float(getattr(r, "score_start", 0.0))
    dur = float(load_score(score_dict).duration)
    return rec, {"time": r.time, "score": (start, start + dur), **profiles}


def summary(recs: list[dict]) -> dict:
    moves = [m for r in recs for m in r["movements"]]
    chosen = [m for m in moves if m["phase"] != "sign"]
    sp = [m["sparc"] for m in moves]
    return {
        "movements": len(moves),
        "median_sparc": float(np.median(sp)) if sp else float("nan"),
        "multi_peak": sum(m["peaks"] > 1 for m in moves),
        "peak_wrist_speed": max((m["peak_speed"] for m in moves), default=0.0),
        "chosen_over_3ms": sum(m["peak_speed"] > WRIST_MAX for m in chosen),
        "chosen_sparc_out": sum(not SPARC_RANGE[0] <= m["sparc"] <= SPARC_RANGE[1] for m in chosen),
        "leaving_frames": sum(r["leaving_frames"] for r in recs),
        "out_of_range_frames": sum(r["out_of_range_frames"] for r in recs),
        "max_joint_speed": max(r["max_joint_speed"] for r in recs),
        "max_joint_speed_chosen": max(r.get("max_joint_speed_chosen", 0.0) for r in recs),
        "chosen_peak_wrist": max((m["peak_speed"] for m in chosen), default=0.0),
        "findings": sum(len(r.get("findings", ())) for r in recs),
    }


def table(recs: list[dict]) -> str:
    rows = [
        (
            "| rollout | movements | peak wrist [m/s] | median SPARC | multi-peak | leaving frames "
            "| out of range | fastest joint [rad/s] |"
        ),
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for r in recs:
        sp = [m["sparc"] for m in r["movements"]]
        rows.append(
            f"| {r['name']} | {len(r['movements'])} | {r['peak_wrist_speed']:.2f} | "
            f"{np.median(sp) if sp else float('nan'):.2f} | "
            f"{sum(m['peaks'] > 1 for m in r['movements'])} | {r['leaving_frames']} | "
            f"{r['out_of_range_frames']} | {r['max_joint_speed']:.1f} |"
        )
    return "\n".join(rows)


def physics_columns(score_dict: dict, solver) -> dict:
    """The physics mode next to the kinematic one (``bench/physics.py``'s ``compare``), or
    ``{"error": message}`` when the simulation diverges."""
    try:
        return compare(load_score(score_dict), solver)
    except PhysicsError as e:
        return {"error": str(e)}


def physics_row(name: str, r: dict) -> str:
    """One row of the side-by-side table (``bench/physics.py``'s columns)."""
    return f"| {name} | {r['error']} |" if "error" in r else physics_line(name, r)


def plot(path: Path, profiles: dict[str, dict]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(profiles)
    fig, axes = plt.subplots(n, 1, figsize=(8, 1.6 * n), sharex=False, squeeze=False)
    for ax, (name, p) in zip(axes[:, 0], profiles.items()):
        for site in WRISTS:
            ax.plot(p["time"], p[site], label=site, lw=1)
        if p.get("score", (0.0, 0.0))[1] > 0.0:  # the score's span; outside it, rest
            ax.axvspan(*p["score"], color="0.93", zorder=0)
        ax.axhline(WRIST_MAX, color="0.6", lw=0.6, ls="--")
        ax.set_ylabel("m/s")
        ax.set_title(name, fontsize=8, loc="left")
    axes[0, 0].legend(fontsize=7, loc="upper right")
    axes[-1, 0].set_xlabel("time [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=90)


def plain(x):
    """numpy scalars as JSON numbers (``json.dumps``'s ``default``)."""
    if isinstance(x, np.generic):
        return x.item()
    raise TypeError(f"{type(x).__name__} is not JSON serializable")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--label", help="write bench/results/motion-LABEL.json")
    ap.add_argument("--plot", type=Path, help="a PNG of the wrist speed profiles")
    ap.add_argument("--examples", help="comma-separated example names (default: all)")
    ap.add_argument("--no-sentence", action="store_true", help="skip the 10-sign sentence")
    ap.add_argument("--scores", type=Path, help="also every *.json score of this folder")
    ap.add_argument("--no-physics", action="store_true", help="skip the physics columns")
    a = ap.parse_args(argv)
    names = (
        a.examples.split(",")
        if a.examples
        else sorted(p.stem for p in (ROOT / "examples").glob("*.json"))
    )
    recs, profiles, rows = [], {}, []
    solver = None if a.no_physics else make_solver()
    for name, s in scores(names, not a.no_sentence, a.scores).items():
        rec, prof = measure(name, s)
        if solver is not None:
            rec["physics"] = physics_columns(s, solver)
            rows.append(physics_row(name, rec["physics"]))
        recs.append(rec)
        profiles[name] = prof
    out = {"machine": machine(), "summary": summary(recs), "rollouts": recs}
    print(table(recs))
    print(json.dumps(out["summary"], indent=1, default=plain))
    if rows:
        print("\nkinematic / physics:\n" + PHYSICS_HEADER + "\n" + "\n".join(rows))
    stem = f"motion-{a.label}" if a.label else "motion"
    (HERE / "results" / f"{stem}.json").write_text(json.dumps(out, indent=1, default=plain) + "\n")
    if a.plot:
        plot(a.plot, profiles)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
