"""Rough edges a new user and a hostile input hit (issue 27): the command line's friction,
unreadable and never-ending inputs, signals, verdicts that must agree."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest

from azee_mj.cli import COMMANDS, main
from azee_mj.errors import MAX_MESSAGE

ROOT = Path(__file__).resolve().parent.parent
DATA = Path(__file__).parent / "data"
GOOD = DATA / "good.json"
ERR = "azee-mj: error: "
ENV = dict(os.environ, PYTHONPATH=str(ROOT))


def _run(capsys, *argv) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    return code, out.out, out.err


def _cli(*argv, **kw) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "azee_mj.cli", *map(str, argv)],
        capture_output=True,
        text=True,
        env=ENV,
        check=False,
        **kw,
    )


# ---------------------------------------------------------------------------------------
# A new user's friction
# ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("argv", [["sites"], ["rules"]])
def test_a_closed_pipe_ends_the_command_quietly(argv):
    p = subprocess.Popen(
        [sys.executable, "-m", "azee_mj.cli", *argv],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=ENV,
    )
    assert p.stdout.readline()  # 'head -1'
    p.stdout.close()
    err = p.stderr.read().decode()
    assert (p.wait(60), err) == (0, "")


def test_a_mistyped_command_gets_a_did_you_mean(capsys):
    code, out, err = _run(capsys, "realise", GOOD, "-o", "x.npz")
    assert (code, out) == (2, "")
    assert err == (
        f"{ERR}unknown command 'realise'; did you mean 'realize'? (commands: sites, "
        "compile, rules, realize, check, preview, render, export, report)\n"
    )
    code, out, err = _run(capsys, "frobnicate")
    assert err == (
        f"{ERR}unknown command 'frobnicate' (commands: sites, compile, rules, realize, "
        "check, preview, render, export, report)\n"
    )


def test_every_subcommand_help_says_what_it_does(capsys):
    for name, (help_line, more) in COMMANDS.items():
        with pytest.raises(SystemExit) as e:
            main([name, "--help"])
        assert e.value.code == 0
        text = capsys.readouterr().out
        description = text.split("\n\n")[1]  # after the usage
        assert " ".join(description.split()) == f"{help_line[0].upper()}{help_line[1:]}. {more}"
    with pytest.raises(SystemExit):
        main(["--help"])
    listed = capsys.readouterr().out
    assert all(f"    {name}" in listed for name in COMMANDS)


def test_check_on_a_score_says_to_realize_it_first(tmp_path, capsys):
    code, out, err = _run(capsys, "check", GOOD)
    assert (code, out) == (2, "")
    assert err == (
        f"{ERR}{GOOD}: check takes a rollout .npz, and this is a score: realize it first "
        f"(azee-mj realize {GOOD} -o OUT.npz), then azee-mj check OUT.npz --score {GOOD}\n"
    )


def test_compile_on_a_json_score_says_compile_takes_azee(capsys):
    code, out, err = _run(capsys, "compile", GOOD)
    assert (code, out) == (2, "")
    assert err == (
        f"{ERR}{GOOD}: compile takes an AZee expression (.azee); a .json score needs no "
        "compiling: give it to realize, check --score, render or export as it is\n"
    )


def test_long_messages_are_shortened(tmp_path, capsys):
    name = "N" * 1_000_000
    (tmp_path / "s.json").write_text(
        json.dumps(
            {
                "format": "azee-score",
                "version": 1,
                "root": {"name": name, "kind": "nope", "start": 0, "end": 1},
            }
        )
    )
    (tmp_path / "e.azee").write_text(f":{name}\n")
    for argv in (
        ("realize", tmp_path / "s.json", "-o", tmp_path / "o.npz"),
        ("compile", tmp_path / "e.azee"),
        ("compile", "-e", f":seq(:bien, ^{name})"),
    ):
        code, _, err = _run(capsys, *argv)
        assert code == 2
        assert err.startswith(ERR) and err.count("\n") == 1
        assert len(err) <= len(ERR) + MAX_MESSAGE + 1, len(err)
        assert "NNNNNNNN…" in err


def test_hostile_file_names_are_escaped_in_success_lines(tmp_path, capsys):
    out = tmp_path / "a\x1b[2Jb\nforged: written.npz"
    code, stdout, _ = _run(capsys, "realize", GOOD, "-o", out, "--fps", "10")
    assert code == 0 and out.exists()
    assert "\x1b" not in stdout and "a\\x1b[2Jb\\x0aforged" in stdout
    page = tmp_path / "p\x1b]0;t\x07.csv"
    code, stdout, _ = _run(capsys, "export", out, "-o", page)
    assert code == 0
    assert stdout == f"{tmp_path}/p\\x1b]0;t\\x07.csv: written\n"


# ---------------------------------------------------------------------------------------
# Signals
# ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("sig", [signal.SIGHUP, signal.SIGQUIT])
def test_sighup_and_sigquit_leave_no_temporary_file(tmp_path, sig):
    src = json.loads((ROOT / "examples" / "armoire.json").read_text())
    kids = [
        dict(src["root"], name=f"S{i}", start=3.5 * i, end=3.5 * i + src["root"]["end"])
        for i in range(60)
    ]
    root = {"name": "L", "kind": "sync", "start": 0, "end": 210, "children": kids}
    score = tmp_path / "long.json"
    score.write_text(json.dumps({"format": "azee-score", "version": 1, "root": root}))
    rollout = tmp_path / "long.npz"
    assert main(["realize", str(score), "-o", str(rollout), "--fps", "50"]) == 0
    out = tmp_path / "out"
    out.mkdir()
    p = subprocess.Popen(
        [sys.executable, "-m", "azee_mj.cli", "export", str(rollout), "-o", str(out / "o.bvh")],
        env=ENV,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:  # stop the writer while its temporary file exists
        temporaries = [f for f in out.iterdir() if f.name.startswith(".")]
        if temporaries:
            p.send_signal(signal.SIGSTOP)
            if all(f.exists() for f in temporaries):
                break
            p.send_signal(signal.SIGCONT)
        time.sleep(0.02)
    p.send_signal(sig)  # delivered mid-write when the writer continues
    p.send_signal(signal.SIGCONT)
    _, err = p.communicate(timeout=60)
    assert (p.returncode, err) == (143, "azee-mj: terminated\n")
    assert list(out.iterdir()) == []


# ---------------------------------------------------------------------------------------
# Files the user cannot read
# ---------------------------------------------------------------------------------------

_AS_OTHER = """
import os, sys
import azee_mj.cli, azee_mj.score, azee_mj.azee, azee_mj.timeline, azee_mj.rollout_io
import azee_mj.check, azee_mj.schedule, azee_mj.batch, azee_mj.files, difflib, tempfile
if os.getuid() == 0:
    os.setgroups([]); os.setgid(65534); os.setuid(65534)
sys.exit(azee_mj.cli.main(sys.argv[1:]))
"""


@pytest.fixture
def public_tmp():
    """A directory every user may enter (pytest's own is the owner's alone)."""
    d = Path(tempfile.mkdtemp(prefix="azee-perm-"))
    d.chmod(0o777)
    yield d
    for p in sorted(d.rglob("*"), reverse=True):
        p.chmod(0o777) if p.is_dir() else None
    import shutil

    shutil.rmtree(d)


def _as_other(*argv) -> tuple[int, str]:
    p = subprocess.run(
        [sys.executable, "-c", _AS_OTHER, *map(str, argv)],
        capture_output=True,
        text=True,
        env=ENV,
        check=False,
    )
    return p.returncode, p.stderr


def test_unreadable_inputs_are_one_message_and_exit_2(public_tmp):
    d = public_tmp
    score = d / "s.json"
    score.write_text(GOOD.read_text())
    score.chmod(0o000)
    expr = d / "e.azee"
    expr.write_text(":bien\n")
    expr.chmod(0o000)
    hidden = d / "hidden"
    hidden.mkdir()
    (hidden / "s.json").write_text(GOOD.read_text())
    hidden.chmod(0o000)
    lex = d / "lex"
    lex.mkdir()
    (lex / "x.azee").write_text(":bien\n")
    lex.chmod(0o000)
    out = d / "o.npz"
    cases = [
        (("realize", score, "-o", out), f"{score}: cannot read the score: Permission denied"),
        (("compile", expr), f"{expr}: cannot read the expression: Permission denied"),
        (
            ("realize", hidden / "s.json", "-o", out),
            f"{hidden / 's.json'}: cannot read the score: Permission denied",
        ),
        (("rules", "--lexicon", lex), f"{lex}: cannot read the directory: Permission denied"),
        (
            ("compile", "-e", ":bien", "--lexicon", lex),
            f"{lex}: cannot read the directory: Permission denied",
        ),
    ]
    for argv, message in cases:
        assert _as_other(*argv) == (2, f"{ERR}{message}\n"), argv
    assert not out.exists()


# ---------------------------------------------------------------------------------------
# Inputs that never end, or are enormous; the .azee front end
# ---------------------------------------------------------------------------------------


def test_a_byte_order_mark_is_accepted(tmp_path, capsys):
    expr = tmp_path / "e.azee"
    expr.write_bytes(b"\xef\xbb\xbf:bien\n")
    score = tmp_path / "s.json"
    score.write_bytes(b"\xef\xbb\xbf" + GOOD.read_bytes())
    code, out, err = _run(capsys, "compile", expr)
    assert (code, err) == (0, "") and json.loads(out)["root"]["name"]
    lex = tmp_path / "lex"
    lex.mkdir()
    (lex / "hello.azee").write_bytes(b"\xef\xbb\xbf:bien\n")
    code, out, err = _run(capsys, "compile", "-e", ":hello", "--lexicon", lex)
    assert (code, err) == (0, "")
    code, out, err = _run(capsys, "realize", score, "-o", tmp_path / "o.npz", "--fps", "10")
    assert (code, err) == (0, "")


@pytest.mark.parametrize("device", ["/dev/zero", "/dev/urandom"])
def test_a_score_or_sign_that_never_ends_is_refused(tmp_path, capsys, device):
    score = tmp_path / "s.json"
    score.symlink_to(device)
    code, _, err = _run(capsys, "realize", score, "-o", tmp_path / "o.npz")
    assert code == 2
    assert err == (
        f"{ERR}{score}: cannot read the score: not a regular file (a device, fifo or socket)\n"
    )
    lex = tmp_path / "lex"
    lex.mkdir()
    (lex / "zero.azee").symlink_to(device)
    code, _, err = _run(capsys, "compile", "-e", ":zero", "--lexicon", lex)
    assert code == 2
    assert err == (
        f"{ERR}{lex / 'zero.azee'}: lexicon :zero: cannot read the sign: not a regular file "
        "(a device, fifo or socket)\n"
    )


def test_a_fifo_in_a_lexicon_does_not_hang(tmp_path):
    lex = tmp_path / "lex"
    lex.mkdir()
    os.mkfifo(lex / "pipe.azee")
    (lex / "hello.azee").write_text(":bien\n")
    # unused: compile does not open it
    p = _cli("compile", "-e", ":hello", "--lexicon", lex, timeout=60)
    assert (p.returncode, p.stderr) == (0, "")
    p = _cli("rules", "--lexicon", lex, timeout=60)
    assert p.returncode == 2
    assert p.stderr == (
        f"{ERR}{lex / 'pipe.azee'}: lexicon :pipe: cannot read the sign: not a regular file "
        "(a device, fifo or socket)\n"
    )


def test_a_score_or_sign_over_the_size_limit_is_refused(tmp_path, capsys):
    from azee_mj.files import MAX_TEXT_BYTES

    big = tmp_path / "big.json"
    with open(big, "wb") as f:
        f.truncate(MAX_TEXT_BYTES + 1)  # sparse: no disk used
    code, _, err = _run(capsys, "realize", big, "-o", tmp_path / "o.npz")
    assert code == 2
    assert err == (
        f"{ERR}{big}: cannot read the score: larger than {MAX_TEXT_BYTES // 2**20} MB, "
        "the limit for a score, expression or sign file\n"
    )
    expr = tmp_path / "big.azee"
    big.rename(expr)
    code, _, err = _run(capsys, "compile", expr)
    assert code == 2
    assert err == (
        f"{ERR}{expr}: cannot read the expression: larger than "
        f"{MAX_TEXT_BYTES // 2**20} MB, the limit for a score, expression or sign file\n"
    )


@pytest.mark.parametrize(
    "text, where",
    [
        (":seq(" * 600 + ":bien" + ")" * 600, "1:325"),
        ("".join(" " * i + ":seq\n" for i in range(600)) + " " * 600 + ":bien\n", "65:65"),
    ],
)
def test_deep_azee_nesting_is_a_clean_error(tmp_path, capsys, text, where):
    from azee_mj.azee.syntax import MAX_NESTING

    expr = tmp_path / "deep.azee"
    expr.write_text(text)
    code, _, err = _run(capsys, "compile", expr)
    assert code == 2
    assert err == f"{ERR}{expr}:{where}: syntax: nesting deeper than {MAX_NESTING} levels\n"


# ---------------------------------------------------------------------------------------
# Rollout files: verdicts and sizes
# ---------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def rollout_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("rollout") / "good.npz"
    assert main(["realize", str(GOOD), "-o", str(path), "--fps", "10"]) == 0
    return path


def _arrays(path) -> dict:
    with np.load(path) as z:
        return {k: z[k] for k in z.files}


def test_nan_site_positions_are_a_check_finding_as_exports_refuse_them(
    tmp_path, capsys, rollout_file
):
    arrays = _arrays(rollout_file)
    arrays["site_pos"][4, 7, 1] = np.nan
    bad = tmp_path / "bad.npz"
    np.savez(bad, **arrays)
    capsys.readouterr()
    code, out, _ = _run(capsys, "check", bad)
    assert code == 1
    assert "1 frame(s) with a non-finite site position (NaN or infinity), first at t=0.400s" in out
    assert "clean" not in out
    code, _, err = _run(capsys, "export", bad, "-o", tmp_path / "x.csv")
    assert (code, err) == (
        2,
        f"{ERR}{bad}: site_pos is not finite at 1 frame(s), first at frame 4\n",
    )


def _member_of_zeros(path: Path, name: str, dtype: str, shape: tuple) -> None:
    """Add ``name`` to the zip at ``path``: an .npy of zeros that deflates to little."""
    import zipfile

    with (
        zipfile.ZipFile(path, "a", zipfile.ZIP_DEFLATED, compresslevel=1) as zf,
        zf.open(name, "w", force_zip64=True) as f,
    ):
        header = {"descr": dtype, "fortran_order": False, "shape": shape}
        np.lib.format.write_array_header_2_0(f, header)
        n = int(np.prod(shape)) * np.dtype(dtype).itemsize
        chunk = bytes(min(n, 64 << 20))
        while n > 0:
            f.write(chunk[: min(n, len(chunk))])
            n -= len(chunk)


def test_a_rollout_announcing_more_than_memory_allows_is_refused(tmp_path, capsys, rollout_file):
    from azee_mj.rollout_io import MAX_BYTES

    arrays = _arrays(rollout_file)
    del arrays["site_pos"]
    path = tmp_path / "int8.npz"
    np.savez(path, **arrays)
    shape = (len(arrays["time"]), 18_000_000, 3)  # int8: 1/8 of its size as numbers
    _member_of_zeros(path, "site_pos.npy", "|i1", shape)
    code, _, err = _run(capsys, "check", path)
    need = int(np.prod(shape)) * 8 // 2**20
    assert code == 2
    assert err == (
        f"{ERR}{path}: array 'site_pos.npy' announces shape {shape}, {need} MB as "
        f"numbers; a rollout's arrays may take at most {MAX_BYTES // 2**20} MB in all\n"
    )


def test_arrays_a_rollout_does_not_hold_are_never_read(tmp_path, rollout_file):
    path = tmp_path / "junk.npz"
    path.write_bytes(rollout_file.read_bytes())
    _member_of_zeros(path, "junk.npy", "<f8", (1 << 27,))  # 1 GB once inflated
    code = (  # numpy's arrays are traced; a forked child's inherited RSS is not counted
        "import sys, tracemalloc\n"
        "from azee_mj.model import load_model\n"
        "from azee_mj.rollout_io import load_rollout\n"
        "nq = load_model().nq\n"
        "tracemalloc.start()\n"
        "r = load_rollout(sys.argv[1], nq)\n"
        "print(len(r.time), tracemalloc.get_traced_memory()[1] // 2**20)\n"
    )
    p = subprocess.run(
        [sys.executable, "-c", code, str(path)],
        capture_output=True,
        text=True,
        env=ENV,
        check=False,
    )
    frames, peak_mb = map(int, p.stdout.split())
    with np.load(rollout_file) as z:
        assert frames == len(z["time"]) and peak_mb < 500, (p.stderr, peak_mb)


def test_realize_and_check_say_one_penetration_verdict(tmp_path, capsys):
    out = tmp_path / "good.npz"
    code, said, _ = _run(capsys, "realize", GOOD, "-o", out, "--fps", "25")
    assert code == 0
    code, checked, _ = _run(capsys, "check", out, "--score", GOOD)
    verdict = checked.splitlines()[2]
    assert verdict == "clean: no penetration over the limit, every joint inside its range"
    assert said.splitlines()[1] == verdict


def test_the_penetration_verdict_is_the_checks(tmp_path, capsys, rollout_file):
    from azee_mj.check import rollout_verdict, verdict_lines
    from azee_mj.model import load_model
    from azee_mj.rollout_io import load_rollout
    from azee_mj.schedule import make_solver
    from azee_mj.score import load_score

    arrays = _arrays(rollout_file)
    s = make_solver()
    for j, v in (("arm_R_flex", 0.3), ("arm_R_abd", -0.5), ("f_arm_R_flex", 0.0)):
        arrays["qpos"][:, s.model.jnt_qposadr[s.joint_id(j)]] = v  # forearm through the chest
    bad = tmp_path / "bad.npz"
    np.savez(bad, **arrays)
    model = load_model()
    r = load_rollout(bad, model.nq)
    report = rollout_verdict(model, r, load_score(GOOD), s)
    lines = verdict_lines(report, r.fps)
    assert lines[0].endswith("penetration(s) over the limit, e.g.:")
    code, checked, _ = _run(capsys, "check", bad, "--score", GOOD)
    assert code == 1
    assert checked.splitlines()[2 : 2 + len(lines)] == list(lines)


@pytest.mark.parametrize(
    "name",
    [
        "examples/info-about.json",
        "examples/nicht-sondern.json",
        "tests/data/kinds.json",
    ],
)
def test_realize_and_check_agree_on_every_constraint(name):
    from azee_mj.score import Trill, load_score
    from azee_mj.timeline import realize, score_traces

    score = load_score(ROOT / name)
    r = realize(score, fps=50)
    trilled = {b.path for b in score.blocks() if any(isinstance(c, Trill) for c in b.constraints)}
    said = {(t.block, t.index): t for t in r.traces if t.block not in trilled}
    every = score_traces(score, r.qpos, r.fps, None, r.score_start)
    checked = {(t.block, t.index): t for t in every}
    checked = {k: t for k, t in checked.items() if k in said}
    assert set(checked) == set(said)
    for k, t in said.items():
        assert (t.ok, t.worst) == pytest.approx((checked[k].ok, checked[k].worst), abs=1e-9), k


# ---------------------------------------------------------------------------------------
# The rendering snippet, pasted
# ---------------------------------------------------------------------------------------


def _snippet() -> str:
    text = (ROOT / "docs" / "rendering.md").read_text()
    code = text.split("```python\n", 1)[1].split("```", 1)[0]
    return code.replace('"examples/', f'"{ROOT}/examples/')


@pytest.mark.parametrize("how", ["file", "stdin"])
def test_the_rendering_snippet_works_as_pasted(tmp_path, how):
    pytest.importorskip("imageio_ffmpeg", reason="video needs azee_mj[render]")
    script = tmp_path / "snippet.py"
    script.write_text(_snippet())  # no __main__ guard: as a user pastes it
    argv = [sys.executable, str(script)] if how == "file" else [sys.executable, "-"]
    p = subprocess.run(
        argv,
        stdin=script.open() if how == "stdin" else subprocess.DEVNULL,
        capture_output=True,
        text=True,
        env=ENV,
        cwd=tmp_path,
        timeout=300,
        check=False,
    )
    assert (p.returncode, p.stderr) == (0, "")
    assert (tmp_path / "bien.mp4").stat().st_size > 10_000


@pytest.mark.parametrize("command", ["render", "realize"])
def test_a_module_in_the_working_folder_is_never_imported_by_workers(tmp_path, command):
    # Python 3.11's forkserver puts the working folder first on its module path: a user's
    # timeit.py there was run instead of the standard module ("internal error (EOFError)").
    exe = Path(sys.executable).parent / "azee-mj"
    if not exe.exists():
        pytest.skip("needs the installed azee-mj command")
    (tmp_path / "timeit.py").write_text("open('ran', 'w').close()\nraise SystemExit(7)\n")
    bien = str(ROOT / "examples" / "bien.json")
    if command == "render":
        pytest.importorskip("PIL", reason="GIF needs azee_mj[render]")
        argv = ["render", bien, "-o", "b.gif", "--size", "240x200", "--fps", "10"]
    else:
        (tmp_path / "in").mkdir()
        (tmp_path / "out").mkdir()
        for name in ("bien", "arbre"):
            (tmp_path / "in" / f"{name}.json").write_text(
                (ROOT / "examples" / f"{name}.json").read_text()
            )
        argv = ["realize", "in", "-o", "out/", "--jobs", "2", "--fps", "10"]
    p = subprocess.run(
        [str(exe), *argv], capture_output=True, text=True, cwd=tmp_path, timeout=300, check=False
    )
    assert (p.returncode, "internal error" in p.stderr) == (0, False)
    assert not (tmp_path / "ran").exists()


def test_the_readme_single_posture_snippet_runs():
    text = (ROOT / "README.md").read_text()
    code = text.split("Single postures:", 1)[1].split("```python\n", 1)[1].split("```", 1)[0]
    p = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=ENV, check=False
    )
    assert (p.returncode, p.stderr) == (0, "")
    assert p.stdout.splitlines()[1] == "True"


def test_the_csv_legend_names_every_column_stem():
    import re

    from azee_mj.export.csv import columns

    text = (ROOT / "docs" / "exports.md").read_text().split("### Column names", 1)[1]
    legend = text.split("\n## ", 1)[0]
    stems = set(re.findall(r"`([A-Za-z_]+)`", legend))
    missing = set()
    for name in columns():
        digit = re.fullmatch(r"[TIMRL]_([A-Za-z]+)_[LR](_[123])?", name)
        if digit:
            stem = f"X_{digit.group(1)}" + ("_n" if digit.group(2) else "")
            found = stem in set(re.findall(r"`(X_[A-Za-z_]+)`", legend))
        else:
            stem = re.sub(r"_[LR]$", "", name)
            found = stem in stems
        if not found:
            missing.add(stem)
    assert missing == set()


def test_every_array_a_rollout_file_holds_is_read(tmp_path):
    from azee_mj import physics
    from azee_mj.rollout_io import (
        ARRAYS,
        dynamic_arrays,
        load_rollout,
        rollout_arrays,
        save_rollout,
    )
    from azee_mj.timeline import realize

    r = physics.realize(GOOD, fps=10)
    assert set(rollout_arrays(r)) | set(dynamic_arrays(r)) <= set(ARRAYS)
    save_rollout(tmp_path / "d.npz", r)
    back = load_rollout(tmp_path / "d.npz", r.qpos.shape[1])
    assert isinstance(back, physics.DynamicRollout)
    assert set(rollout_arrays(realize(GOOD, fps=10))) <= set(ARRAYS)
