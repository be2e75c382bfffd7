"""Realizing many scores at once: one worker process per core, one solver per worker.

Each score (a ``SCORE.json`` or an ``EXPR.azee``) is realized exactly as it would be alone
(the solver keeps no state between scores) and its rollout written by the output rule of
:mod:`azee_mj.files` (a temporary file renamed when complete), so an output is whole or
absent. A bad score costs only its own output: its one-line message names the file, the
others still complete. Stopping the batch (SIGTERM, Ctrl-C) stops every worker and leaves
no temporary file. Units: frames per second.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from azee_mj.errors import AzeeError

if TYPE_CHECKING:
    from azee_mj.azee import Lexicon
    from azee_mj.ik import Solver
    from azee_mj.score import Score
    from azee_mj.timeline import Rollout

#: What a directory given as input contributes: its scores and expressions (not recursive).
SCORE_PATTERNS = ("*.json", "*.azee")


@dataclass(frozen=True)
class Job:
    """One score to realize: ``score`` -> rollout ``output`` (and optional ``report`` JSON)."""

    score: Path
    output: Path
    report: Path | None = None


@dataclass(frozen=True)
class Outcome:
    """What became of a :class:`Job`: ``lines`` to print on success, else ``error``;
    ``missed`` constraints out of tolerance; ``wall`` and ``cpu`` are the seconds it took in
    its worker (elapsed, and CPU time)."""

    job: Job
    lines: tuple[str, ...] = ()
    error: str = ""
    missed: int = 0
    wall: float = 0.0
    cpu: float = 0.0

    @property
    def ok(self) -> bool:
        return not self.error


def usable_cores() -> int:
    """The number of cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def score_files(inputs: Iterable[str | os.PathLike]) -> list[Path]:
    """The score paths of ``inputs``: files as given, directories as their ``*.json`` and
    ``*.azee`` files (sorted, not recursive). Raises :class:`AzeeError` for a directory
    without any."""
    out: list[Path] = []
    for p in map(Path, inputs):
        if p.is_dir():
            found = sorted(f for pat in SCORE_PATTERNS for f in p.glob(pat) if f.is_file())
            if not found:
                raise AzeeError(f"{p}: no *.json or *.azee scores in this directory")
            out.extend(found)
        else:
            out.append(p)
    return out


def plan(scores: Sequence[Path], out_dir: Path, report_dir: Path | None = None) -> list[Job]:
    """Jobs writing ``out_dir/STEM.npz`` (and ``report_dir/STEM.json``) for each score.
    Raises :class:`AzeeError` when two scores would write the same output."""
    jobs, seen = [], {}
    for s in scores:
        out = out_dir / f"{s.stem}.npz"
        if out in seen:
            raise AzeeError(f"{seen[out]} and {s} would both write {out}; rename one")
        seen[out] = s
        jobs.append(Job(s, out, report_dir / f"{s.stem}.json" if report_dir else None))
    return jobs


def missed(rollout: Rollout) -> int:
    """Constraints out of tolerance plus findings (what ``--strict`` fails on)."""
    bad = sum(not t.ok for t in rollout.traces)
    return bad + sum(f.kind != "constraint" for f in rollout.findings)


def summary_lines(output: str | os.PathLike, rollout: Rollout, fps: float) -> tuple[str, ...]:
    """What ``azee-mj realize`` prints for a rollout written to ``output``: one line, then
    why each missed constraint missed (the first five), then the findings (the first
    five)."""
    s = rollout.stats
    bad = [t for t in rollout.traces if not t.ok]
    lead = f", the score from {rollout.score_start:.2f} s" if rollout.score_start else ""
    head = (
        f"{output}: {len(rollout.time)} frames at {fps:g} fps{lead}, {s.problems} IK "
        f"problems ({s.iterations} iterations) in {s.total_time:.3f} s; "
        f"{len(rollout.traces) - len(bad)}/{len(rollout.traces)} constraints within "
        f"tolerance"
    )
    more = (f"  ... and {len(bad) - 5} more (see --report)",) if len(bad) > 5 else ()
    found = [f for f in rollout.findings if f.kind != "constraint"]
    extra = (f"  ... and {len(found) - 5} more findings (see --report)",) if len(found) > 5 else ()
    lines = [f"  finding: {f.describe()}" for f in found[:5]]
    return (head, *(f"  {t.describe()}" for t in bad[:5]), *more, *lines, *extra)


def read_score(
    path: str | os.PathLike, lexicon: Iterable[str | os.PathLike] | Lexicon = ()
) -> Score:
    """The score at ``path``: a ``SCORE.json``, or an ``EXPR.azee`` compiled with the sign
    directories ``lexicon`` (searched before the bundled lexicon)."""
    from azee_mj.score import load_score

    if Path(path).suffix.lower() == ".azee":
        from azee_mj.azee import compile_file

        return load_score(compile_file(path, lexicon=lexicon))
    return load_score(path)


def realize_file(
    job: Job,
    *,
    fps: float,
    mode: str,
    solver: Solver | None = None,
    lexicon: Iterable[str | os.PathLike] | Lexicon = (),
    progress: Callable[[float], None] | None = None,
    motion: Mapping | None = None,
) -> Rollout:
    """Realize ``job.score`` and write its rollout (and report) atomically; the rollout.
    ``motion``: the realizer's ``rest``, ``hold`` and ``tempo`` (see
    :func:`~azee_mj.timeline.realize`). Raises :class:`AzeeError` for a bad score or an
    output that may not be written."""
    from azee_mj.files import save_json
    from azee_mj.rollout_io import save_rollout
    from azee_mj.timeline import realize

    rollout = realize(
        read_score(job.score, lexicon),
        fps=fps,
        mode=mode,
        solver=solver,
        progress=progress,
        **(motion or {}),
    )
    save_rollout(job.output, rollout, inputs=(job.score,))
    if job.report is not None:
        save_json(job.report, rollout.report(), inputs=(job.score, job.output))
    return rollout


_SOLVER: Solver | None = None
_LEXICON: Lexicon | tuple[str, ...] = ()
_PRELOAD = (
    "azee_mj.azee",
    "azee_mj.batch",
    "azee_mj.files",
    "azee_mj.rollout_io",
    "azee_mj.schedule",
    "azee_mj.score",
    "azee_mj.timeline",
)


def _prepare(lexicon: Sequence[str]) -> None:
    """One solver and one lexicon for all the jobs of this process."""
    global _SOLVER, _LEXICON
    from azee_mj.schedule import make_solver

    _SOLVER = make_solver()
    _LEXICON = ()
    if lexicon:
        from azee_mj.azee import Lexicon

        _LEXICON = Lexicon(lexicon)


def _on_term(signum, frame) -> None:
    from azee_mj.files import remove_temporaries

    remove_temporaries()
    os._exit(128 + signum)


def _init_worker(lexicon: Sequence[str]) -> None:
    """A pool worker: SIGTERM removes the file being written and ends the worker at once;
    Ctrl-C is left to the parent, which stops the workers."""
    signal.signal(signal.SIGTERM, _on_term)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _prepare(lexicon)


def _run(job: Job, fps: float, mode: str, motion: Mapping | None = None) -> Outcome:
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        rollout = realize_file(
            job, fps=fps, mode=mode, solver=_SOLVER, lexicon=_LEXICON, motion=motion
        )
    except AzeeError as e:
        msg = str(e)
        error = msg if msg.startswith(str(job.score)) else f"{job.score}: {msg}"
        return Outcome(
            job, error=error, wall=time.perf_counter() - t0, cpu=time.process_time() - c0
        )
    return Outcome(
        job,
        summary_lines(job.output, rollout, fps),
        missed=missed(rollout),
        wall=time.perf_counter() - t0,
        cpu=time.process_time() - c0,
    )


def _size(path: Path) -> int:
    try:
        return path.stat().st_size
    except OSError:
        return 0


def realize_many(
    jobs: Sequence[Job],
    *,
    fps: float = 50.0,
    mode: str = "multitrack",
    workers: int | None = None,
    lexicon: Iterable[str | os.PathLike] = (),
    on_done: Callable[[Outcome, int], None] | None = None,
    motion: Mapping | None = None,
) -> list[Outcome]:
    """Realize every job, ``workers`` processes at once (default :func:`usable_cores`;
    1 runs here, without a pool); ``.azee`` scores are compiled with the sign directories
    ``lexicon``. ``on_done(outcome, finished)`` is called in this process as each job ends,
    in completion order; the outcomes are returned in job order. The output directories
    must exist (the output rule of :mod:`azee_mj.files`).

    Workers start with the ``forkserver`` method where there is one (``spawn`` otherwise),
    so no GL or MuJoCo state is inherited, and each compiles one solver for all its jobs.
    An exception here (Ctrl-C, SIGTERM, a worker that died) cancels the jobs not started
    and terminates the workers, each removing the file it was writing, before it propagates.
    """
    workers = max(1, min(workers or usable_cores(), len(jobs)))
    lex = tuple(map(str, lexicon))
    done: dict[int, Outcome] = {}

    def finish(i: int, o: Outcome) -> None:
        done[i] = o
        if on_done is not None:
            on_done(o, len(done))

    if workers == 1:
        _prepare(lex)
        for i, job in enumerate(jobs):
            finish(i, _run(job, fps, mode, motion))
        return [done[i] for i in range(len(jobs))]
    if "forkserver" in multiprocessing.get_all_start_methods():
        ctx = multiprocessing.get_context("forkserver")
        # Import once in the server (if not started yet), not in every worker.
        ctx.set_forkserver_preload(list(_PRELOAD))
    else:
        ctx = multiprocessing.get_context("spawn")
    before = set(multiprocessing.active_children())
    pool = ProcessPoolExecutor(workers, mp_context=ctx, initializer=_init_worker, initargs=(lex,))
    try:
        # Largest scores first, so that no long one starts last while the other workers idle.
        order = sorted(range(len(jobs)), key=lambda i: -_size(jobs[i].score))
        pending = {pool.submit(_run, jobs[i], fps, mode, motion): i for i in order}
        while pending:
            finished, _ = wait(pending, return_when=FIRST_COMPLETED)
            for f in finished:
                finish(pending.pop(f), f.result())
    except BaseException:
        pool.shutdown(wait=False, cancel_futures=True)
        started = set(multiprocessing.active_children()) - before
        for p in started:
            p.terminate()
        for p in started:
            p.join()
        raise
    finally:
        pool.shutdown(wait=True)
    return [done[i] for i in range(len(jobs))]
