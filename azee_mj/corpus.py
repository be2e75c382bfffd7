"""A corpus of scores: what running thousands of them needs around
:func:`~azee_mj.batch.realize_many`.

* A manifest, one row per score (:data:`FIELDS`), as JSON Lines (``.jsonl``) or CSV
  (``.csv``), a row appended as each score ends, so a stopped batch's manifest says what it
  finished.
* Resuming (:func:`resume`): a score whose output (and report) exist, are not older than
  the score file, validate and were realized with the same options (the fingerprint of
  :func:`~azee_mj.batch.fingerprint` the file records) is done and is not realized again;
  the temporary files a killed batch left beside its outputs are removed.
* A progress bar on a terminal (:class:`Progress`: scores done, failed, rate, time left),
  nothing on a file or pipe; and the one-line summary at the end (:func:`summary`).

Units: seconds.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import os
import sys
import time
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any, Self

from azee_mj.batch import (
    Job,
    Outcome,
    job_fingerprint,
    read_score,
    realize_many,
    remove_temporaries_of,
)
from azee_mj.errors import AzeeError, InputFileError, printable, shorten
from azee_mj.files import atomic_path

#: The columns of a manifest.
FIELDS = (
    "input",
    "output",
    "status",
    "error",
    "duration_s",
    "frames",
    "fps",
    "constraints",
    "constraints_met",
    "findings",
    "wall_s",
    "cpu_s",
    "worker",
    "options",
)
#: A row's ``status``: realized now or in an earlier run, or failed (``error`` says why).
DONE, FAILED = "done", "failed"


def row(outcome: Outcome, fps: float, options: str = "") -> dict:
    """The manifest row of an outcome (numbers ``None`` for a failed score); ``options``:
    the fingerprint of the options it was realized with."""
    j, ok = outcome.job, outcome.ok
    return {
        "input": str(j.score),
        "output": str(j.output),
        "status": DONE if ok else FAILED,
        "error": outcome.error,
        "duration_s": outcome.duration if ok else None,
        "frames": outcome.frames if ok else None,
        "fps": fps,
        "constraints": outcome.constraints if ok else None,
        "constraints_met": outcome.constraints - outcome.missed if ok else None,
        "findings": outcome.findings if ok else None,
        "wall_s": round(outcome.wall, 4),
        "cpu_s": round(outcome.cpu, 4),
        "worker": outcome.worker,
        "options": options,
    }


#: What a spreadsheet reads as a formula at the start of a cell (and ``'``, the mark that
#: says it is text, so that a cell which starts with it reads back unchanged).
_FORMULA = ("=", "+", "-", "@", "'")


def csv_cell(value) -> object:
    """A manifest value as a CSV cell: ``""`` for none; a text with its control characters
    and terminal escapes written as ``\\xNN`` (:func:`~azee_mj.errors.printable`) and, when
    it starts as a formula would (``= + - @``), after a ``'`` that makes a spreadsheet
    show it as text (:func:`read_cell` takes it off)."""
    if value is None:
        return ""
    if not isinstance(value, str):
        return value
    value = printable(value)
    return "'" + value if value.startswith(_FORMULA) else value


def read_cell(text: str) -> str:
    """A CSV manifest cell as written by :func:`csv_cell`, without its ``'`` mark."""
    return text[1:] if text.startswith("'") and text[1:].startswith(_FORMULA) else text


def json_controls(text: str) -> str:
    """JSON text with every character that could drive a terminal (those
    :func:`~azee_mj.errors.printable` escapes) written as a ``\\uNNNN`` escape: the same
    JSON value, and ``cat`` shows it raw without harm."""
    return "".join(f"\\u{ord(c):04x}" if printable(c) != c else c for c in text)


class Manifest:
    """A manifest file: the ``rows`` given written at once (atomically), then one row
    appended (and flushed) per :meth:`add`. JSON Lines, or CSV for a ``.csv`` path."""

    def __init__(self, path: str | os.PathLike, rows: Iterable[dict] = (), inputs=()):
        self.path = Path(path)
        self.csv = self.path.suffix.lower() == ".csv"
        with atomic_path(self.path, inputs=inputs) as tmp:
            tmp.write_text("".join(self._text(r, header=k == 0) for k, r in enumerate(rows)))
            if self.csv and tmp.stat().st_size == 0:
                tmp.write_text(self._text(None, header=True))
        self._file: IO[str] | None = open(self.path, "a", encoding="utf-8", newline="")  # noqa: SIM115

    def _text(self, r: dict | None, header: bool) -> str:
        if not self.csv:
            text = json.dumps({k: r.get(k) for k in FIELDS}, ensure_ascii=False)
            return json_controls(text) + "\n"
        buf = io.StringIO()
        w = csv.DictWriter(buf, FIELDS, lineterminator="\n")
        if header:
            w.writeheader()
        if r is not None:
            w.writerow({k: csv_cell(r.get(k)) for k in FIELDS})
        return buf.getvalue()

    def add(self, r: dict) -> None:
        assert self._file is not None
        self._file.write(self._text(r, header=False))
        self._file.flush()

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def read_manifest(path: str | os.PathLike) -> list[dict]:
    """The rows of a manifest (JSON Lines or CSV); none if it does not exist. A line cut
    short by a killed batch (the last one), and a line that is not a row (not a JSON object
    of numbers, texts and nulls), are left out; CSV values are read as text."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        return []
    except (OSError, UnicodeDecodeError) as e:
        raise InputFileError(f"{shorten(str(p), 200)}: cannot read the manifest ({e})") from None
    text = text[: text.rfind("\n") + 1]  # whole lines only
    if p.suffix.lower() == ".csv":
        try:
            rows = list(csv.DictReader(io.StringIO(text)))
        except csv.Error as e:  # e.g. a field over the csv module's size limit
            raise InputFileError(
                f"{shorten(str(p), 200)}: cannot read the manifest ({e})"
            ) from None
        rows = [r for r in rows if None not in r and None not in r.values()]
        return [{k: read_cell(v) for k, v in r.items()} for r in rows]
    out = []
    for line in text.splitlines():
        try:
            r = json.loads(line)
        except (ValueError, RecursionError):  # not a row (a line of 100,000 brackets)
            continue
        # a row's values are JSON scalars: a list or an object is not a row ("output": [])
        if isinstance(r, dict) and all(
            v is None or isinstance(v, str | int | float) for v in r.values()
        ):
            out.append(r)
    return out


def _fresh(output: Path, score: Path) -> bool:
    try:
        return output.stat().st_mtime >= score.stat().st_mtime
    except OSError:
        return False


def done_row(
    job: Job,
    nq: int,
    fps: float,
    lexicon=(),
    earlier: dict | None = None,
    options: str | None = None,
) -> dict | None:
    """The manifest row of a job finished by an earlier run, ``None`` if it must be
    realized: its output (and report) must exist, be no older than the score, validate, at
    ``fps``, and record the options fingerprint ``options`` (None: not compared). The
    earlier run's row is kept when there is one."""
    from azee_mj.rollout_io import load_rollout, rollout_options

    if not _fresh(job.output, job.score):
        return None
    try:
        rollout = load_rollout(job.output, nq)
        if job.report is not None:
            if not _fresh(job.report, job.score):
                return None
            json.loads(job.report.read_text(encoding="utf-8"))
    except (AzeeError, OSError, ValueError):
        return None
    if abs(rollout.fps - fps) > 1e-9 * fps:
        return None
    if options is not None and rollout_options(job.output) != options:
        return None
    mine = {"input": str(job.score), "output": str(job.output), "options": options or ""}
    if earlier is not None and earlier.get("status") == DONE:
        return {**earlier, **mine}
    try:
        duration: float | None = read_score(job.score, lexicon).duration
    except AzeeError:
        duration = None
    met = sum(t.ok for t in rollout.traces)
    return {
        "input": str(job.score),
        "output": str(job.output),
        "status": DONE,
        "error": "",
        "duration_s": duration,
        "frames": len(rollout.time),
        "fps": fps,
        "constraints": len(rollout.traces),
        "constraints_met": met,
        "findings": None,
        "wall_s": None,
        "cpu_s": None,
        "worker": None,
        "options": options or "",
    }


def resume(
    jobs: Sequence[Job],
    nq: int,
    fps: float,
    lexicon=(),
    manifest: Sequence[dict] = (),
    mode: str = "multitrack",
    motion: Mapping | None = None,
) -> tuple[list[Job], list[dict]]:
    """Split ``jobs`` into those still to realize and the manifest rows of those done by
    an earlier run with the same options (``fps``, ``mode``, ``motion``, the ``lexicon``
    of an ``.azee`` score; see :func:`done_row`; ``manifest`` holds that run's rows);
    first removes the temporary files a killed run left for every job."""
    earlier = {r.get("output"): r for r in manifest}
    todo, kept = [], []
    remove_temporaries_of(*jobs)
    for job in jobs:
        options = job_fingerprint(job, fps, mode, motion, tuple(map(str, lexicon)))
        r = done_row(job, nq, fps, lexicon, earlier.get(str(job.output)), options)
        if r is None:
            todo.append(job)
        else:
            kept.append(r)
    return todo, kept


def _clock(seconds: float) -> str:
    s = round(seconds)
    return f"{s // 3600}h{s // 60 % 60:02d}m" if s >= 3600 else f"{s // 60}m{s % 60:02d}s"


@dataclass
class Progress:
    """A progress bar of a batch on ``stream`` when it is a terminal, nothing otherwise:
    scores done (of ``total``, ``skipped`` done before), failed, rate and time left."""

    total: int
    skipped: int = 0
    stream: IO[str] | None = None

    def __post_init__(self) -> None:
        self.stream = self.stream or sys.stderr
        self.on = bool(getattr(self.stream, "isatty", lambda: False)())
        self.done = self.failed = 0
        self.t0 = time.perf_counter()
        self._shown = 0.0
        self.draw(force=True)

    def text(self, width: int = 24) -> str:
        """The bar's line (without the carriage return)."""
        finished = self.skipped + self.done + self.failed
        n = int(width * finished / self.total) if self.total else width
        elapsed = time.perf_counter() - self.t0
        ran = self.done + self.failed
        rate = ran / elapsed if elapsed > 0 and ran else 0.0
        left = (
            f", {_clock((self.total - finished) / rate)} left"
            if rate and finished < self.total
            else ""
        )
        skipped = f" ({self.skipped} done before)" if self.skipped else ""
        return (
            f"realize [{'#' * n}{'.' * (width - n)}] {finished}/{self.total}{skipped}, "
            f"{self.failed} failed, {rate:.2f} scores/s{left}"
        )

    def clear(self) -> None:
        """Erase the bar (before printing another line)."""
        if self.on:
            self.stream.write("\r\x1b[K")

    def draw(self, force: bool = False) -> None:
        now = time.perf_counter()
        if self.on and (force or now - self._shown > 0.1):
            self.stream.write("\r\x1b[K" + self.text())
            self.stream.flush()
            self._shown = now

    def update(self, outcome: Outcome) -> None:
        if outcome.ok:
            self.done += 1
        else:
            self.failed += 1
        self.draw(force=True)  # (the line printed before it cleared the bar)

    def close(self) -> None:
        """Draw the last state and end the line."""
        if self.on:
            self.draw(force=True)
            self.stream.write("\n")
            self.stream.flush()


def summary(outcomes: Sequence[Outcome], skipped: int, seconds: float) -> list[str]:
    """The lines ending a batch: how many scores were realized, skipped and failed, in how
    long, then the failed files (the first ten)."""
    failed = [o for o in outcomes if not o.ok]
    n = len(outcomes) + skipped
    head = f"{n} score{'s' if n != 1 else ''}: {len(outcomes) - len(failed)} realized"
    if skipped:
        head += f", {skipped} done before (--resume)"
    head += f", {len(failed)} failed in {_clock(seconds)}"
    lines = [head]
    if failed:
        names = ", ".join(printable(shorten(str(o.job.score), 200)) for o in failed[:10])
        more = f" and {len(failed) - 10} more" if len(failed) > 10 else ""
        lines.append(f"failed: {names}{more}")
    return lines


def realize_corpus(
    jobs: Sequence[Job],
    *,
    nq: int,
    fps: float = 50.0,
    mode: str = "multitrack",
    workers: int | None = None,
    lexicon: Sequence[str | os.PathLike] = (),
    client: Any | None = None,
    manifest: str | os.PathLike | None = None,
    resume_run: bool = False,
    out: IO[str] | None = None,
    err: IO[str] | None = None,
    motion: Mapping | None = None,
) -> tuple[list[Outcome], list[dict]]:
    """Realize ``jobs`` as ``azee-mj realize SCORES... -o DIR/`` does: with ``resume_run``
    the jobs an earlier run finished are skipped (:func:`resume`; ``nq`` is the signer's
    number of joint coordinates, to validate their rollouts); each score's lines go to
    ``out`` as it ends (its error to ``err``), its row to the ``manifest`` file, the
    progress bar and the summary to ``err`` (default: standard output and error);
    ``motion``: the realizer's options (see :func:`~azee_mj.batch.realize_file`). The
    outcomes of the jobs realized now, and the
    manifest rows of those skipped. Stopped by an exception (Ctrl-C, SIGTERM), it removes
    the temporary files of the jobs not finished before it propagates."""
    out, err = out or sys.stdout, err or sys.stderr
    earlier = read_manifest(manifest) if manifest is not None and resume_run else []
    lex = tuple(map(str, lexicon))
    todo, kept = (
        resume(jobs, nq, fps, lex, earlier, mode, motion) if resume_run else (list(jobs), [])
    )
    bar = Progress(len(jobs), len(kept), err)
    t0 = time.perf_counter()
    with contextlib.ExitStack() as stack:
        sheet = None
        if manifest is not None:
            inputs = [j.score for j in jobs]
            sheet = stack.enter_context(Manifest(manifest, kept, inputs=inputs))

        def done(o: Outcome, n: int) -> None:
            bar.clear()
            if o.ok:
                print("\n".join(map(printable, o.lines)), file=out, flush=True)
            else:
                print(f"azee-mj: error: {printable(o.error)}", file=err, flush=True)
            if sheet is not None:
                sheet.add(row(o, fps, job_fingerprint(o.job, fps, mode, motion, lex)))
            bar.update(o)

        try:
            outcomes = realize_many(
                todo,
                fps=fps,
                mode=mode,
                workers=workers,
                lexicon=lexicon,
                on_done=done,
                client=client,
                motion=motion,
            )
        except BaseException:
            remove_temporaries_of(*todo)
            raise
        finally:
            bar.close()
    for line in summary(outcomes, len(kept), time.perf_counter() - t0):
        print(f"azee-mj: {line}", file=err)
    return outcomes, kept
