"""Realizing many scores at once: on one worker process per core (the default), or on the
workers of a Dask cluster (the ``cluster`` extra), one solver per worker.

Each score (a ``SCORE.json`` or an ``EXPR.azee``) is realized exactly as it would be alone
(the solver keeps no state between scores) and its rollout written by the output rule of
:mod:`azee_mj.files` (a temporary file renamed when complete), so an output is whole or
absent. A failing score costs only its own output: a bad score gives its one-line message
naming the file, an unexpected error (a bug) an "internal error" line naming it, and the
others still complete. Stopping the batch (SIGTERM, Ctrl-C) stops every worker and leaves
no temporary file; a worker whose batch process died (SIGKILL, SIGHUP) ends itself within a
second (:func:`lifeline`). Units: frames per second, seconds.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import re
import signal
import socket
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from azee_mj.errors import AzeeError
from azee_mj.lifeline import lifeline, worker_context

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
    """What became of a :class:`Job`: ``lines`` to print on success, else ``error``.

    ``duration`` is the score's length [s], ``frames`` the rollout's; ``constraints`` were
    traced, ``missed`` of them out of tolerance; ``findings`` counts what ``azee-mj check``
    finds in the rollout (penetrations, joint-range violations, non-finite postures);
    ``wall`` and ``cpu`` are the seconds it took in its worker (elapsed, and CPU time);
    ``worker`` is ``HOST:PID`` of the process that realized it."""

    job: Job
    lines: tuple[str, ...] = ()
    error: str = ""
    missed: int = 0
    wall: float = 0.0
    cpu: float = 0.0
    duration: float = 0.0
    frames: int = 0
    constraints: int = 0
    findings: int = 0
    worker: str = ""

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
    Raises :class:`AzeeError` when two scores would write the same file, also through a
    symbolic link already in an output directory."""
    jobs, seen = [], {}
    for s in scores:
        job = Job(
            s, out_dir / f"{s.stem}.npz", report_dir / f"{s.stem}.json" if report_dir else None
        )
        for out in (job.output, job.report):
            if out is None:
                continue
            real = os.path.realpath(out)
            if real in seen:
                other, first = seen[real]
                via = "" if first == out else f" (through {first} and {out})"
                raise AzeeError(f"{other} and {s} would both write {real}{via}; rename one")
            seen[real] = (s, out)
        jobs.append(job)
    return jobs


def fingerprint(
    fps: float,
    mode: str = "multitrack",
    motion: Mapping | None = None,
    lexicon: Iterable[str | os.PathLike] = (),
    *,
    dynamics: bool = False,
    blinks: tuple[int, float] | None = None,
) -> str:
    """The options a rollout was realized with, as one line that the same options always
    give and other options never do, e.g. ``fps=50.0;mode=multitrack;rest=1;hold=0.3;
    tempo=1.0;gap=1.5``: ``fps`` [frames/s], the ``mode``, the ``motion`` options
    (``rest``, ``hold`` [s], ``tempo``, ``rest_gap`` [s]; defaults filled in), the sign
    directories ``lexicon`` an ``.azee`` score was compiled with (absolute paths; their
    contents are not read),
    ``dynamics`` (the physics mode) and automatic ``blinks`` (seed, rate per minute).
    ``--resume`` realizes again an output whose recorded fingerprint differs."""
    from azee_mj.blend import REST_GAP, REST_HOLD

    m = dict(motion or {})
    parts = [
        f"fps={float(fps)!r}",
        f"mode={mode}",
        f"rest={int(bool(m.get('rest', True)))}",
        f"hold={float(m.get('hold', REST_HOLD))!r}",
        f"tempo={float(m.get('tempo', 1.0))!r}",
        f"gap={float(m.get('rest_gap', REST_GAP))!r}",
    ]
    if dynamics:
        parts.append("dynamics=1")
    if blinks is not None:
        parts.append(f"blinks={int(blinks[0])}@{float(blinks[1])!r}")
    dirs = [os.path.abspath(d) for d in lexicon]
    if dirs:
        parts.append("lexicon=" + "|".join(dirs))
    return ";".join(parts)


def job_fingerprint(
    job: Job, fps: float, mode: str, motion: Mapping | None, lexicon: Iterable = ()
) -> str:
    """:func:`fingerprint` of ``job`` realized with these options (the ``lexicon`` counts
    for an ``.azee`` score only: a ``SCORE.json`` never reads it)."""
    dirs = getattr(lexicon, "dirs", lexicon)  # a Lexicon, or its directories
    azee = job.score.suffix.lower() == ".azee"
    return fingerprint(fps, mode, motion, dirs if azee else ())


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
    return _realize_file(job, fps, mode, solver, lexicon, progress, motion)[1]


def _realize_file(job, fps, mode, solver, lexicon, progress, motion=None) -> tuple[Score, Rollout]:
    """The score as realized (at its tempo) and its rollout, written."""
    from azee_mj.files import save_json
    from azee_mj.rollout_io import save_rollout
    from azee_mj.timeline import at_tempo, realize

    motion = dict(motion or {})
    options = job_fingerprint(job, fps, mode, motion, lexicon)
    score = read_score(job.score, lexicon)
    rollout = realize(score, fps=fps, mode=mode, solver=solver, progress=progress, **motion)
    score = at_tempo(score, motion.get("tempo", 1.0), 0.0)
    save_rollout(job.output, rollout, inputs=(job.score,), options=options)
    if job.report is not None:
        save_json(job.report, rollout.report(), inputs=(job.score, job.output))
    return score, rollout


#: The random part of a temporary file's name (:func:`tempfile.mkstemp`'s).
_RANDOM = re.compile(r"[a-z0-9_]{8}")


def remove_temporaries_of(*jobs: Job) -> int:
    """Remove the temporary files killed workers left for the outputs of ``jobs`` (the
    hidden ``.NAME.XXXXXXXX.SUFFIX`` files of :func:`azee_mj.files.atomic_path`), reading
    each output directory once; how many."""
    names: dict[Path, set[str]] = {}
    for job in jobs:
        for out in (job.output, job.report):
            if out is not None:
                real = Path(os.path.realpath(out))
                names.setdefault(real.parent, set()).add(real.name)
    n = 0
    for folder, mine in names.items():
        try:
            entries = os.listdir(folder)
        except OSError:
            continue
        for entry in entries:
            if entry.startswith(".") and _temporary_of(entry) in mine:
                with contextlib.suppress(OSError):
                    os.unlink(folder / entry)
                    n += 1
    return n


def _temporary_of(entry: str) -> str | None:
    """The output name whose temporary file ``entry`` (``.NAME.XXXXXXXX.SUFFIX``, SUFFIX
    the output's own) would be, or None."""
    for suffix in {Path(entry).suffix, ""}:
        core = entry[1 : len(entry) - len(suffix)]
        name = core[:-9]
        random = len(core) > 9 and core[-9] == "." and _RANDOM.fullmatch(core[-8:])
        if random and Path(name).suffix == suffix:
            return name
    return None


# -- the worker side: one solver and one lexicon per worker thread -----------------------

_LOCAL = threading.local()


def _worker_state(lexicon: tuple[str, ...]) -> tuple[Solver, Lexicon | tuple[str, ...]]:
    """This thread's solver and the lexicon of ``lexicon`` (made on first use, kept)."""
    if getattr(_LOCAL, "key", None) != lexicon:
        from azee_mj.schedule import make_solver

        lex: Lexicon | tuple[str, ...] = ()
        if lexicon:
            from azee_mj.azee import Lexicon

            lex = Lexicon(lexicon)
        _LOCAL.solver = getattr(_LOCAL, "solver", None) or make_solver()
        _LOCAL.lexicon, _LOCAL.key = lex, lexicon
    return _LOCAL.solver, _LOCAL.lexicon


def worker_name() -> str:
    """``HOST:PID`` of this process (a manifest's ``worker``)."""
    return f"{socket.gethostname()}:{os.getpid()}"


def findings(score: Score, rollout: Rollout, solver: Solver) -> int:
    """How many findings ``azee-mj check --score`` reports on ``rollout`` (``score`` as
    realized, at its tempo): the penetrations, joint-range violations and non-finite
    postures or sites of its verdict, on the signer ``check`` loads, and the speeds over the
    human range."""
    from azee_mj.check import rollout_verdict
    from azee_mj.model import load_model
    from azee_mj.timeline import rollout_speed_findings

    if getattr(_LOCAL, "check_model", None) is None:
        _LOCAL.check_model = load_model()
    v = rollout_verdict(_LOCAL.check_model, rollout, score, solver)
    found = (v.penetrations, v.range_violations, v.nonfinite, v.nonfinite_sites)
    return sum(map(len, found)) + len(rollout_speed_findings(score, rollout, solver))


def run_job(
    job: Job, fps: float, mode: str, lexicon: tuple[str, ...] = (), motion: Mapping | None = None
) -> Outcome:
    """Realize one job in this worker (``motion``: see :func:`realize_file`) and say what
    became of it; never raises (but for ``KeyboardInterrupt`` and the like): a bad score or
    a bug is the outcome's ``error``."""
    t0, c0 = time.perf_counter(), time.process_time()

    def failed(error: str) -> Outcome:
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        return Outcome(job, error=error, wall=wall, cpu=cpu, worker=worker_name())

    try:
        solver, lex = _worker_state(lexicon)
        score, rollout = _realize_file(job, fps, mode, solver, lex, None, motion)
        found = findings(score, rollout, solver)
    except AzeeError as e:
        msg = str(e)
        return failed(msg if msg.startswith(str(job.score)) else f"{job.score}: {msg}")
    except Exception as e:  # noqa: BLE001 - a bug (or RecursionError): this score only
        from azee_mj.errors import shorten

        return failed(f"{job.score}: internal error ({shorten(f'{type(e).__name__}: {e}', 200)})")
    return Outcome(
        job,
        summary_lines(job.output, rollout, fps),
        missed=missed(rollout),
        wall=time.perf_counter() - t0,
        cpu=time.process_time() - c0,
        duration=float(score.duration),
        frames=len(rollout.time),
        constraints=len(rollout.traces),
        findings=found,
        worker=worker_name(),
    )


# -- the process pool -----------------------------------------------------------------------

_PRELOAD = (
    "azee_mj.azee",
    "azee_mj.batch",
    "azee_mj.check",
    "azee_mj.files",
    "azee_mj.rollout_io",
    "azee_mj.schedule",
    "azee_mj.score",
    "azee_mj.timeline",
)


def _on_term(signum, frame) -> None:
    from azee_mj.files import remove_temporaries

    remove_temporaries()
    os._exit(128 + signum)


def _init_worker(lexicon: tuple[str, ...], parent: int) -> None:
    """A pool worker: SIGTERM removes the file being written and ends the worker at once;
    Ctrl-C is left to the parent, which stops the workers; the worker ends with ``parent``."""
    signal.signal(signal.SIGTERM, _on_term)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    lifeline(parent)
    _worker_state(lexicon)


def _size(path: Path) -> int:
    try:
        return path.stat().st_size
    except OSError:
        return 0


def largest_first(jobs: Sequence[Job]) -> list[int]:
    """Job indices, largest score file first (so no long score starts last while the
    other workers idle)."""
    return sorted(range(len(jobs)), key=lambda i: -_size(jobs[i].score))


@contextlib.contextmanager
def _pool(workers: int, lexicon: tuple[str, ...]):
    """A process pool whose workers end with this process; any exception here (Ctrl-C,
    SIGTERM) terminates them, each removing the file it was writing."""
    before = set(multiprocessing.active_children())
    pool = ProcessPoolExecutor(
        workers,
        mp_context=worker_context(_PRELOAD),
        initializer=_init_worker,
        initargs=(lexicon, os.getpid()),
    )
    try:
        yield pool
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


def _pool_outcomes(
    jobs: Sequence[Job],
    fps: float,
    mode: str,
    workers: int,
    lexicon: tuple[str, ...],
    motion: Mapping | None = None,
) -> Iterator[tuple[int, Outcome]]:
    """(index, outcome) of every job as it ends, ``workers`` processes at once.

    At most ``workers`` jobs are handed out at a time, so when a worker dies (killed, out of
    memory, a crash in native code) the jobs it may have held are known: they are tried
    once more in a fresh pool, and a job whose worker dies twice is a failed outcome."""
    queue = largest_first(jobs)
    lost: dict[int, int] = {}
    while queue:
        with _pool(workers, lexicon) as pool:
            running: dict[Any, int] = {}
            broken = False
            while (queue and not broken) or running:
                while queue and len(running) < workers and not broken:
                    i = queue.pop(0)
                    running[pool.submit(run_job, jobs[i], fps, mode, lexicon, motion)] = i
                finished, _ = wait(running, return_when=FIRST_COMPLETED)
                for f in finished:
                    i = running.pop(f)
                    try:
                        yield i, f.result()
                    except BrokenProcessPool:
                        broken = True
                        lost[i] = lost.get(i, 0) + 1
                        if lost[i] < 2:
                            queue.insert(0, i)
                        else:
                            msg = f"{jobs[i].score}: its worker process died twice (killed?)"
                            yield i, Outcome(jobs[i], error=msg)


def _outcomes(
    jobs: Sequence[Job],
    fps: float,
    mode: str,
    workers: int,
    lexicon: tuple[str, ...],
    client: Any | None,
    motion: Mapping | None = None,
) -> Iterator[tuple[int, Outcome]]:
    if client is not None:
        from azee_mj.cluster import as_completed_on

        calls = [
            (run_job, (jobs[i], fps, mode, lexicon, motion), f"realize-{i}")
            for i in range(len(jobs))
        ]
        priority = {i: -k for k, i in enumerate(largest_first(jobs))}
        for i, result in as_completed_on(
            client, calls, priority=[priority[i] for i in range(len(jobs))]
        ):
            if isinstance(result, BaseException):
                what = f"{type(result).__name__}: {result}"
                yield i, Outcome(jobs[i], error=f"{jobs[i].score}: its worker failed ({what})")
            else:
                yield i, result
    elif workers == 1:
        for i, job in enumerate(jobs):
            yield i, run_job(job, fps, mode, lexicon, motion)
    else:
        yield from _pool_outcomes(jobs, fps, mode, workers, lexicon, motion)


def realize_many(
    jobs: Sequence[Job],
    *,
    fps: float = 50.0,
    mode: str = "multitrack",
    workers: int | None = None,
    lexicon: Iterable[str | os.PathLike] = (),
    on_done: Callable[[Outcome, int], None] | None = None,
    client: Any | None = None,
    motion: Mapping | None = None,
) -> list[Outcome]:
    """Realize every job (``motion``: see :func:`realize_file`); ``.azee`` scores are compiled with the sign directories
    ``lexicon``. ``on_done(outcome, finished)`` is called in this process as each job ends,
    in completion order; the outcomes are returned in job order. The output directories
    must exist (the output rule of :mod:`azee_mj.files`).

    Where: on the workers of the Dask ``client`` (a ``distributed.Client``; the files must be
    on a file system its workers share, see ``docs/cluster.md``), else in a pool of
    ``workers`` processes (default :func:`usable_cores`; 1 runs here, without a pool). Pool
    workers start with the ``forkserver`` method where there is one (``spawn`` otherwise),
    so no GL or MuJoCo state is inherited, and each compiles one solver for all its jobs.
    An exception here (Ctrl-C, SIGTERM) cancels the jobs not started and stops the workers
    of the pool, each removing the file it was writing, before it propagates.
    """
    if not jobs:
        return []
    workers = max(1, min(workers or usable_cores(), len(jobs)))
    lex = tuple(map(str, lexicon))
    done: dict[int, Outcome] = {}
    motion = dict(motion) if motion else None
    for i, outcome in _outcomes(jobs, fps, mode, workers, lex, client, motion):
        done[i] = outcome
        if on_done is not None:
            on_done(outcome, len(done))
    # A worker that died (killed, out of memory) while writing left its temporary file;
    # its job ran again elsewhere. Every job has ended: none is being written now.
    remove_temporaries_of(*jobs)
    return [done[i] for i in range(len(jobs))]
