"""Hostile input, unsafe output paths, hidden nondeterminism (issue 14): every failure is one
clean message, every run repeatable."""

from __future__ import annotations

import dataclasses
import json
import os
import select
import signal
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from azee_mj.cli import main
from azee_mj.errors import AzeeError, OutputError, ScoreError, tidy
from azee_mj.files import Terminated, atomic_path, check_output, install_signal_handlers
from azee_mj.model import load_model
from azee_mj.rollout_io import load_rollout, rollout_arrays, save_rollout
from azee_mj.score import load_score
from azee_mj.timeline import realize
from azee_mj.timing import MAX_FRAMES, check_fps, exact_time, frame_count, frame_range

ROOT = Path(__file__).resolve().parent.parent
DATA = Path(__file__).parent / "data"
GOOD = DATA / "good.json"
ERR = "azee-mj: error: "


def _run(capsys, *argv) -> tuple[int, str]:
    code = main([str(a) for a in argv])
    return code, capsys.readouterr().err


def _score(**root) -> dict:
    return {
        "format": "azee-score",
        "version": 1,
        "root": {
            "name": "R",
            "kind": "cstr",
            "start": 0,
            "end": 1,
            "constraints": [{"type": "morph", "id": "fist", "weight": 1.0, "side": "s"}],
        }
        | root,
    }


# ---------------------------------------------------------------------------------------
# Output paths
# ---------------------------------------------------------------------------------------


def test_a_fifo_output_is_refused_and_left_alone(tmp_path, capsys):
    fifo = tmp_path / "pipe.npz"
    os.mkfifo(fifo)
    code, err = _run(capsys, "realize", GOOD, "-o", fifo)
    assert code == 2
    assert err == (
        f"{ERR}{fifo}: exists and is not a regular file (a device, fifo or socket); "
        "refusing to replace it\n"
    )
    assert fifo.is_fifo()


def test_a_device_output_is_refused():
    with pytest.raises(OutputError) as e:
        check_output("/dev/null")
    assert str(e.value) == (
        "/dev/null: exists and is not a regular file (a device, fifo or "
        "socket); refusing to replace it"
    )


def test_a_directory_output_is_refused(tmp_path, capsys):
    code, err = _run(capsys, "realize", GOOD, "-o", tmp_path)
    assert (code, err) == (2, f"{ERR}{tmp_path}: is a directory; give a file name\n")


def test_the_input_is_never_an_output(tmp_path, capsys):
    score = tmp_path / "s.json"
    score.write_text(GOOD.read_text())
    code, err = _run(capsys, "realize", score, "-o", score)
    assert (code, err) == (2, f"{ERR}{score}: is also an input ({score}); write to another file\n")
    link = tmp_path / "link.npz"
    link.symlink_to(score)
    code, err = _run(capsys, "realize", score, "-o", tmp_path / "o.npz", "--report", link)
    assert (code, err) == (2, f"{ERR}{link}: is also an input ({score}); write to another file\n")
    assert score.read_text() == GOOD.read_text()
    assert not (tmp_path / "o.npz").exists()


def test_a_symlink_is_written_through(tmp_path, capsys):
    real = tmp_path / "real.npz"
    real.write_bytes(b"old")
    link = tmp_path / "link.npz"
    link.symlink_to(real)
    assert main(["realize", str(GOOD), "-o", str(link), "--fps", "10"]) == 0
    assert link.is_symlink() and os.readlink(link) == str(real)
    assert load_rollout(real, load_model().nq).fps == 10.0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.npz", "real.npz"]


def test_a_file_as_parent_directory_or_a_missing_directory(tmp_path, capsys):
    f = tmp_path / "file"
    f.write_text("x")
    code, err = _run(capsys, "realize", GOOD, "-o", f / "o.npz")
    assert (code, err) == (2, f"{ERR}{f / 'o.npz'}: cannot be written: Not a directory\n")
    code, err = _run(capsys, "realize", GOOD, "-o", tmp_path / "no" / "o.npz")
    assert (code, err) == (
        2,
        (f"{ERR}{tmp_path / 'no' / 'o.npz'}: the directory {tmp_path / 'no'} does not exist\n"),
    )


def test_an_unwritable_report_is_found_before_any_work(tmp_path, capsys):
    out = tmp_path / "o.npz"
    code, err = _run(capsys, "realize", GOOD, "-o", out, "--report", tmp_path / "no" / "r.json")
    assert code == 2 and err.startswith(f"{ERR}{tmp_path / 'no' / 'r.json'}: the directory")
    assert not out.exists()
    assert list(tmp_path.iterdir()) == []


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write into a read-only directory")
def test_a_read_only_directory_is_refused(tmp_path, capsys):
    d = tmp_path / "ro"
    d.mkdir(mode=0o500)
    code, err = _run(capsys, "realize", GOOD, "-o", d / "o.npz")
    assert (code, err) == (2, f"{ERR}{d / 'o.npz'}: the directory {d} is not writable\n")


def test_report_and_render_use_the_same_rule(tmp_path, capsys):
    fifo = tmp_path / "r.html"
    os.mkfifo(fifo)
    code, err = _run(capsys, "report", GOOD, "-o", fifo)
    assert code == 2 and "exists and is not a regular file" in err
    code, err = _run(capsys, "render", GOOD, "-o", GOOD.with_suffix(".png"), "--score", GOOD)
    assert code == 0 or "is also an input" not in err  # a distinct file: allowed
    GOOD.with_suffix(".png").unlink(missing_ok=True)
    png = tmp_path / "x.png"
    png.symlink_to(GOOD)
    code, err = _run(capsys, "render", GOOD, "-o", png)
    assert (code, err) == (2, f"{ERR}{png}: is also an input ({GOOD}); write to another file\n")


#: Every command that writes, with an output suffix it accepts.
WRITERS = [
    ("realize", ".npz"),
    ("report", ".html"),
    ("render", ".png"),
    ("export", ".csv"),
    ("compile", ".json"),
]


@pytest.mark.parametrize("command, suffix", WRITERS)
def test_every_writing_command_follows_the_output_rule(tmp_path, capsys, command, suffix):
    src = tmp_path / "five.azee"  # an .azee input counts as an input like a score
    src.write_text(":nb-5\n")
    fifo = tmp_path / f"pipe{suffix}"
    os.mkfifo(fifo)
    code, err = _run(capsys, command, src, "-o", fifo)
    assert (code, err) == (
        2,
        (
            f"{ERR}{fifo}: exists and is not a regular file (a device, fifo "
            "or socket); refusing to replace it\n"
        ),
    )
    link = tmp_path / f"link{suffix}"
    link.symlink_to(src)
    code, err = _run(capsys, command, src, "-o", link)
    assert (code, err) == (2, f"{ERR}{link}: is also an input ({src}); write to another file\n")
    code, err = _run(capsys, command, src, "-o", tmp_path / "no" / f"o{suffix}")
    assert (code, err) == (
        2,
        (
            f"{ERR}{tmp_path / 'no' / f'o{suffix}'}: the directory "
            f"{tmp_path / 'no'} does not exist\n"
        ),
    )
    assert src.read_text() == ":nb-5\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([src.name, fifo.name, link.name])


def test_export_score_and_lexicon_signs_are_inputs(tmp_path, capsys):
    lex = tmp_path / "signs"
    lex.mkdir()
    sign = lex / "hello.azee"
    sign.write_text(":seq(:bien, :nb-5)\n")
    src = tmp_path / "x.azee"
    src.write_text(":hello\n")
    code, err = _run(capsys, "compile", src, "-o", sign.with_suffix(".azee"), "--lexicon", lex)
    assert (code, err) == (2, f"{ERR}{sign}: is also an input ({sign}); write to another file\n")
    rollout = tmp_path / "x.npz"
    assert (
        main(["realize", str(src), "-o", str(rollout), "--lexicon", str(lex), "--fps", "10"]) == 0
    )
    capsys.readouterr()
    page = tmp_path / "x.html"
    page.symlink_to(src)
    code, err = _run(capsys, "export", rollout, "--score", src, "--lexicon", lex, "-o", page)
    assert (code, err) == (2, f"{ERR}{page}: is also an input ({src}); write to another file\n")
    assert src.read_text() == ":hello\n" and sign.read_text() == ":seq(:bien, :nb-5)\n"


def test_sigterm_while_writing_removes_the_temporary_file(tmp_path):
    install_signal_handlers()
    try:
        out = tmp_path / "o.json"
        with pytest.raises(Terminated), atomic_path(out) as tmp:
            tmp.write_text("partial")
            os.kill(os.getpid(), signal.SIGTERM)
        assert list(tmp_path.iterdir()) == []
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        signal.signal(signal.SIGINT, signal.default_int_handler)


def _long_score(path: Path, copies: int = 60) -> Path:
    """``copies`` armoire signs in a row (60: a score that takes tens of seconds to realize)."""
    score = json.loads((ROOT / "examples" / "armoire.json").read_text())
    kids = []
    for i in range(copies):
        r = dict(score["root"], name=f"S{i}", start=3.5 * i, end=3.5 * i + score["root"]["end"])
        kids.append(r)
    path.write_text(
        json.dumps(
            {
                "format": "azee-score",
                "version": 1,
                "root": {
                    "name": "L",
                    "kind": "sync",
                    "start": 0,
                    "end": 3.5 * copies,
                    "children": kids,
                },
            }
        )
    )
    return path


def test_sigterm_to_the_command_exits_143_and_leaves_nothing(tmp_path):
    import time

    src = _long_score(tmp_path / "long.json")
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    p = subprocess.Popen(
        [sys.executable, "-m", "azee_mj.cli", "realize", str(src), "-o", str(tmp_path / "o.npz")],
        env=env,
        stderr=subprocess.PIPE,
        text=True,
    )
    time.sleep(2.0)  # imported and realizing (the whole run takes over 10 s)
    p.send_signal(signal.SIGTERM)
    _, err = p.communicate(timeout=60)
    assert (p.returncode, err) == (143, "azee-mj: terminated\n")
    assert [x.name for x in tmp_path.iterdir()] == ["long.json"]


@pytest.mark.parametrize(
    "group, sig, code, message",
    [
        (False, signal.SIGTERM, 143, "azee-mj: terminated\n"),  # to the command only
        (True, signal.SIGINT, 130, "azee-mj: interrupted\n"),  # Ctrl-C: to the process group
    ],
)
def test_stopping_a_batch_stops_every_worker_and_leaves_whole_outputs(
    tmp_path, group, sig, code, message
):
    src = tmp_path / "in"
    src.mkdir()
    _long_score(src / "long.json", copies=300)  # minutes of work for one worker
    (src / "good.json").write_text(GOOD.read_text())
    out = tmp_path / "out"
    out.mkdir()
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    p = subprocess.Popen(
        [sys.executable, "-m", "azee_mj.cli", "realize", str(src), "-o", str(out), "--jobs", "2"],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    try:
        # Wait for good.json's summary line; the long score is then being realized in the
        # other worker.
        assert select.select([p.stdout], [], [], 120)[0], "no score finished within 120 s"
        assert p.stdout.readline().startswith(f"{out / 'good.npz'}: ")
        if group:
            os.killpg(p.pid, sig)
        else:
            p.send_signal(sig)
        _, err = p.communicate(timeout=60)  # returns once no worker holds the pipes open
    finally:
        if p.poll() is None:  # a failed test leaves no batch running
            os.killpg(p.pid, signal.SIGKILL)
    assert (p.returncode, err) == (code, message)
    assert [x.name for x in out.iterdir()] == ["good.npz"]  # no long.npz, no temporary file
    assert load_rollout(out / "good.npz", load_model().nq).fps == 50.0


# ---------------------------------------------------------------------------------------
# Limits
# ---------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "end, message",
    [
        (1e6, "R: field 'end': the score lasts 1000000 s; the longest score is 3600 s (1 hour)"),
        (
            1e308,
            "R: field 'end': 1e+308 is out of range; numbers in a score lie within -1e+06 to 1e+06",
        ),
        (
            10**30,
            (
                "R: field 'end': an integer of about 31 digits is out of range; numbers in a "
                "score lie within -1e+06 to 1e+06"
            ),
        ),
        (
            10**400,
            (
                "R: field 'end': an integer of about 401 digits is out of range; numbers in a "
                "score lie within -1e+06 to 1e+06"
            ),
        ),
    ],
)
def test_long_or_huge_scores_are_refused(end, message):
    with pytest.raises(ScoreError) as e:
        load_score(_score(end=end))
    assert str(e.value) == message


def test_a_huge_integer_in_the_file(tmp_path, capsys):
    src = tmp_path / "big.json"
    src.write_text(json.dumps(_score()).replace('"end": 1', '"end": ' + "9" * 400))
    code, err = _run(capsys, "realize", src, "-o", tmp_path / "o.npz")
    assert (code, err) == (
        2,
        (
            f"{ERR}{src}: invalid score: the integer 9999999999999999999… "
            "has 400 digits; numbers in a score lie within -1e+06 to 1e+06\n"
        ),
    )


@pytest.mark.parametrize("depth", [120, 600, 5000])
def test_deep_nesting_is_refused_without_recursion_error(tmp_path, capsys, depth):
    b = {"name": "K", "kind": "cstr", "start": 0, "end": 1, "constraints": []}
    text = json.dumps(b)
    for i in range(depth):
        text = f'{{"name": "N{i}", "kind": "sync", "start": 0, "end": 1, "children": [{text}]}}'
    src = tmp_path / "deep.json"
    src.write_text('{"format": "azee-score", "version": 1, "root": ' + text + "}")
    code, err = _run(capsys, "realize", src, "-o", tmp_path / "o.npz")
    assert code == 2
    assert err in (
        (
            f"{ERR}score: the score is nested deeper than 100 levels of objects and "
            "arrays; the deepest nesting allowed is 100\n"
        ),
        (f"{ERR}{src}: invalid score: nested deeper than 100 levels of objects and arrays\n"),
    )


def test_deep_expressions_are_refused():
    v = "up"
    for _ in range(200):
        v = {"unit": v}
    data = _score(
        constraints=[
            {"type": "orient", "bone": "!palm(s)", "axis": "DIR", "rel": "abs", "vector": v}
        ]
    )
    with pytest.raises(ScoreError) as e:
        load_score(data)
    assert str(e.value) == (
        "score: the score is nested deeper than 100 levels of objects and "
        "arrays; the deepest nesting allowed is 100"
    )


@pytest.mark.parametrize("fps", ["0", "nan", "inf", "1e308", "-5", "1001"])
@pytest.mark.parametrize("command", ["realize", "report", "render", "export"])
def test_fps_must_be_finite_and_in_range(tmp_path, capsys, fps, command):
    out = (
        tmp_path
        / {"realize": "o.npz", "report": "r.html", "render": "o.gif", "export": "o.csv"}[command]
    )
    code, err = _run(capsys, command, GOOD, "-o", out, "--fps", fps)
    if command == "render":  # the video's frame rate
        assert float(fps) > 240 or not 0 < float(fps) <= 240
        assert (code, err) == (2, f"{ERR}--fps: must be in (0, 240], got {float(fps):g}\n")
    else:
        assert (code, err) == (
            2,
            (f"{ERR}--fps must be a number from 1 to 1000, got {float(fps):g}\n"),
        )
    assert list(tmp_path.iterdir()) == []


def test_an_hour_with_its_rest_moves_is_refused_before_any_solve(capsys, tmp_path):
    # The lead-in and return to rest are planned after the key postures; a score whose
    # rollout could pass the frame limit with them is refused first (it took minutes before).
    path = tmp_path / "hour.json"
    path.write_text(json.dumps(_score(end=3599)))
    out = tmp_path / "hour.npz"
    code, err = _run(capsys, "realize", path, "-o", out)
    assert (code, err) == (
        2,
        (
            f"{ERR}3599 s of score at 50 fps, with up to 2.7 s of lead-in from rest and return "
            "to it, may need 180088 frames; the limit is 180001 frames (1 hour at 50 fps): "
            "lower --fps, realize with --no-rest or split the score\n"
        ),
    )
    assert not out.exists()
    assert realize(_score(end=3590), fps=1).qpos.shape[0] <= MAX_FRAMES


def test_frame_count_limit():
    assert frame_count(3600, 50) == MAX_FRAMES == 180_001
    with pytest.raises(AzeeError) as e:
        frame_count(3600, 60)
    assert str(e.value) == (
        "3600 s at 60 fps is 216001 frames; the limit is 180001 frames "
        "(1 hour at 50 fps): lower --fps or split the score"
    )
    with pytest.raises(AzeeError):
        check_fps(float("nan"))


# ---------------------------------------------------------------------------------------
# Internal errors
# ---------------------------------------------------------------------------------------


def test_an_internal_error_is_one_line_and_debug_shows_the_traceback(tmp_path, capsys, monkeypatch):
    import azee_mj.timeline

    def broken(*a, **k):
        raise ZeroDivisionError("division by zero")

    monkeypatch.setattr(azee_mj.timeline, "realize", broken)
    code, err = _run(capsys, "realize", GOOD, "-o", tmp_path / "o.npz")
    assert (code, err) == (
        3,
        (
            "azee-mj: internal error (ZeroDivisionError: division by zero); "
            "please report it with the command and its input files (add "
            "--debug for the traceback)\n"
        ),
    )
    code, err = _run(capsys, "--debug", "realize", GOOD, "-o", tmp_path / "o.npz")
    assert code == 3 and err.startswith("Traceback (most recent call last):")
    assert list(tmp_path.iterdir()) == []


# ---------------------------------------------------------------------------------------
# Time
# ---------------------------------------------------------------------------------------


def test_block_times_are_exact_and_frames_follow_one_rule():
    assert exact_time(1.0 + 1.4) == 2.4 == 120 / 50
    assert frame_range(exact_time(1.0 + 1.4), 3.0, 50, 1000) == range(120, 150)
    assert frame_range(0.1 * 3, 0.5, 10, 1000) == range(3, 5)


def _shifted(data: dict, shift: float) -> dict:
    d = json.loads(json.dumps(data))
    d["root"]["end"] += shift
    for c in d["root"]["children"]:
        c["start"] += shift
        c["end"] += shift
    return d


def test_a_sign_shifted_by_multiples_of_a_tenth_meets_what_it_met():
    data = json.loads((ROOT / "examples" / "nicht-sondern.json").read_text())
    met = {}
    for shift in (0.0, 0.1, 0.3, 1.0):
        r = realize(_shifted(data, shift))
        met[shift] = [(t.block, t.index, t.ok) for t in r.traces]
    assert sum(ok for *_, ok in met[0.0]) == 23 == len(met[0.0])
    assert met[0.1] == met[0.3] == met[1.0] == met[0.0]


# ---------------------------------------------------------------------------------------
# Determinism
# ---------------------------------------------------------------------------------------


def test_two_processes_with_different_hash_seeds_give_the_same_bytes(tmp_path):
    outs = []
    for seed in ("4", "5"):
        out = tmp_path / f"a{seed}.npz"
        env = dict(os.environ, PYTHONPATH=str(ROOT), PYTHONHASHSEED=seed)
        subprocess.run(
            [
                sys.executable,
                "-m",
                "azee_mj.cli",
                "realize",
                str(ROOT / "examples" / "armoire.json"),
                "-o",
                str(out),
            ],
            env=env,
            check=True,
            capture_output=True,
        )
        with zipfile.ZipFile(out) as z:
            outs.append({n: z.read(n) for n in z.namelist()})
    a, b = outs
    assert list(a) == list(b)
    assert [n for n in a if a[n] != b[n]] == []
    assert (tmp_path / "a4.npz").read_bytes() == (tmp_path / "a5.npz").read_bytes()


# ---------------------------------------------------------------------------------------
# Rollout files
# ---------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def rollout():
    return realize(load_score(GOOD), fps=10)


def _write(path, arrays):
    with open(path, "wb") as f:
        np.savez(f, **arrays)
    return path


def test_sparse_residuals_round_trip_and_dense_files_still_load(tmp_path, rollout):
    nq = load_model().nq
    save_rollout(tmp_path / "r.npz", rollout)
    back = load_rollout(tmp_path / "r.npz", nq)
    for t, u in zip(rollout.traces, back.traces, strict=True):
        assert (t.block, t.index, t.first, t.frames) == (u.block, u.index, u.first, u.frames)
        assert np.array_equal(t.values, u.values, equal_nan=True)
    a = rollout_arrays(rollout)
    dense = {
        k: v
        for k, v in a.items()
        if k not in ("residual_first", "residual_count", "residual_values")
    }
    dense["residuals"] = np.array([t.values for t in rollout.traces]).T
    del dense["residual_reasons"]  # files from before the reasons were stored
    old = load_rollout(_write(tmp_path / "old.npz", dense), nq)
    assert [t.worst for t in old.traces] == [t.worst for t in rollout.traces]
    assert {t.reason for t in old.traces} == {""}


def test_the_reason_of_a_miss_round_trips(tmp_path, rollout):
    why = "stopped by the upper limit of joint back_1_rot (18 deg)"
    traces = (dataclasses.replace(rollout.traces[0], reason=why), *rollout.traces[1:])
    save_rollout(tmp_path / "r.npz", dataclasses.replace(rollout, traces=traces))
    back = load_rollout(tmp_path / "r.npz", load_model().nq)
    assert [t.reason for t in back.traces] == [why] + [t.reason for t in rollout.traces[1:]]


def _damaged(tmp_path, rollout, **changes):
    a = rollout_arrays(rollout) | changes
    return _write(tmp_path / "bad.npz", a)


@pytest.mark.parametrize(
    "change, message",
    [
        ({"fps": np.array([10.0, 20.0])}, "fps must be one number, got shape (2,)"),
        ({"fps": np.array("ten")}, "array 'fps' must hold numbers, got dtype <U3"),
        ({"fps": np.array(np.nan)}, "fps must be a number from 1 to 1000, got nan"),
        ({"time": np.zeros((3, 3))}, "array 'time' must have 1 dimension(s), got shape (3, 3)"),
        (
            {"site_names": np.arange(3)},
            "array 'site_names' must be a list of names, got dtype int64 shape (3,)",
        ),
        ({"residual_names": np.array(["nohash"] * 3)}, "residual name 'nohash' is not BLOCK#INDEX"),
    ],
)
def test_damaged_rollouts_are_refused_with_one_line(tmp_path, rollout, change, message):
    path = _damaged(tmp_path, rollout, **change)
    with pytest.raises(AzeeError) as e:
        load_rollout(path, load_model().nq)
    assert str(e.value) == f"{path}: {message}"


def test_truncated_corrupt_and_huge_header_rollouts(tmp_path, rollout, capsys):
    save_rollout(tmp_path / "r.npz", rollout)
    data = (tmp_path / "r.npz").read_bytes()
    (tmp_path / "trunc.npz").write_bytes(data[: len(data) // 2])
    (tmp_path / "noise.npz").write_bytes(bytes(range(256)) * 10)
    huge = tmp_path / "huge.npz"
    header = np.lib.format.header_data_from_array_1_0(np.zeros(3))
    header["shape"] = (10**9, 10**6)
    with zipfile.ZipFile(huge, "w") as z, z.open("qpos.npy", "w") as f:
        np.lib.format.write_array_header_1_0(f, header)
        f.write(b"\0" * 24)
    for name in ("trunc", "noise", "huge"):
        code, err = _run(capsys, "check", tmp_path / f"{name}.npz")
        assert (
            code == 2 and err.startswith(f"{ERR}{tmp_path / name}.npz: ") and err.count("\n") == 1
        )
    code, err = _run(capsys, "check", huge)
    assert err == (
        f"{ERR}{huge}: array 'qpos.npy' announces shape (1000000000, 1000000), more "
        "than the file holds or than a rollout may be\n"
    )


def test_nan_postures_are_a_check_finding_and_refused_elsewhere(tmp_path, rollout, capsys):
    q = rollout.qpos.copy()
    q[3, 5] = np.nan
    path = _damaged(tmp_path, rollout, qpos=q)
    code = main(["check", str(path)])
    out = capsys.readouterr().out
    assert code == 1
    assert "1 frame(s) with a non-finite posture (NaN or infinity), first at t=0.300s" in out
    code, err = _run(capsys, "render", path, "-o", tmp_path / "x.png")
    assert (code, err) == (2, f"{ERR}{path}: qpos is not finite at 1 frame(s), first at frame 3\n")


# ---------------------------------------------------------------------------------------
# Messages
# ---------------------------------------------------------------------------------------


def test_control_characters_are_escaped_and_long_names_shortened():
    data = _score(name="A\nB\x1b[2J", end=0)
    with pytest.raises(ScoreError) as e:
        load_score(data)
    assert str(e.value) == (
        "A\\x0aB\\x1b[2J: field 'end': end 0 is not after start 0; a block needs start < end"
    )
    with pytest.raises(ScoreError) as e:
        load_score(_score(name="N" * 100_000, end=0))
    assert str(e.value) == (
        "N" * 79 + "…: field 'end': end 0 is not after start 0; a block needs start < end"
    )
    assert tidy("\u202eevil " + "x" * 200) == "\\u202eevil " + "x" * 79 + "…"


def test_an_unknown_site_is_quoted_as_written(tmp_path):
    data = _score(constraints=[{"type": "place", "site": "@NOSE(s)", "at": "@FH"}])
    with pytest.raises(ScoreError) as e:
        load_score(data)
    assert str(e.value) == (
        "R: constraint 1 (place): unknown site '@NOSE(s)'; did you mean "
        "'@NO(s)'? (azee-mj sites lists all)"
    )
