"""The ``azee-mj`` command line: catalogue, compile and rules (the ``.azee`` front end),
realize, check, preview, render, export, report.

Exit status: 0 done; 1 a check found problems (``check``, or ``realize --strict`` with a
constraint out of tolerance, a penetration or a finding: a speed over the human range), or
some of several scores failed (the others written, a summary naming the failed files); 2 bad
input (a score, rollout, option or output path; one message, no output file);
3 an internal error (a bug: one line asking for a report; ``--debug`` shows the
traceback); 130 interrupted (Ctrl-C); 143 terminated (SIGTERM, SIGHUP or SIGQUIT). A closed
standard output (``azee-mj sites | head -1``) ends the command quietly with 0. Every
output is written by the one rule of :mod:`azee_mj.files`, checked before any work starts
(:func:`_outputs`).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import os
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

from azee_mj.errors import AzeeError, one_line, printable, shorten
from azee_mj.timing import DEFAULT_FPS

#: Exit statuses (see the module docstring).
EXIT_OK, EXIT_FINDINGS, EXIT_BAD_INPUT, EXIT_INTERNAL = 0, 1, 2, 3
EXIT_INTERRUPTED, EXIT_TERMINATED = 130, 143


@dataclasses.dataclass(frozen=True)
class _Run:
    """What one command carries besides its options: ``cleanup`` holds the temporary files it
    makes until it ends."""

    cleanup: contextlib.ExitStack

    def score_path(self, path: str | None, lexicon: Sequence[str] | None) -> str | None:
        """A score argument as a JSON path: a ``.azee`` expression is compiled (with the
        ``lexicon`` directories) to ``STEM.json`` in a temporary directory that lives until
        the command ends; any other path is returned as it is."""
        if path is None or Path(path).suffix.lower() != ".azee":
            return path
        from azee_mj.azee import compile_file, dump_score

        score = compile_file(path, lexicon=lexicon or ())
        tmp = Path(self.cleanup.enter_context(tempfile.TemporaryDirectory(prefix="azee-mj-")))
        out = tmp / f"{Path(path).stem}.json"
        out.write_text(dump_score(score), encoding="utf-8")
        return str(out)


def _outputs(
    outputs: Sequence[str | None],
    inputs: Sequence[str | None],
    lexicon: Sequence[str] | None,
    directory: bool = False,
) -> None:
    """The one output check of every writing command, before any work: each output path
    given (e.g. ``--output``, ``--report``) must be writable and differ from every input
    path given and from every sign file of the ``lexicon`` directories (see
    :func:`azee_mj.files.check_output`); with ``directory`` each is a directory that must
    exist (one rule with realize: :func:`azee_mj.files.check_output_dir`)."""
    from azee_mj.files import check_output, check_output_dir

    given = [p for p in inputs if p] + _lexicon_files(lexicon)
    paths = [p for p in outputs if p]
    for p in paths:
        if directory:
            check_output_dir(p)
        else:
            check_output(p, given)
    real = [os.path.realpath(p) for p in paths]
    if len(set(real)) < len(real):
        raise AzeeError(f"{paths[0]}: the same file is given for two outputs")


def _lexicon_files(lexicon: Sequence[str] | None) -> list[Path]:
    """The sign files of the ``--lexicon`` directories (inputs no output may replace)."""
    out = []
    for d in lexicon or ():
        with contextlib.suppress(OSError):  # unreadable: the lexicon says so when it is read
            out += [p for p in Path(d).iterdir() if p.suffix in (".json", ".azee")]
    return out


def _cmd_sites(args, run: _Run) -> int:
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
    from azee_mj.arkit import ARKIT_SHAPES

    sided = [k for k, v in m.morphs.items() if v.sided]
    face = [k for k in ARKIT_SHAPES if k in m.morphs]
    others = [k for k in m.morphs if k not in face]
    print("morphs: " + ", ".join(others))
    print(f"face morphs, the {len(face)} ARKit blend shapes (Left/Right: the signer's own):")
    for i in range(0, len(face), 6):
        print("  " + " ".join(face[i : i + 6]))
    print("sided morphs (with 'side': s, w, R or L; both sides without): " + ", ".join(sided))
    return 0


def _add_lexicon(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--lexicon",
        action="append",
        metavar="DIR",
        help="a directory of signs (NAME.json, NAME.azee) for .azee input, searched "
        "before the bundled lexicon; repeatable",
    )


def _cmd_compile(args, run: _Run) -> int:
    from azee_mj.azee import compile_file, compile_text, dump_score
    from azee_mj.files import atomic_path

    if (args.input is None) == (args.e is None):
        raise AzeeError("compile: give one EXPR.azee file or -e TEXT")
    if args.input is not None and Path(args.input).suffix.lower() == ".json":
        raise AzeeError(
            f"{args.input}: compile takes an AZee expression (.azee); a .json score needs no "
            "compiling: give it to realize, check --score, render or export as it is"
        )
    _outputs((args.output,), (args.input,), args.lexicon)
    lex = args.lexicon or ()
    if args.e is not None:
        score = compile_text(args.e, args.strong_side, lex, file="<-e>")
    else:
        score = compile_file(args.input, args.strong_side, lex)
    text = dump_score(score)
    if args.output is None:
        sys.stdout.write(text)
        return 0
    out = Path(args.output)
    with atomic_path(out, inputs=(args.input,) if args.input else ()) as tmp:
        tmp.write_text(text, encoding="utf-8")
    print(
        printable(f"{out}: written ({score['root']['end']:g} s, root {score['root']['name']})"),
        file=sys.stderr,
    )
    return 0


def _cmd_rules(args, run: _Run) -> int:
    from azee_mj.azee import RULES, Lexicon, rules_catalogue

    lex = Lexicon(args.lexicon or ())
    if args.json:
        print(json.dumps(rules_catalogue(lex)))
        return 0
    print(f"{len(RULES)} rules:")
    for r in RULES:
        alias = f" (alias {', '.join(':' + a for a in r.aliases)})" if r.aliases else ""
        print(f"  :{r.name}({r.signature()}){alias}")
        print(f"      {r.summary}")
        print(f"      source: {r.source}; approximated: {r.approximated}")
    names = lex.names()
    print(f"{len(names)} signs:")
    for n in names:
        s = lex.get(n)
        dur = f"{s.duration:g} s" if s.duration is not None else "expression"
        print(f"  :{n}({s.signature()}) {dur}" if s.params else f"  :{n} {dur}")
    return 0


def _v(v) -> str:
    return "[" + ", ".join(f"{x:+.3f}" for x in v) + "]"


def _cmd_check(args, run: _Run) -> int:
    from azee_mj.check import rollout_verdict, summary
    from azee_mj.model import load_model
    from azee_mj.rollout_io import load_rollout

    if Path(args.rollout).suffix.lower() in (".json", ".azee"):
        raise AzeeError(
            f"{args.rollout}: check takes a rollout .npz, and this is a score: realize it first "
            f"(azee-mj realize {args.rollout} -o OUT.npz), then azee-mj check OUT.npz "
            f"--score {args.rollout}"
        )
    model = load_model()
    rollout = load_rollout(args.rollout, model.nq, allow_nonfinite=True)  # NaN: a finding
    score, solver = None, None
    if args.score:
        from azee_mj.rollout_io import realized_score
        from azee_mj.schedule import make_solver
        from azee_mj.score import load_score

        score = realized_score(load_score(run.score_path(args.score, args.lexicon)), args.rollout)
        solver = make_solver()
    report = rollout_verdict(model, rollout, score, solver)
    lines = summary(report, rollout.fps).splitlines()
    ok = report.clean
    if score is not None:
        from azee_mj.timeline import residual_summary, rollout_speed_findings

        text, within = residual_summary(score, rollout, solver)
        found = rollout_speed_findings(score, rollout, solver)  # as realize says them
        more = [f"  ... and {len(found) - 5} more findings"] if len(found) > 5 else []
        lines += [*text.splitlines(), *(f"  finding: {f.describe()}" for f in found[:5]), *more]
        ok = ok and within and not found
    print("\n".join(map(printable, lines)))  # block names are the score's: never raw
    return 0 if ok else 1


class _Progress:
    """A one-line progress bar on a terminal's stderr; silent otherwise."""

    def __init__(self, label: str):
        self.label, self.on = label, sys.stderr.isatty()

    def __call__(self, fraction: float) -> None:
        if self.on:
            n = int(30 * fraction)
            end = "\n" if fraction >= 1.0 else ""
            print(
                f"\r{self.label} [{'#' * n}{'.' * (30 - n)}] {fraction:4.0%}",
                end=end,
                file=sys.stderr,
                flush=True,
            )


def _cmd_realize(args, run: _Run) -> int:
    from azee_mj.batch import fingerprint, missed, summary_lines
    from azee_mj.check import rollout_verdict, verdict_lines
    from azee_mj.files import save_json
    from azee_mj.model import load_model
    from azee_mj.rollout_io import save_rollout
    from azee_mj.schedule import make_solver
    from azee_mj.score import load_score
    from azee_mj.timeline import realize
    from azee_mj.timing import check_fps

    check_fps(args.fps)
    _not_empty(args)
    motion = _motion(args)
    if args.jobs is not None and args.jobs < 1:
        raise AzeeError(f"--jobs must be at least 1, got {args.jobs}")
    if len(args.score) > 1 or os.path.isdir(args.score[0]) or _dir_like(args.output):
        if args.dynamics:
            raise AzeeError("--dynamics realizes one score at a time (give one SCORE and OUT.npz)")
        if args.blinks is not None:
            raise AzeeError("--blinks: give one score (automatic blinks are per score)")
        return _realize_many(args, motion)
    if args.resume or args.manifest or args.scheduler:
        raise AzeeError("--resume, --manifest and --scheduler are for several scores (-o DIR/)")
    if args.dynamics and args.mode != "multitrack":
        raise AzeeError("--dynamics follows the multitrack realization; drop --mode flattened")
    path = args.score[0]
    _outputs((args.output, args.report), (path,), args.lexicon)
    score = _with_blinks(load_score(run.score_path(path, args.lexicon)), args)
    solver = make_solver()
    if args.dynamics:
        from azee_mj import physics

        rollout = physics.realize(score, fps=args.fps, progress=_Progress("realize"), **motion)
    else:
        rollout = realize(
            score,
            fps=args.fps,
            mode=args.mode,
            solver=solver,
            progress=_Progress("realize"),
            **motion,
        )
    azee = Path(path).suffix.lower() == ".azee"
    options = fingerprint(
        args.fps,
        args.mode,
        motion,
        (args.lexicon or ()) if azee else (),
        dynamics=args.dynamics,
        blinks=None if args.blinks is None else (args.blinks, args.blink_rate),
    )
    save_rollout(args.output, rollout, inputs=(path,), options=options)
    if args.report:
        save_json(args.report, rollout.report(), inputs=(path, args.output))
    # the penetration verdict 'check --score' would say of this rollout, said here too: on
    # the signer 'check' loads (the solver's copy lacks the visual geoms, whose numbers
    # name the unnamed geoms, and adds margins)
    timed = score.at_tempo(args.tempo) if args.tempo != 1.0 else score  # as realized
    verdict = rollout_verdict(load_model(), rollout, timed, solver)
    lines = summary_lines(args.output, rollout, args.fps)
    print("\n".join(map(printable, (lines[0], *verdict_lines(verdict, args.fps), *lines[1:]))))
    if args.dynamics:
        print(rollout.summary())
    return 1 if args.strict and (missed(rollout) or not verdict.clean) else 0


#: ``realize``'s options that take a name, and what to give: an empty one is an error
#: (never a silent default: ``--scheduler ''`` must not run here).
_NAMED = {
    "scheduler": "'local', an address such as tcp://HOST:8786, or a scheduler file (.json)",
    "manifest": "a file FILE.jsonl or FILE.csv",
    "report": "a file REPORT.json, or a directory DIR/ for several scores",
}


def _not_empty(args) -> None:
    """Refuse an option of :data:`_NAMED` given as an empty (or blank) text."""
    for opt, what in _NAMED.items():
        value = getattr(args, opt)
        if value is not None and not value.strip():
            raise AzeeError(f"--{opt} is empty; give {what}")


def _motion(args) -> dict:
    """The realizer's motion options from ``--no-rest``, ``--rest-hold``, ``--rest-gap``,
    ``--tempo`` (checked here: a bad one is exit 2 before any work)."""
    import math

    from azee_mj.blend import REST_GAP, REST_HOLD

    hold = REST_HOLD if args.rest_hold is None else args.rest_hold
    gap = REST_GAP if args.rest_gap is None else args.rest_gap
    for opt, v, lo, hi in (("--tempo", args.tempo, 0.1, 10.0), ("--rest-hold", hold, 0, 10)):
        if not (math.isfinite(v) and lo <= v <= hi):
            raise AzeeError(f"{opt} must be a number from {lo:g} to {hi:g}, got {v:g}")
    if not gap >= 0.0:
        raise AzeeError(f"--rest-gap must be a number of seconds from 0 (inf: never), got {gap:g}")
    return {"rest": not args.no_rest, "hold": hold, "tempo": args.tempo, "rest_gap": gap}


def _with_blinks(score, args):
    """``score`` with automatic blinks when ``--blinks SEED`` was given."""
    if getattr(args, "blinks", None) is None:
        return score
    from azee_mj.blinks import add_blinks

    return add_blinks(score, args.blinks, rate=args.blink_rate)


def _add_blinks(p) -> None:
    from azee_mj.blinks import RATE_PER_MIN

    p.add_argument(
        "--blinks",
        type=int,
        metavar="SEED",
        help="add automatic eye blinks, drawn from SEED (the same seed, the same blinks; "
        "default: none)",
    )
    p.add_argument(
        "--blink-rate",
        type=float,
        default=RATE_PER_MIN,
        metavar="PER_MIN",
        help=f"mean blinks per minute with --blinks (default {RATE_PER_MIN:g})",
    )


def _dir_like(path: str) -> bool:
    """A path written as a directory (``DIR/``)."""
    return path.endswith(("/", os.sep))


def _realize_many(args, motion: dict) -> int:
    """Several scores (or directories of them) to ``-o DIR/``: in a process pool (one
    process per core, or ``--jobs``), or on a Dask cluster (``--scheduler``), with the
    checked motion options ``motion`` (:func:`_motion`).

    Everything is checked before any score is realized: the output (and ``--report``)
    directories exist and are writable, no two scores write the same file, no output is an
    input, and the manifest may be written. A failing score never stops the others: exit 1
    if any failed or (with ``--strict``) missed a constraint, else 0."""
    from azee_mj.batch import plan, score_files
    from azee_mj.corpus import realize_corpus
    from azee_mj.files import check_output, check_output_dir
    from azee_mj.model import load_model

    scores = score_files(args.score)
    lexicon = args.lexicon or ()
    if any(s.suffix.lower() == ".azee" for s in scores):
        from azee_mj.azee import Lexicon

        Lexicon(lexicon)  # a bad --lexicon once, not once per expression
    check_output_dir(args.output)
    if args.report:
        check_output_dir(args.report)
    jobs = plan(scores, Path(args.output), Path(args.report) if args.report else None)
    inputs = [*scores, *_lexicon_files(args.lexicon)]
    for j in jobs:
        for out in (j.output, j.report):
            if out is not None:
                check_output(out, inputs)
    if args.manifest:
        check_output(args.manifest, inputs)
        if any(os.path.realpath(args.manifest) == os.path.realpath(j.output) for j in jobs):
            raise AzeeError(f"{args.manifest}: is also a score's output; write to another file")
    with contextlib.ExitStack() as stack:
        client = None
        if args.scheduler:
            from azee_mj.batch import usable_cores
            from azee_mj.cluster import open_client

            n = min(args.jobs or usable_cores(), len(jobs))
            client = stack.enter_context(open_client(args.scheduler, n))
        outcomes, _ = realize_corpus(
            jobs,
            nq=load_model().nq,
            fps=args.fps,
            mode=args.mode,
            workers=args.jobs,
            lexicon=lexicon,
            client=client,
            manifest=args.manifest,
            resume_run=args.resume,
            motion=motion,
        )
    if not all(o.ok for o in outcomes):
        return EXIT_FINDINGS
    return EXIT_FINDINGS if args.strict and any(o.missed for o in outcomes) else EXIT_OK


def _clip(args, run: _Run, progress: bool = True):
    """The clip of ``preview`` and ``render``: their input (and ``--score``), a score
    realized at ``--fps`` (default :data:`~azee_mj.timing.DEFAULT_FPS`)."""
    from azee_mj.markers import load_clip
    from azee_mj.timing import check_fps

    if args.fps is not None:
        check_fps(args.fps)
    score = run.score_path(args.score, args.lexicon)
    return load_clip(
        run.score_path(args.input, args.lexicon),
        score=score,
        fps=args.fps or DEFAULT_FPS,
        progress=_Progress("realize") if progress else None,
        blinks=getattr(args, "blinks", None),
        blink_rate=getattr(args, "blink_rate", None),
    )


def _cmd_preview(args, run: _Run) -> int:
    from azee_mj.viewer import preview

    clip = _clip(args, run)
    n = preview(clip, targets=not args.no_targets, max_frames=args.max_frames, camera=args.camera)
    if args.max_frames is not None:
        print(f"preview: {n} viewer updates")
    return 0


def _cmd_render(args, run: _Run) -> int:
    from azee_mj.render import check_render_options, parse_size, render

    size = parse_size(args.size)
    check_render_options(args.output, size, args.fps, args.time, args.jobs)  # before realizing
    _outputs((args.output,), (args.input, args.score), args.lexicon)
    clip = _clip(args, run)
    out = render(
        clip,
        args.output,
        camera=args.camera,
        size=size,
        fps=args.fps,
        time=args.time,
        targets=args.targets,
        antialias=not args.no_antialias,
        workers=args.jobs,
        progress=_Progress("render"),
    )
    print(printable(f"{out}: written"))
    return 0


def _cmd_report(args, run: _Run) -> int:
    from azee_mj.report import write_report
    from azee_mj.timing import check_fps

    fps = check_fps(args.fps)
    as_dir = _dir_like(args.output) or os.path.isdir(args.output)
    _outputs((args.output,), (args.score,), args.lexicon, directory=as_dir)
    paths = write_report(
        run.score_path(args.score, args.lexicon),
        args.output,
        fps=fps,
        progress=_Progress("report"),
        dynamics=args.dynamics,
    )
    for p in paths:
        print(printable(f"{p}: written"))
    return 0


def _cmd_export(args, run: _Run) -> int:
    from azee_mj.export import export
    from azee_mj.timing import check_fps

    check_fps(args.fps)
    _outputs((args.output,), (args.input, args.score), args.lexicon)
    out = export(
        run.score_path(args.input, args.lexicon),
        args.output,
        score=run.score_path(args.score, args.lexicon),
        fps=args.fps,
    )
    print(printable(f"{out}: written"))
    return 0


#: Per command: its one-line help, and what its ``--help`` says next.
COMMANDS = {
    "sites": (
        "list the AZee catalogue (sites, bones, loci, morphs)",
        (
            "The names a score may use: AZee sites, bones (with their body, direction and normal), "
            "signing-space loci and facial morphs."
        ),
    ),
    "compile": (
        "compile an AZee expression (.azee) to a score",
        (
            "Reads one AZee expression (a file, or -e TEXT) with the bundled signs and any "
            "--lexicon directories, and writes an azee-score JSON file that realize, check, render "
            "and export take."
        ),
    ),
    "rules": (
        "list the rules and signs of the .azee front end",
        (
            "The production rules the .azee front end knows, with their arguments and sources, and "
            "the signs of the lexicon."
        ),
    ),
    "realize": (
        "realize a score to a rollout .npz (or many to DIR/)",
        (
            "Solves the score's postures frame by frame and writes the rollout (postures, site "
            "positions, schedule, residuals); prints how many constraints were met, the "
            "penetrations check would find, and why any constraint missed."
        ),
    ),
    "check": (
        "check a rollout for penetrations and range violations",
        (
            "Reports penetrations deeper than the limit, joints outside their range and non-finite "
            "frames; with --score, also each constraint's residual and the speeds over the human "
            "range, as realize says them. Exit 1 on any finding."
        ),
    ),
    "preview": (
        "play a score or rollout in the MuJoCo viewer",
        "Opens the interactive MuJoCo viewer on the motion (needs a display).",
    ),
    "render": (
        "render a score or rollout offscreen to .mp4, .gif or .png",
        (
            "Draws the motion with MuJoCo's offscreen renderer to a video, a GIF, one still frame "
            "or a contact sheet of the key postures."
        ),
    ),
    "export": (
        "export a score or rollout to .glb, .gltf, .bvh, .pose, .csv or a web player .html",
        (
            "Writes the motion for other tools: glTF/GLB, BVH, .pose, CSV of site positions, or a "
            "self-contained web player page."
        ),
    ),
    "report": (
        "HTML report (or PNG set) of a score's realization",
        (
            "Realizes the score and writes its timeline per track, the solver's work and the "
            "residuals as one HTML page, or as PNG files in a directory."
        ),
    ),
}


def _command(sub, name: str) -> argparse.ArgumentParser:
    """The subcommand ``name`` of :data:`COMMANDS`: its ``--help`` starts with its one-line
    help and says next what it does."""
    help, more = COMMANDS[name]
    description = f"{help[0].upper()}{help[1:]}. {more}"
    return sub.add_parser(name, help=help, description=description)


_FPS_DEFAULT = f"(default {DEFAULT_FPS:g})"


def build_parser() -> argparse.ArgumentParser:
    from azee_mj import __version__

    p = argparse.ArgumentParser(
        prog="azee-mj", description="Realize AZee sign-language scores on a MuJoCo signer."
    )
    p.add_argument("--version", action="version", version=f"azee-mj {__version__}")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    s = _command(sub, "sites")
    s.add_argument("--json", action="store_true", help="print one JSON object")
    s.set_defaults(func=_cmd_sites)

    a = _command(sub, "compile")
    a.add_argument("input", nargs="?", metavar="EXPR.azee", help="the expression file")
    a.add_argument("-e", metavar="TEXT", help="the expression as text instead of a file")
    a.add_argument("-o", "--output", help="SCORE.json (default: standard output)")
    a.add_argument(
        "--strong-side", choices=["R", "L"], default="R", help="the score's strong side (default R)"
    )
    _add_lexicon(a)
    a.set_defaults(func=_cmd_compile)

    u = _command(sub, "rules")
    u.add_argument("--json", action="store_true", help="print one JSON object")
    _add_lexicon(u)
    u.set_defaults(func=_cmd_rules)

    r = _command(sub, "realize")
    r.add_argument(
        "score",
        nargs="+",
        metavar="SCORE",
        help="SCORE.json (azee-score version 1) or EXPR.azee; several, or a "
        "directory of them (*.json, *.azee), are realized in parallel to -o DIR/",
    )
    r.add_argument(
        "-o",
        "--output",
        required=True,
        help="OUT.npz, or an existing DIR/ for NAME.npz of each score",
    )
    r.add_argument(
        "--fps", type=float, default=DEFAULT_FPS, help=f"frames per second {_FPS_DEFAULT}"
    )
    r.add_argument(
        "--mode",
        choices=["multitrack", "flattened"],
        default="multitrack",
        help="blocks per articulator track (default) or the 2018 flattened method",
    )
    r.add_argument(
        "--report",
        help="also write residuals and timings to REPORT.json "
        "(an existing DIR/ for several scores)",
    )
    r.add_argument(
        "--strict",
        action="store_true",
        help="exit 1 if any constraint is not met or the motion leaves the human range "
        "(a finding; default: 0, and say why)",
    )
    r.add_argument(
        "--no-rest",
        action="store_true",
        help="no lead-in from rest nor return to rest: start in the first posture, keep the last",
    )
    r.add_argument(
        "--rest-hold",
        type=float,
        metavar="S",
        help="seconds a hand, the head or the trunk holds its last posture before relaxing "
        "to rest (default 0.3)",
    )
    r.add_argument(
        "--rest-gap",
        type=float,
        metavar="S",
        help="a hand, the head or the trunk whose next block is at least S seconds away "
        "returns to rest in between and comes back (default 1.5; inf: never)",
    )
    r.add_argument(
        "--tempo",
        type=float,
        default=1.0,
        metavar="F",
        help="play the score F times as fast (0.5: half speed; default 1)",
    )
    r.add_argument(
        "--jobs",
        type=int,
        help="processes (or local Dask workers) for several scores (default: one per usable core)",
    )
    r.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="realize several scores on Dask: 'local' (a cluster of --jobs workers here), a "
        "scheduler address (tcp://HOST:8786) or a scheduler file (.json); needs the cluster "
        "extra",
    )
    r.add_argument(
        "--resume",
        action="store_true",
        help="skip the scores whose output (and report) exist, are newer than the score, "
        "validate and were realized with the same options (fps, mode, rest, tempo, ...): "
        "finish a stopped batch",
    )
    r.add_argument(
        "--manifest",
        metavar="FILE",
        help="write one row per score (input, output, duration, frames, constraints met, "
        "findings, time, worker) to FILE.jsonl or FILE.csv",
    )
    r.add_argument(
        "--dynamics",
        action="store_true",
        help="physics mode: MuJoCo moves the signer along the realization, with human "
        "torque limits (adds torques, effort and energy; docs/physics.md)",
    )
    _add_blinks(r)
    _add_lexicon(r)
    r.set_defaults(func=_cmd_realize)

    c = _command(sub, "check")
    c.add_argument("rollout", help="ROLLOUT.npz written by 'azee-mj realize'")
    c.add_argument(
        "--score", help="the score it realizes (.json or .azee): also report constraint residuals"
    )
    _add_lexicon(c)
    c.set_defaults(func=_cmd_check)

    from azee_mj.render import CAMERAS

    v = _command(sub, "preview")
    v.add_argument(
        "input",
        metavar="SCORE|ROLLOUT",
        help="SCORE.json or EXPR.azee (realized first) or ROLLOUT.npz",
    )
    v.add_argument("--score", help="the score of a ROLLOUT.npz, to draw its targets")
    _add_lexicon(v)
    v.add_argument("--fps", type=float, help=f"frames per second when realizing {_FPS_DEFAULT}")
    v.add_argument("--camera", choices=CAMERAS, help="start from a fixed camera (default: free)")
    v.add_argument("--no-targets", action="store_true", help="do not draw constraint targets")
    v.add_argument("--max-frames", type=int, help=argparse.SUPPRESS)  # for tests
    _add_blinks(v)
    v.set_defaults(func=_cmd_preview)

    w = _command(sub, "render")
    w.add_argument(
        "input",
        metavar="SCORE|ROLLOUT",
        help="SCORE.json or EXPR.azee (realized first) or ROLLOUT.npz",
    )
    w.add_argument("-o", "--output", required=True, help="OUT.mp4, OUT.gif or OUT.png")
    _add_lexicon(w)
    w.add_argument("--score", help="the score of a ROLLOUT.npz (targets, contact sheet labels)")
    w.add_argument("--camera", choices=CAMERAS, default="front", help="camera (default front)")
    w.add_argument("--size", default="640x480", help="WxH in pixels (default 640x480)")
    w.add_argument("--fps", type=float, help="video frames per second (default: the rollout's)")
    w.add_argument(
        "--time",
        type=float,
        help="for .png: the frame at T seconds (default: a contact sheet of the key postures)",
    )
    w.add_argument("--targets", action="store_true", help="draw constraint targets")
    w.add_argument(
        "--no-antialias",
        action="store_true",
        help="no supersampling: about 1.5 times as fast in software GL, with jagged edges",
    )
    w.add_argument(
        "--jobs",
        type=int,
        help="processes rendering video frames (default: 2 "
        "where 2 cores are usable, 1 for short videos)",
    )
    _add_blinks(w)
    w.set_defaults(func=_cmd_render)

    e = _command(sub, "export")
    e.add_argument(
        "input",
        metavar="SCORE|ROLLOUT",
        help="SCORE.json or EXPR.azee (realized first) or ROLLOUT.npz",
    )
    e.add_argument(
        "-o",
        "--output",
        required=True,
        help="OUT.glb, OUT.gltf, OUT.bvh, OUT.pose, OUT.csv or OUT.html",
    )
    e.add_argument("--score", help="the score of a ROLLOUT.npz (the player shows its blocks)")
    _add_lexicon(e)
    e.add_argument(
        "--fps",
        type=float,
        default=DEFAULT_FPS,
        help=f"frames per second when realizing a score {_FPS_DEFAULT}",
    )
    e.set_defaults(func=_cmd_export)

    h = _command(sub, "report")
    h.add_argument("score", help="SCORE.json or EXPR.azee")
    _add_lexicon(h)
    h.add_argument("-o", "--output", required=True, help="REPORT.html, or DIR/ for PNG files")
    h.add_argument(
        "--fps", type=float, default=DEFAULT_FPS, help=f"frames per second {_FPS_DEFAULT}"
    )
    h.add_argument(
        "--dynamics", action="store_true", help="report the physics mode (adds the dynamics)"
    )
    h.set_defaults(func=_cmd_report)
    return p


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``azee-mj``; returns the exit status (see the module docstring).

    ``--debug`` anywhere on the command line shows the traceback of an internal error."""
    from azee_mj.files import Terminated, install_signal_handlers, remove_temporaries

    argv = list(sys.argv[1:] if argv is None else argv)
    debug = "--debug" in argv
    argv = [a for a in argv if a != "--debug"]
    try:
        install_signal_handlers()  # before the parser imports the renderer (about 1 s)
    except ValueError:  # not the main thread: signals stay as they are
        pass
    unknown = _unknown_command(argv)
    if unknown:
        print(f"azee-mj: error: {unknown}", file=sys.stderr)
        return EXIT_BAD_INPUT
    try:
        args = build_parser().parse_args(argv)
        with contextlib.ExitStack() as cleanup:
            return args.func(args, _Run(cleanup))
    except AzeeError as e:
        print(f"azee-mj: error: {one_line(str(e))}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except BrokenPipeError:  # '| head': the reader has what it wanted
        _quiet_stdout()
        return EXIT_OK
    except PermissionError as e:  # an input nobody checked before reading it
        remove_temporaries()
        where = f"{e.filename}: " if e.filename else ""
        print(f"azee-mj: error: {one_line(f'{where}permission denied')}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        remove_temporaries()
        print("azee-mj: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Terminated:
        print("azee-mj: terminated", file=sys.stderr)
        return EXIT_TERMINATED
    except MemoryError:
        remove_temporaries()
        print(
            "azee-mj: error: out of memory; try a shorter score or a lower --fps", file=sys.stderr
        )
        return EXIT_BAD_INPUT
    except Exception as e:  # noqa: BLE001 - a bug: one line, the traceback only when asked
        remove_temporaries()
        if debug:
            import traceback

            traceback.print_exc()
        what = shorten(printable(f"{type(e).__name__}: {e}"), 200)
        print(
            f"azee-mj: internal error ({what}); please report it with the command and its "
            "input files (add --debug for the traceback)",
            file=sys.stderr,
        )
        return EXIT_INTERNAL


def __getattr__(name: str):
    """``load_clip`` is :func:`azee_mj.markers.load_clip`, imported when first asked for (the
    command line itself starts without the realizing modules)."""
    if name == "load_clip":
        from azee_mj.markers import load_clip

        return load_clip
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _unknown_command(argv: list[str]) -> str:
    """The message for a first word that is no command (with the closest one), else ""."""
    import difflib

    if not argv or argv[0].startswith("-"):
        return ""
    commands = list(COMMANDS)
    if argv[0] in commands:
        return ""
    close = difflib.get_close_matches(argv[0], commands, n=1, cutoff=0.6)
    hint = f"; did you mean {close[0]!r}?" if close else ""
    return one_line(f"unknown command {argv[0]!r}{hint} (commands: {', '.join(commands)})")


def _quiet_stdout() -> None:
    """Point standard output at /dev/null, so that the interpreter's last flush into the
    closed pipe is silent too."""
    with contextlib.suppress(OSError, ValueError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)


if __name__ == "__main__":
    sys.exit(main())
