"""Batches of scores (issue 25): the manifest, resuming, the progress bar, failing scores,
workers that never outlive their command, and a real Dask ``LocalCluster``."""

from __future__ import annotations

import json
import os
import pty
import re
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from azee_mj.batch import Job, Outcome, fingerprint, plan, realize_many
from azee_mj.blend import REST_GAP, REST_HOLD
from azee_mj.cli import main
from azee_mj.corpus import FIELDS, Manifest, Progress, read_manifest, remove_temporaries_of
from azee_mj.errors import AzeeError
from azee_mj.lifeline import alive, start_time
from azee_mj.rollout_io import rollout_options

ROOT = Path(__file__).resolve().parent.parent
DATA = Path(__file__).parent / "data"
GOOD = DATA / "good.json"


def _chain(path: Path, sign: str = "armoire", copies: int = 1) -> Path:
    """``copies`` of the bundled example ``sign`` in a row (armoire: about 1.3 s each)."""
    score = json.loads((ROOT / "examples" / f"{sign}.json").read_text())
    d = score["root"]["end"]
    kids = [
        dict(score["root"], name=f"S{i}", start=(d + 0.2) * i, end=(d + 0.2) * i + d)
        for i in range(copies)
    ]
    root = {"name": "C", "kind": "sync", "start": 0, "end": (d + 0.2) * copies, "children": kids}
    path.write_text(json.dumps({"format": "azee-score", "version": 1, "root": root}))
    return path


def _bad(path: Path) -> Path:
    s = json.loads(GOOD.read_text())
    s["root"]["children"][1]["constraints"][0]["site"] = "@T_TPI(s)"
    path.write_text(json.dumps(s))
    return path


def _same(a: Path, b: Path) -> None:
    with np.load(a) as x, np.load(b) as y:
        assert x.files == y.files
        for k in x.files:
            assert np.array_equal(x[k], y[k]), k


def _hidden(d: Path) -> list[str]:
    return sorted(p.name for p in d.iterdir() if p.name.startswith("."))


def _cli(*args: str | Path) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.Popen(
        [sys.executable, "-m", "azee_mj.cli", "realize", *map(str, args)],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )


def _descendants(pid: int) -> dict[int, str | None]:
    """Every process below ``pid``, with its start time."""
    parent = {}
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                stat = (d / "stat").read_text()
            except OSError:
                continue
            parent[int(d.name)] = int(stat[stat.rindex(")") + 2 :].split()[1])
    out, todo = {}, [pid]
    while todo:
        p = todo.pop()
        for c, pp in parent.items():
            if pp == p and c not in out:
                out[c] = start_time(c)
                todo.append(c)
    return out


def _parent(pid: int) -> int | None:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return int(stat[stat.rindex(")") + 2 :].split()[1])


_UNREAD: dict[int, bytes] = {}


def _wait_line(p: subprocess.Popen, timeout: float = 120) -> str:
    """The first line of the next score that ends (skipping the indented lines, a missed
    constraint's or a finding's, under the score before). Reads the pipe itself, keeping
    what follows the line: a line already read must not wait for the next score (a
    buffered ``readline`` may hold it while ``select`` waits for more)."""
    fd = p.stdout.fileno()
    while True:
        rest = _UNREAD.get(p.pid, b"")
        while b"\n" not in rest:
            assert select.select([fd], [], [], timeout)[0], "no score finished in time"
            chunk = os.read(fd, 65536)
            assert chunk, "the command ended before another score did"
            rest += chunk
        line, _, _UNREAD[p.pid] = rest.partition(b"\n")
        if not line.startswith(b" "):
            return line.decode() + "\n"


# ---------------------------------------------------------------------------------------
# Planning, manifest, progress
# ---------------------------------------------------------------------------------------


def test_two_scores_may_not_write_one_file_through_a_symlink(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "a.npz").symlink_to(out / "b.npz")
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    with pytest.raises(AzeeError) as e:
        plan([a, b], out)
    assert str(e.value) == (
        f"{a} and {b} would both write {out / 'b.npz'} (through {out / 'a.npz'} and "
        f"{out / 'b.npz'}); rename one"
    )
    assert [j.output for j in plan([a], out)] == [out / "a.npz"]  # alone, it is written through


@pytest.mark.parametrize("suffix", [".jsonl", ".csv"])
def test_the_manifest_keeps_its_rows_and_ignores_a_line_cut_short(tmp_path, suffix):
    path = tmp_path / f"m{suffix}"
    first = {k: None for k in FIELDS} | {"input": "a.json", "output": "a.npz", "status": "done"}
    with Manifest(path, [first]) as m:
        m.add(first | {"input": 'b,"x".json', "output": "b.npz", "frames": 3})
    rows = read_manifest(path)
    assert [r["input"] for r in rows] == ["a.json", 'b,"x".json']
    assert str(rows[1]["frames"]) == "3"
    with open(path, "a") as f:  # a killed batch may leave half a line
        f.write('{"input": "c.json", "out' if suffix == ".jsonl" else "c.json,c.npz,do")
    assert [r["input"] for r in read_manifest(path)] == ["a.json", 'b,"x".json']
    assert read_manifest(tmp_path / "none.jsonl") == []


def test_the_progress_bar_is_drawn_on_a_terminal_only(tmp_path):
    job = Job(Path("a.json"), Path("a.npz"))
    master, slave = pty.openpty()
    with os.fdopen(slave, "w") as tty:
        bar = Progress(4, skipped=1, stream=tty)
        bar.update(Outcome(job, worker="h:1"))
        bar.update(Outcome(job, error="a.json: bad"))
        text = bar.text()
        bar.close()
    shown = ""
    while select.select([master], [], [], 0.5)[0]:
        try:
            chunk = os.read(master, 10000)
        except OSError:  # the other end is closed: all read
            break
        if not chunk:
            break
        shown += chunk.decode()
    os.close(master)
    assert text.startswith("realize [##################......] 3/4 (1 done before), 1 failed, ")
    assert text.endswith(" left") and " scores/s, " in text
    assert "3/4 (1 done before), 1 failed" in shown
    with open(tmp_path / "log", "w") as log:
        bar = Progress(2, stream=log)
        bar.update(Outcome(job))
        bar.close()
    assert (tmp_path / "log").read_text() == ""


def test_stale_temporaries_of_a_job_are_removed_and_nothing_else(tmp_path):
    job = Job(tmp_path / "a.json", tmp_path / "a.npz", tmp_path / "a.report.json")
    names = [".a.npz.ab12cd_9.npz", ".a.report.json.0123abcd.json", ".a.npz.keep", "a.npz"]
    for n in names:
        (tmp_path / n).write_text("x")
    assert remove_temporaries_of(job) == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == [".a.npz.keep", "a.npz"]


# ---------------------------------------------------------------------------------------
# Failing scores
# ---------------------------------------------------------------------------------------


def test_a_failing_score_never_stops_the_others(tmp_path, capsys):
    src, out = tmp_path / "src", tmp_path / "out"
    src.mkdir()
    out.mkdir()
    bad = _bad(src / "bad.json")
    deep = src / "deep.azee"  # deeper than any parser allows: a clean error or a bug, alone
    deep.write_text(":seq(" * 3000 + ":bien" + ")" * 3000 + "\n")
    (src / "good.json").write_text(GOOD.read_text())
    (src / "five.azee").write_text(":nb-5\n")
    manifest = tmp_path / "m.jsonl"
    argv = [str(src), "-o", str(out), "--fps", "25", "--jobs", "2", "--manifest", str(manifest)]
    assert main(["realize", *argv]) == 1
    captured = capsys.readouterr()
    assert f"azee-mj: error: {bad}: GOOD.K1: constraint 1 (place): unknown site" in captured.err
    assert f"azee-mj: error: {deep}:" in captured.err
    assert captured.err.endswith(f"\nazee-mj: failed: {bad}, {deep}\n")
    # the time taken is the machine's (a loaded one may take over a minute): any is right
    assert re.search(r"\nazee-mj: 4 scores: 2 realized, 2 failed in \d+m\d\ds\n", captured.err)
    assert sorted(p.name for p in out.iterdir()) == ["five.npz", "good.npz"]
    rows = {Path(r["input"]).name: r for r in read_manifest(manifest)}
    assert sorted(rows) == ["bad.json", "deep.azee", "five.azee", "good.json"]
    assert rows["bad.json"]["status"] == "failed" and "unknown site" in rows["bad.json"]["error"]
    good = rows["good.json"]
    with np.load(out / "good.npz") as z:  # the lead-in and the return to rest included
        frames = len(z["time"])
    assert good["status"] == "done" and good["frames"] == frames and good["fps"] == 25.0
    assert good["constraints"] == good["constraints_met"] == 3 and good["findings"] == 0
    assert good["duration_s"] == pytest.approx(1.2) and good["worker"].count(":") == 1
    assert good["wall_s"] > 0 and good["output"] == str(out / "good.npz")


# ---------------------------------------------------------------------------------------
# Stopping, resuming, killing
# ---------------------------------------------------------------------------------------


def test_sigterm_then_resume_finishes_with_no_score_done_twice(tmp_path, capsys):
    src, out = tmp_path / "src", tmp_path / "out"
    src.mkdir()
    out.mkdir()
    for k in range(6):
        _chain(src / f"s{k}.json", "armoire" if k else "nicht-sondern", copies=2 + k % 3)
    manifest = tmp_path / "m.jsonl"
    p = _cli(src, "-o", out, "--jobs", "2", "--manifest", manifest)
    try:
        _wait_line(p)
        _wait_line(p)
        p.send_signal(signal.SIGTERM)
        _, err = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
    assert p.returncode == 143, err
    assert _hidden(out) == []
    first = {f.name: f.stat().st_mtime_ns for f in out.iterdir()}
    assert 2 <= len(first) < 6
    rows = read_manifest(manifest)
    assert {Path(r["output"]).name for r in rows} <= set(first)
    # What a SIGKILL would leave: a temporary file; and a damaged output counts as not done.
    (out / ".s5.npz.abcd1234.npz").write_text("partial")
    damaged = min(first)
    (out / damaged).write_bytes(b"PK\x03\x04 not a whole file")
    capsys.readouterr()
    assert (
        main(
            [
                "realize",
                str(src),
                "-o",
                str(out),
                "--jobs",
                "2",
                "--manifest",
                str(manifest),
                "--resume",
            ]
        )
        == 0
    )
    captured = capsys.readouterr()
    heads = [line for line in captured.out.splitlines() if not line.startswith(" ")]
    again = sorted(Path(line.split(":")[0]).name for line in heads)
    assert again == sorted({f"s{k}.npz" for k in range(6)} - set(first) | {damaged})
    assert (
        f"azee-mj: 6 scores: {len(again)} realized, {6 - len(again)} done before (--resume)"
        in captured.err
    )
    for name, mtime in first.items():
        if name != damaged:
            assert (out / name).stat().st_mtime_ns == mtime, f"{name} was written twice"
    assert _hidden(out) == []
    final = read_manifest(manifest)
    assert sorted(Path(r["output"]).name for r in final) == [f"s{k}.npz" for k in range(6)]
    assert all(r["status"] == "done" for r in final)
    alone = tmp_path / "alone.npz"
    assert main(["realize", str(src / "s1.json"), "-o", str(alone)]) == 0
    _same(alone, out / "s1.npz")


def test_resume_realizes_again_what_other_options_made(tmp_path, capsys):
    src, out, signs = tmp_path / "src", tmp_path / "out", tmp_path / "signs"
    for d in (src, out, signs):
        d.mkdir()
    (src / "good.json").write_text(GOOD.read_text())
    (src / "five.azee").write_text(":nb-5\n")
    manifest = tmp_path / "m.csv"
    # one score alone, as a batch would realize it: its options are the batch's
    assert main(["realize", str(GOOD), "-o", str(out / "good.npz"), "--fps", "25"]) == 0
    base = ["realize", str(src), "-o", str(out), "--fps", "25", "--jobs", "1"]
    base += ["--manifest", str(manifest), "--resume"]

    def run(*extra: str) -> set[str]:
        """The outputs a resumed batch with ``extra`` options realized again."""
        capsys.readouterr()
        assert main([*base, *extra]) == 0
        heads = [x for x in capsys.readouterr().out.splitlines() if not x.startswith(" ")]
        return {Path(x.split(":")[0]).name for x in heads}

    assert run() == {"five.npz"}
    assert run() == set()
    plain = fingerprint(25.0)
    assert rollout_options(out / "good.npz") == rollout_options(out / "five.npz") == plain
    assert {r["options"] for r in read_manifest(manifest)} == {plain}
    options = (["--tempo", "2"], ["--no-rest"], ["--rest-hold", "1.5"], ["--rest-gap", "3"])
    for extra in (*options, ["--mode", "flattened"]):
        assert run(*extra) == {"good.npz", "five.npz"}, extra
        assert run(*extra) == set(), extra
    now = fingerprint(25.0, "flattened")
    assert {r["options"] for r in read_manifest(manifest)} == {now}
    assert now == f"fps=25.0;mode=flattened;rest=1;hold={REST_HOLD!r};tempo=1.0;gap={REST_GAP!r}"
    # sign directories count for an expression only, which is compiled with them
    lexicon = ["--mode", "flattened", "--lexicon", str(signs)]
    assert run(*lexicon) == {"five.npz"}
    assert rollout_options(out / "five.npz") == fingerprint(25.0, "flattened", lexicon=[signs])
    assert run(*lexicon) == set()
    # a rollout that records no options (written before they were recorded) is made again
    with np.load(out / "good.npz") as z:
        np.savez(out / "good.npz", **{k: z[k] for k in z.files if k != "options"})
    assert rollout_options(out / "good.npz") is None
    assert run(*lexicon) == {"good.npz"}
    assert fingerprint(25.0, dynamics=True) != plain
    assert fingerprint(25.0, blinks=(3, 17.0)) != fingerprint(25.0, blinks=(4, 17.0))


@pytest.mark.parametrize(
    "sig, cluster",
    [(signal.SIGKILL, False), (signal.SIGHUP, False), (signal.SIGKILL, True)],
    ids=["pool-SIGKILL", "pool-SIGHUP", "dask-SIGKILL"],
)
def test_workers_never_outlive_their_command(tmp_path, sig, cluster):
    if cluster:
        pytest.importorskip("distributed", reason="the cluster extra (dask) is not installed")
    src, out = tmp_path / "src", tmp_path / "out"
    src.mkdir()
    out.mkdir()
    _chain(src / "long.json", copies=200)  # minutes for one worker
    (src / "good.json").write_text(GOOD.read_text())
    p = _cli(src, "-o", out, "--jobs", "2", *(["--scheduler", "local"] if cluster else []))
    workers: dict[int, str | None] = {}
    try:
        assert _wait_line(p).startswith(f"{out / 'good.npz'}: ")
        workers = _descendants(p.pid)
        assert len(workers) >= 2
        p.send_signal(sig)
        p.wait(timeout=30)
        deadline = time.monotonic() + 15
        while time.monotonic() < deadline and any(alive(w, s) for w, s in workers.items()):
            time.sleep(0.2)
        left = [w for w, s in workers.items() if alive(w, s)]
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
        for w, s in {**workers, **_descendants(p.pid)}.items():
            if alive(w, s):  # a failed test leaves no worker running
                os.kill(w, signal.SIGKILL)
    assert left == [], f"workers still running after {sig!r}: {left}"
    assert sorted(x.name for x in out.iterdir()) == ["good.npz"]


def test_a_worker_that_dies_costs_no_score(tmp_path):
    src, out = tmp_path / "src", tmp_path / "out"
    src.mkdir()
    out.mkdir()
    for k in range(4):
        _chain(src / f"s{k}.json", copies=3)
    manifest = tmp_path / "m.csv"
    # What a worker killed while writing leaves (whether the kill below lands in a write is
    # chance): the batch removes it once every job has ended.
    (out / ".s2.npz.abcd1234.npz").write_text("partial")
    p = _cli(src, "-o", out, "--jobs", "2", "--manifest", manifest)
    try:
        _wait_line(p)
        # The pool's workers are the fork server's children (the server is the command's).
        workers = [w for w in _descendants(p.pid) if _parent(w) not in (p.pid, None)]
        assert workers
        os.kill(workers[0], signal.SIGKILL)
        _stdout, err = p.communicate(timeout=300)
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
    assert p.returncode == 0, err
    assert sorted(x.name for x in out.iterdir()) == [f"s{k}.npz" for k in range(4)]
    assert sorted(Path(r["output"]).name for r in read_manifest(manifest)) == [
        f"s{k}.npz" for k in range(4)
    ]


# ---------------------------------------------------------------------------------------
# Dask
# ---------------------------------------------------------------------------------------


def test_a_local_dask_cluster_of_two_workers_writes_what_one_process_writes(tmp_path):
    distributed = pytest.importorskip("distributed", reason="the cluster extra is not installed")
    scores = [GOOD, DATA / "kinds.json", ROOT / "examples" / "bien.json"]
    one, dask = tmp_path / "one", tmp_path / "dask"
    one.mkdir()
    dask.mkdir()
    alone = realize_many(plan(scores, one), fps=25, workers=1)
    with (
        distributed.LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
        ) as cluster,
        distributed.Client(cluster) as client,
    ):
        seen = []
        outcomes = realize_many(
            plan(scores, dask), fps=25, client=client, on_done=lambda o, n: seen.append(n)
        )
        pids = set(client.run(os.getpid).values())
    assert seen == [1, 2, 3]
    assert all(o.ok for o in outcomes), [o.error for o in outcomes]
    assert {int(o.worker.split(":")[1]) for o in outcomes} <= pids
    for a, b in zip(alone, outcomes, strict=True):
        assert (a.frames, a.constraints, a.missed, a.findings) == (
            b.frames,
            b.constraints,
            b.missed,
            b.findings,
        )
        _same(a.job.output, b.job.output)


def test_the_command_runs_on_a_dask_cluster_here_or_at_an_address(tmp_path, capsys):
    distributed = pytest.importorskip("distributed", reason="the cluster extra is not installed")
    bad = _bad(tmp_path / "bad.json")
    single = tmp_path / "good.npz"
    assert main(["realize", str(GOOD), "-o", str(single), "--fps", "25"]) == 0
    scheduler_file = tmp_path / "scheduler.json"
    with distributed.LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        dashboard_address=None,
        scheduler_kwargs={"scheduler_file": str(scheduler_file)},
    ) as cluster:
        for k, where in enumerate(["local", cluster.scheduler_address, str(scheduler_file)]):
            out = tmp_path / f"out{k}"
            out.mkdir()
            argv = [GOOD, DATA / "kinds.json", bad, "-o", out, "--fps", "25", "--jobs", "2"]
            assert main(["realize", *map(str, argv), "--scheduler", where]) == 1
            captured = capsys.readouterr()
            assert captured.err.endswith(f"azee-mj: failed: {bad}\n"), where
            assert sorted(p.name for p in out.iterdir()) == ["good.npz", "kinds.npz"]
            _same(single, out / "good.npz")
        assert len(cluster.scheduler_info["workers"]) == 2  # left running


def test_scheduler_mistakes_are_one_clear_line(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    assert main(["realize", str(GOOD), "-o", str(tmp_path / "x.npz"), "--resume"]) == 2
    assert capsys.readouterr().err == (
        "azee-mj: error: --resume, --manifest and --scheduler are for several scores (-o DIR/)\n"
    )
    try:
        import distributed  # noqa: F401
    except ImportError:
        assert main(["realize", str(GOOD), "-o", f"{out}/", "--scheduler", "local"]) == 2
        assert capsys.readouterr().err == (
            "azee-mj: error: --scheduler needs Dask: install the cluster extra "
            "(pip install 'azee_mj[cluster]')\n"
        )
        return
    missing = tmp_path / "nope.json"
    assert main(["realize", str(GOOD), "-o", f"{out}/", "--scheduler", str(missing)]) == 2
    assert (
        capsys.readouterr().err
        == f"azee-mj: error: --scheduler {missing}: no such scheduler file\n"
    )
    assert main(["realize", str(GOOD), "-o", f"{out}/", "--scheduler", "nonsense://x"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(
        "azee-mj: error: --scheduler nonsense://x: cannot reach a Dask scheduler ("
    )
    assert list(out.iterdir()) == []


def test_the_manifest_counts_the_findings_check_says(tmp_path, capsys):
    # armoire's hands come down over the human wrist speed: check --score says two findings
    # (and exits 1, as realize --strict); the manifest's count used to leave speeds out.
    score = Path(__file__).resolve().parent.parent / "examples" / "armoire.json"
    src, out, manifest = tmp_path / "src", tmp_path / "out", tmp_path / "m.jsonl"
    src.mkdir()
    out.mkdir()
    (src / "armoire.json").write_text(score.read_text())
    assert main(["realize", str(src), "-o", str(out), "--manifest", str(manifest)]) == 0
    capsys.readouterr()
    assert main(["check", str(out / "armoire.npz"), "--score", str(score)]) == 1
    said = capsys.readouterr().out.splitlines()
    found = [line for line in said if line.startswith("  finding: ")]
    assert "clean: no penetration over the limit, every joint inside its range" in said
    assert len(found) == 2 and all("m/s (limit 3.00)" in line for line in found)
    assert [r["findings"] for r in read_manifest(manifest)] == [2]
