"""The ``azee-mj`` command line: catalogue, realize, check, preview, render, report.

Bad input prints one message and exits with status 2; a failed check exits with 1.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from azee_mj.errors import AzeeError

if TYPE_CHECKING:
    from azee_mj.markers import Clip


def _cmd_sites(args) -> int:
    from azee_mj.sites import DEFAULT_MAP

    if args.json:
        print(json.dumps(DEFAULT_MAP.to_json()))
        return 0
    m = DEFAULT_MAP
    print(f"{len(m.sites)} sites (AZee name -> model site):")
    names = list(m.sites)
    for i in range(0, len(names), 8):
        print("  " + " ".join(names[i : i + 8]))
    print(f"{len(m.bones)} bones (AZee bone -> body, DIR, NRM in the body frame):")
    for k, b in m.bones.items():
        print(f"  {k:12s} {b.body:12s} dir {_v(b.dir)} nrm {_v(b.nrm)}")
    print("loci: " + ", ".join(f"^{k} -> {v}" for k, v in m.loci.items()))
    print("morphs: " + ", ".join(m.morphs))
    return 0


def _v(v) -> str:
    return "[" + ", ".join(f"{x:+.3f}" for x in v) + "]"


def _cmd_check(args) -> int:
    from azee_mj.check import check_poses, summary
    from azee_mj.model import load_model
    from azee_mj.rollout_io import load_rollout

    model = load_model()
    rollout = load_rollout(args.rollout, model.nq)
    allowed, score, solver = frozenset(), None, None
    if args.score:
        from azee_mj.schedule import contact_pairs, make_solver
        from azee_mj.score import load_score

        score, solver = load_score(args.score), make_solver()
        allowed = contact_pairs(score, rollout.time, solver)
    report = check_poses(model, rollout.qpos, allowed=allowed)
    print(summary(report, rollout.fps))
    ok = report.clean
    if score is not None:
        from azee_mj.timeline import residual_summary

        text, within = residual_summary(score, rollout, solver)
        print(text)
        ok = ok and within
    return 0 if ok else 1


class _Progress:
    """A one-line progress bar on a terminal's stderr; silent otherwise."""

    def __init__(self, label: str):
        self.label, self.on = label, sys.stderr.isatty()

    def __call__(self, fraction: float) -> None:
        if self.on:
            n = int(30 * fraction)
            end = "\n" if fraction >= 1.0 else ""
            print(f"\r{self.label} [{'#' * n}{'.' * (30 - n)}] {fraction:4.0%}", end=end,
                  file=sys.stderr, flush=True)  # fmt: skip


def _cmd_realize(args) -> int:
    from azee_mj.batch import summary_lines
    from azee_mj.files import save_json
    from azee_mj.rollout_io import save_rollout
    from azee_mj.score import load_score
    from azee_mj.timeline import realize

    if args.fps <= 0:
        raise AzeeError(f"--fps must be positive, got {args.fps}")
    if args.jobs is not None and args.jobs < 1:
        raise AzeeError(f"--jobs must be at least 1, got {args.jobs}")
    if len(args.score) > 1 or Path(args.score[0]).is_dir() or _is_dir(args.output):
        return _realize_many(args)
    score = load_score(args.score[0])
    rollout = realize(score, fps=args.fps, mode=args.mode, progress=_Progress("realize"))
    save_rollout(args.output, rollout)
    if args.report:
        save_json(args.report, rollout.report())
    print("\n".join(summary_lines(args.output, rollout, args.fps)))
    return 0


def _is_dir(path: str) -> bool:
    return path.endswith(("/", os.sep)) or Path(path).is_dir()


def _realize_many(args) -> int:
    """Several scores (or directories of them) to ``-o DIR/``, one process per core."""
    from azee_mj.batch import plan, realize_many, score_files

    out = Path(args.output)
    if out.exists() and not out.is_dir():
        raise AzeeError(f"-o: {out} is a file; several scores need an output directory")
    report = Path(args.report) if args.report else None
    if report is not None and report.exists() and not report.is_dir():
        raise AzeeError(f"--report: {report} is a file; several scores need a directory")
    jobs = plan(score_files(args.score), out, report)
    bar = _Progress(f"realize {len(jobs)} scores")

    def done(o, n):
        if o.ok:
            print("\n".join(o.lines), flush=True)
        else:
            print(f"azee-mj: error: {o.error}", file=sys.stderr, flush=True)
        bar(n / len(jobs))

    outcomes = realize_many(jobs, fps=args.fps, mode=args.mode, workers=args.jobs,
                            on_done=done)  # fmt: skip
    return 0 if all(o.ok for o in outcomes) else 2


def load_clip(
    path: str | os.PathLike,
    *,
    score: str | os.PathLike | None = None,
    fps: float = 50.0,
    progress: Callable[[float], None] | None = None,
) -> Clip:
    """A clip from ``SCORE.json`` (realized at ``fps``) or ``ROLLOUT.npz`` (with an optional
    ``score`` for targets and the schedule)."""
    from azee_mj import score as sc
    from azee_mj.markers import Clip, schedule_of, shared_solver
    from azee_mj.model import load_model
    from azee_mj.rollout_io import load_rollout
    from azee_mj.timeline import realize

    path = Path(path)
    if path.suffix.lower() == ".json":
        s = sc.load_score(path)
        rollout = realize(s, fps=fps, solver=shared_solver(), progress=progress)
        return Clip.from_rollout(rollout, s, path.stem)
    if path.suffix.lower() != ".npz":
        raise AzeeError(f"{path}: expected a SCORE.json or a ROLLOUT.npz, got suffix "
                        f"{path.suffix!r}")  # fmt: skip
    r = load_rollout(path, load_model().nq)
    given = sc.load_score(Path(score)) if score else None
    sched = schedule_of(given) if given is not None else {}
    return Clip(r.time, r.qpos, r.fps, sched, given, path.stem)


def _clip(args, progress: bool = True):

    if args.fps is not None and args.fps <= 0:
        raise AzeeError(f"--fps must be positive, got {args.fps}")
    realize_fps = args.fps or 50.0
    return load_clip(args.input, score=getattr(args, "score", None), fps=realize_fps,
                     progress=_Progress("realize") if progress else None)  # fmt: skip


def _cmd_preview(args) -> int:
    from azee_mj.viewer import preview

    clip = _clip(args)
    n = preview(clip, targets=not args.no_targets, max_frames=args.max_frames,
                camera=args.camera)  # fmt: skip
    if args.max_frames is not None:
        print(f"preview: {n} viewer updates")
    return 0


def _cmd_render(args) -> int:
    from azee_mj.render import check_render_options, parse_size, render

    size = parse_size(args.size)
    check_render_options(args.output, size, args.fps, args.time)  # before realizing
    clip = _clip(args)
    out = render(clip, args.output, camera=args.camera, size=size, fps=args.fps,
                 time=args.time, targets=args.targets, antialias=not args.no_antialias,
                 progress=_Progress("render"))  # fmt: skip
    print(f"{out}: written")
    return 0


def _cmd_report(args) -> int:
    from azee_mj.report import write_report

    paths = write_report(args.score, args.output, fps=args.fps or 50.0,
                         progress=_Progress("report"))  # fmt: skip
    for p in paths:
        print(f"{p}: written")
    return 0


def build_parser() -> argparse.ArgumentParser:
    from azee_mj import __version__

    p = argparse.ArgumentParser(
        prog="azee-mj", description="Realize AZee sign-language scores on a MuJoCo signer."
    )
    p.add_argument("--version", action="version", version=f"azee-mj {__version__}")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    s = sub.add_parser("sites", help="list the AZee catalogue (sites, bones, loci, morphs)")
    s.add_argument("--json", action="store_true", help="print one JSON object")
    s.set_defaults(func=_cmd_sites)

    r = sub.add_parser("realize", help="realize a score to a rollout .npz (or many to DIR/)")
    r.add_argument("score", nargs="+", metavar="SCORE",
                   help="SCORE.json (azee-score version 1); several, or a directory of them, "
                   "are realized in parallel to -o DIR/")
    r.add_argument("-o", "--output", required=True, help="OUT.npz, or DIR/ for several scores")
    r.add_argument("--fps", type=float, default=50.0, help="frames per second (default 50)")
    r.add_argument("--mode", choices=["multitrack", "flattened"], default="multitrack",
                   help="blocks per articulator track (default) or the 2018 flattened method")
    r.add_argument("--report", help="also write residuals and timings to REPORT.json "
                   "(DIR/ for several scores)")
    r.add_argument("--jobs", type=int, help="processes for several scores (default: one per "
                   "usable core)")
    r.set_defaults(func=_cmd_realize)

    c = sub.add_parser("check", help="check a rollout for penetrations and range violations")
    c.add_argument("rollout", help="ROLLOUT.npz written by 'azee-mj realize'")
    c.add_argument("--score", help="the score it realizes: also report constraint residuals")
    c.set_defaults(func=_cmd_check)

    from azee_mj.render import CAMERAS

    v = sub.add_parser("preview", help="play a score or rollout in the MuJoCo viewer")
    v.add_argument("input", metavar="SCORE|ROLLOUT",
                   help="SCORE.json (realized first) or ROLLOUT.npz")
    v.add_argument("--score", help="the score of a ROLLOUT.npz, to draw its targets")
    v.add_argument("--fps", type=float, help="frames per second when realizing (default 50)")
    v.add_argument("--camera", choices=CAMERAS, help="start from a fixed camera (default: free)")
    v.add_argument("--no-targets", action="store_true", help="do not draw constraint targets")
    v.add_argument("--max-frames", type=int, help=argparse.SUPPRESS)  # for tests
    v.set_defaults(func=_cmd_preview)

    w = sub.add_parser("render", help="render a score or rollout offscreen to .mp4, .gif or .png")
    w.add_argument("input", metavar="SCORE|ROLLOUT",
                   help="SCORE.json (realized first) or ROLLOUT.npz")
    w.add_argument("-o", "--output", required=True, help="OUT.mp4, OUT.gif or OUT.png")
    w.add_argument("--score", help="the score of a ROLLOUT.npz (targets, contact sheet labels)")
    w.add_argument("--camera", choices=CAMERAS, default="front", help="camera (default front)")
    w.add_argument("--size", default="640x480", help="WxH in pixels (default 640x480)")
    w.add_argument("--fps", type=float, help="video frames per second (default: the rollout's)")
    w.add_argument("--time", type=float, help="for .png: the frame at T seconds (default: a "
                   "contact sheet of the key postures)")
    w.add_argument("--targets", action="store_true", help="draw constraint targets")
    w.add_argument("--no-antialias", action="store_true", help="no multisampling: about twice "
                   "as fast in software GL, with jagged edges")
    w.set_defaults(func=_cmd_render)

    h = sub.add_parser("report", help="HTML report (or PNG set) of a score's realization")
    h.add_argument("score", help="SCORE.json")
    h.add_argument("-o", "--output", required=True, help="REPORT.html, or DIR/ for PNG files")
    h.add_argument("--fps", type=float, help="frames per second (default 50)")
    h.set_defaults(func=_cmd_report)
    return p


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``azee-mj``; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except AzeeError as e:
        print(f"azee-mj: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
