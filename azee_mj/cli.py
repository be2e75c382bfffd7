"""The ``azee-mj`` command line: catalogue, realize, check, preview, render, report.

Bad input prints one message and exits with status 2; a failed check exits with 1.
"""

from __future__ import annotations

import argparse
import json
import sys

from azee_mj.errors import AzeeError


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
    from azee_mj.export import load_rollout_arrays
    from azee_mj.model import load_model

    arrays = load_rollout_arrays(args.rollout)
    model = load_model()
    if arrays["qpos"].shape[1] != model.nq:
        raise AzeeError(
            f"{args.rollout}: qpos has {arrays['qpos'].shape[1]} columns; the bundled signer "
            f"has nq={model.nq}"
        )
    allowed = frozenset()
    if args.score:
        from azee_mj.timeline import contact_pairs

        allowed = contact_pairs(args.score, arrays["time"])
    report = check_poses(model, arrays["qpos"], allowed=allowed)
    fps = float(arrays["fps"]) if "fps" in arrays else None
    print(summary(report, fps))
    ok = report.clean
    if args.score:
        from azee_mj.timeline import residual_summary

        text, within = residual_summary(args.score, arrays)
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
    from azee_mj.export import save_json, save_npz
    from azee_mj.score import load_score
    from azee_mj.timeline import realize

    if args.fps <= 0:
        raise AzeeError(f"--fps must be positive, got {args.fps}")
    score = load_score(args.score)
    rollout = realize(score, fps=args.fps, mode=args.mode, progress=_Progress("realize"))
    save_npz(args.output, rollout.arrays())
    if args.report:
        save_json(args.report, rollout.report())
    s = rollout.stats
    bad = [t for t in rollout.traces if not t.ok]
    print(f"{args.output}: {len(rollout.time)} frames at {args.fps:g} fps, {s.problems} IK "
          f"problems ({s.iterations} iterations) in {s.total_time:.3f} s; "
          f"{len(rollout.traces) - len(bad)}/{len(rollout.traces)} constraints within tolerance")
    for t in bad[:5]:
        scale, unit = (1000.0, "mm") if t.unit == "m" else (180.0 / 3.141592653589793, "deg")
        print(f"  {t.block} constraint {t.index} ({t.kind}): worst {t.worst * scale:.2f} {unit}"
              f" (tol {t.tol * scale:.2f} {unit})")
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

    r = sub.add_parser("realize", help="realize a score to a rollout .npz")
    r.add_argument("score", help="SCORE.json (azee-score version 1)")
    r.add_argument("-o", "--output", required=True, help="OUT.npz")
    r.add_argument("--fps", type=float, default=50.0, help="frames per second (default 50)")
    r.add_argument("--mode", choices=["multitrack", "flattened"], default="multitrack",
                   help="blocks per articulator track (default) or the 2018 flattened method")
    r.add_argument("--report", help="also write residuals and timings to REPORT.json")
    r.set_defaults(func=_cmd_realize)

    c = sub.add_parser("check", help="check a rollout for penetrations and range violations")
    c.add_argument("rollout", help="ROLLOUT.npz written by 'azee-mj realize'")
    c.add_argument("--score", help="the score it realizes: also report constraint residuals")
    c.set_defaults(func=_cmd_check)
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
