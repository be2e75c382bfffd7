"""Realizing many scores at once: one worker process per core, one solver per worker.

Each score is realized exactly as it would be alone (the solver keeps no state between
scores) and its rollout written atomically, so an output is whole or absent. A bad score
costs only its own output: its one-line message names the file, the others still complete.
Units: frames per second.
"""

from __future__ import annotations

import multiprocessing
import os
import time
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from azee_mj.errors import AzeeError

if TYPE_CHECKING:
    from azee_mj.ik import Solver
    from azee_mj.timeline import Rollout


@dataclass(frozen=True)
class Job:
    """One score to realize: ``score`` -> rollout ``output`` (and optional ``report`` JSON)."""

    score: Path
    output: Path
    report: Path | None = None


@dataclass(frozen=True)
class Outcome:
    """What became of a :class:`Job`: ``lines`` to print on success, else ``error``;
    ``wall`` and ``cpu`` are the seconds it took in its worker (elapsed, and CPU time)."""

    job: Job
    lines: tuple[str, ...] = ()
    error: str = ""
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
    """The score paths of ``inputs``: files as given, directories as their ``*.json`` files
    (sorted, not recursive). Raises :class:`AzeeError` for a directory without scores."""
    out: list[Path] = []
    for p in map(Path, inputs):
        if p.is_dir():
            found = sorted(f for f in p.glob("*.json") if f.is_file())
            if not found:
                raise AzeeError(f"{p}: no *.json scores in this directory")
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


def summary_lines(output: str | os.PathLike, rollout: Rollout, fps: float) -> tuple[str, ...]:
    """What ``azee-mj realize`` prints for a rollout written to ``output``."""
    s = rollout.stats
    bad = [t for t in rollout.traces if not t.ok]
    head = (f"{output}: {len(rollout.time)} frames at {fps:g} fps, {s.problems} IK "
            f"problems ({s.iterations} iterations) in {s.total_time:.3f} s; "
            f"{len(rollout.traces) - len(bad)}/{len(rollout.traces)} constraints within "
            f"tolerance")  # fmt: skip
    return (head, *(f"  {t.describe()}" for t in bad[:5]))


def realize_file(
    job: Job, *, fps: float, mode: str, solver: Solver | None = None,
    progress: Callable[[float], None] | None = None,
) -> tuple[str, ...]:  # fmt: skip
    """Realize ``job.score`` and write its rollout (and report) atomically; the summary
    lines. Raises :class:`AzeeError` for a bad score."""
    from azee_mj.files import save_json
    from azee_mj.rollout_io import save_rollout
    from azee_mj.score import load_score
    from azee_mj.timeline import realize

    rollout = realize(load_score(job.score), fps=fps, mode=mode, solver=solver,
                      progress=progress)  # fmt: skip
    save_rollout(job.output, rollout)
    if job.report is not None:
        save_json(job.report, rollout.report())
    return summary_lines(job.output, rollout, fps)


_SOLVER: Solver | None = None
_PRELOAD = ("azee_mj.batch", "azee_mj.files", "azee_mj.rollout_io", "azee_mj.schedule",
            "azee_mj.score", "azee_mj.timeline")  # fmt: skip


def _init_worker() -> None:
    global _SOLVER
    from azee_mj.schedule import make_solver

    _SOLVER = make_solver()


def _run(job: Job, fps: float, mode: str) -> Outcome:
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        lines, error = realize_file(job, fps=fps, mode=mode, solver=_SOLVER), ""
    except AzeeError as e:
        msg, lines = str(e), ()
        error = msg if msg.startswith(str(job.score)) else f"{job.score}: {msg}"
    return Outcome(job, lines, error, time.perf_counter() - t0, time.process_time() - c0)


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
    on_done: Callable[[Outcome, int], None] | None = None,
) -> list[Outcome]:
    """Realize every job, ``workers`` processes at once (default :func:`usable_cores`;
    1 runs here, without a pool). ``on_done(outcome, finished)`` is called in this process
    as each job ends, in completion order; the outcomes are returned in job order.

    Workers start with the ``forkserver`` method where there is one (``spawn`` otherwise),
    so no GL or MuJoCo state is inherited, and each compiles one solver for all its jobs.
    """
    workers = max(1, min(workers or usable_cores(), len(jobs)))
    done: dict[int, Outcome] = {}

    def finish(i: int, o: Outcome) -> None:
        done[i] = o
        if on_done is not None:
            on_done(o, len(done))

    if workers == 1:
        _init_worker()
        for i, job in enumerate(jobs):
            finish(i, _run(job, fps, mode))
        return [done[i] for i in range(len(jobs))]
    if "forkserver" in multiprocessing.get_all_start_methods():
        ctx = multiprocessing.get_context("forkserver")
        # Import once in the server (if not started yet), not in every worker.
        ctx.set_forkserver_preload(list(_PRELOAD))
    else:
        ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(workers, mp_context=ctx, initializer=_init_worker) as pool:
        # Largest scores first, so that no long one starts last while the other workers idle.
        order = sorted(range(len(jobs)), key=lambda i: -_size(jobs[i].score))
        pending = {pool.submit(_run, jobs[i], fps, mode): i for i in order}
        while pending:
            finished, _ = wait(pending, return_when=FIRST_COMPLETED)
            for f in finished:
                finish(pending.pop(f), f.result())
    return [done[i] for i in range(len(jobs))]
