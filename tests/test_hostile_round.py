"""Hostile inputs on the surfaces added in the same round as issue 27 (batch manifests,
mouthing, Dask addresses, the physics mode): each case failed before its fix."""

from __future__ import annotations

import csv
import io
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from azee_mj.cli import main
from azee_mj.corpus import FIELDS, Manifest, read_manifest
from azee_mj.errors import AzeeError

ROOT = Path(__file__).resolve().parent.parent
GOOD = Path(__file__).parent / "data" / "good.json"
ERR = "azee-mj: error: "

#: Names a spreadsheet would run as formulas, or that drive a terminal.
FORMULAS = ['=HYPERLINK("http://x")', "+1+1", "-2+3", "@SUM(A1)", "'=quoted", "'plain"]
CONTROLS = ["red\x1b[31m.json", "csi\x9b2J.json", "bidi\u202egnp.json", "nl\nforged.json"]


def _run(capsys, *argv) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    return code, out.out, out.err


def _rows(names: list[str]) -> list[dict]:
    return [
        {k: None for k in FIELDS}
        | {"input": n, "output": n + ".npz", "status": "failed"}
        | {"error": f"{n}: bad", "frames": 3}
        for n in names
    ]


def test_a_csv_manifest_writes_no_formula_and_reads_its_cells_back(tmp_path):
    path = tmp_path / "m.csv"
    with Manifest(path, _rows(FORMULAS[:3])) as m:
        for r in _rows(FORMULAS[3:]):
            m.add(r)
    cells = [c for row in csv.reader(io.StringIO(path.read_text())) for c in row]
    assert not [c for c in cells if c[:1] in ("=", "+", "-", "@")]
    assert '\'=HYPERLINK("http://x")' in cells and "''=quoted" in cells
    rows = read_manifest(path)
    assert [r["input"] for r in rows] == FORMULAS
    assert [r["output"] for r in rows] == [n + ".npz" for n in FORMULAS]
    assert [r["frames"] for r in rows] == ["3"] * len(FORMULAS)


@pytest.mark.parametrize("suffix", [".csv", ".jsonl"])
def test_a_manifest_never_holds_a_raw_control_character(tmp_path, suffix):
    path = tmp_path / f"m{suffix}"
    with Manifest(path, _rows(CONTROLS)):
        pass
    text = path.read_text(encoding="utf-8")
    for c in "\x1b\x9b\u202e":
        assert c not in text
    assert text.count("\n") == len(CONTROLS) + (suffix == ".csv")  # one line a row
    rows = read_manifest(path)
    if suffix == ".jsonl":  # JSON escapes: the names come back exactly
        assert [r["input"] for r in rows] == CONTROLS
        assert [json.loads(line)["error"] for line in text.splitlines()] == [
            f"{n}: bad" for n in CONTROLS
        ]
    else:  # CSV has no escapes: the names are shown as the terminal lines show them
        assert [r["input"] for r in rows] == [
            "red\\x1b[31m.json",
            "csi\\x9b2J.json",
            "bidi\\u202egnp.json",
            "nl\\x0aforged.json",
        ]


def test_a_batch_of_hostile_file_names_writes_a_safe_manifest_and_terminal(tmp_path, capsys):
    src, out = tmp_path / "src", tmp_path / "out"
    src.mkdir()
    out.mkdir()
    names = ["=1+2.json", "-x.json", "esc\x1b]0;pwned\x07.json"]
    for n in names:
        shutil.copy(GOOD, src / n)
    manifest = tmp_path / "m.csv"
    code, said, err = _run(
        capsys,
        "realize",
        src,
        "-o",
        f"{out}/",
        "--fps",
        "10",
        "--jobs",
        "1",
        "--manifest",
        manifest,
    )
    assert code == 0, err
    for text in (said, err, manifest.read_text()):
        assert "\x1b" not in text and "\x07" not in text
    cells = [c for row in csv.reader(io.StringIO(manifest.read_text())) for c in row]
    assert not [c for c in cells if c[:1] in ("=", "+", "-", "@")]
    got = sorted(Path(r["input"]).name for r in read_manifest(manifest))
    assert got == sorted(["=1+2.json", "-x.json", "esc\\x1b]0;pwned\\x07.json"])


def test_a_mouthed_word_has_a_length_limit(tmp_path, capsys):
    from azee_mj.mouthing import MAX_WORD

    out = tmp_path / "o.json"
    word = "a" * (MAX_WORD + 1)
    code, _, err = _run(capsys, "compile", "-e", f':mouthing(:bien, "{word}")', "-o", out)
    assert code == 2
    assert err == (
        f"{ERR}<-e>:1:1: :mouthing'word: the word is {MAX_WORD + 1} characters long; a "
        f"mouthing says at most {MAX_WORD} (a word or a short phrase)\n"
    )
    assert not out.exists()
    # in a sequence, the block path says which
    code, _, err = _run(capsys, "compile", "-e", f':seq(:bien, :mouthing(:bien, "{word}"))')
    assert code == 2 and err.startswith(f"{ERR}<-e>:1:13: :seq'item:mouthing'word: the word is")


@pytest.mark.parametrize(("word", "code"), [("nul\x00x", "0000"), ("red\x1b[31m", "001B")])
def test_a_mouthed_word_holds_no_control_character(tmp_path, capsys, word, code):
    expr = tmp_path / "m.azee"
    expr.write_text(f':mouthing(:bien, "{word}")\n', encoding="utf-8")
    status, _, err = _run(capsys, "compile", expr, "-o", tmp_path / "m.json")
    assert status == 2
    assert err == (
        f"{ERR}{expr}:1:1: :mouthing'word: the word holds the control character U+{code}; "
        'write the word to mouth in letters, e.g. "maison"\n'
    )
    assert not (tmp_path / "m.json").exists()


def test_a_mouthed_word_at_the_limit_is_mouthed(tmp_path):
    pytest.importorskip("phonemizer", reason="mouthing needs azee_mj[mouthing]")
    from azee_mj import mouthing

    if shutil.which("espeak-ng") is None and shutil.which("espeak") is None:
        pytest.skip("mouthing needs espeak-ng")
    word = ("maison " * 20)[: mouthing.MAX_WORD]
    keys = mouthing.keys(word, "fr", 2.0)
    assert len(keys) > 2 and keys[-1].viseme == "sil"


@pytest.mark.parametrize("value", ["", " ", "\t"])
def test_an_empty_scheduler_is_refused_not_run_here(tmp_path, capsys, value):
    out = tmp_path / "out"
    out.mkdir()
    code, said, err = _run(
        capsys, "realize", GOOD, GOOD.parent / "kinds.json", "-o", f"{out}/", "--scheduler", value
    )
    assert code == 2 and said == ""
    assert err == (
        f"{ERR}--scheduler is empty; give 'local', an address such as tcp://HOST:8786, or a "
        "scheduler file (.json)\n"
    )
    assert list(out.iterdir()) == []
    # one score: the same message (before, '' let it realize here)
    code, _, err = _run(capsys, "realize", GOOD, "-o", tmp_path / "o.npz", "--scheduler", value)
    assert code == 2 and "--scheduler is empty" in err
    assert not (tmp_path / "o.npz").exists()


@pytest.mark.parametrize(
    ("option", "what"),
    [("--manifest", "a file FILE.jsonl or FILE.csv"), ("--report", "a file REPORT.json")],
)
def test_an_empty_output_option_is_refused(tmp_path, capsys, option, what):
    code, _, err = _run(capsys, "realize", GOOD, "-o", tmp_path / "o.npz", option, "")
    assert code == 2 and err.startswith(f"{ERR}{option} is empty; give {what}")
    assert list(tmp_path.iterdir()) == []


def test_open_client_refuses_an_empty_address():
    from azee_mj.cluster import open_client

    with pytest.raises(AzeeError) as e, open_client(""):
        pass
    assert str(e.value).startswith("--scheduler is empty")


# ---------------------------------------------------------------------------------------
# One verdict: realize (with --dynamics too) and check
# ---------------------------------------------------------------------------------------


def test_the_penetration_verdict_does_not_depend_on_the_solvers_margins():
    from azee_mj.check import check_poses
    from azee_mj.model import load_model
    from azee_mj.schedule import make_solver

    solver, model = make_solver(), load_model()
    assert solver.model.geom_margin.max() > 0  # the IK solver's copy has margins
    rng = np.random.default_rng(0)
    q = np.repeat(model.qpos0[None], 200, axis=0)
    for j in np.flatnonzero(model.jnt_limited):
        lo, hi = model.jnt_range[j]
        q[:, model.jnt_qposadr[j]] = rng.uniform(lo, hi, len(q))
    a, b = check_poses(solver.model, q), check_poses(model, q)
    assert len(b.penetrations) > 100  # random postures: many limbs through each other
    np.testing.assert_array_equal(a.max_depth, b.max_depth)
    key = sorted((p.frame, p.depth) for p in a.penetrations)
    assert key == sorted((p.frame, p.depth) for p in b.penetrations)


@pytest.mark.parametrize("dynamics", [True, False])
def test_realize_and_check_say_the_same_findings(tmp_path, capsys, dynamics):
    score = ROOT / "examples" / "armoire.json"
    out = tmp_path / "a.npz"
    mode = ["--dynamics"] if dynamics else []
    code, said, err = _run(capsys, "realize", score, "-o", out, "--fps", "25", *mode, "--strict")
    assert code == 1, err
    code, checked, err = _run(capsys, "check", out, "--score", score)
    assert code == 1, err  # check said nothing of speeds, and exited 0
    said_lines = said.splitlines()[1 : -1 if dynamics else None]  # not the physics line
    checked_lines = checked.splitlines()[2:]
    found = [x for x in said_lines if x.startswith("  finding: ")]
    assert found  # the simulated motion has wrists over the human speed
    assert [x for x in checked_lines if x.startswith("  finding: ")] == found
    assert [x for x in checked_lines if "constraint" in x and x.startswith("  ")] == [
        x for x in said_lines if "constraint" in x and x.startswith("  ")
    ]
    verdict = [x for x in said_lines if not x.startswith("  ")]
    assert checked_lines[: len(verdict)] == verdict


def test_a_dynamic_rollouts_findings_are_those_of_its_own_motion():
    from azee_mj import physics
    from azee_mj.score import load_score
    from azee_mj.timeline import rollout_speed_findings

    score = load_score(ROOT / "examples" / "armoire.json")
    r = physics.realize(score, fps=25)
    speeds = tuple(f for f in r.findings if f.kind == "speed")
    assert speeds and speeds == rollout_speed_findings(score, r)


def test_an_internal_error_in_one_score_never_ends_a_batch(tmp_path, capsys, monkeypatch):
    import azee_mj.batch

    src, out = tmp_path / "src", tmp_path / "out"
    src.mkdir()
    out.mkdir()
    for name in ("buggy.json", "good.json"):
        shutil.copy(GOOD, src / name)
    read = azee_mj.batch.read_score

    def buggy(path, lexicon=()):  # a bug that only this score meets
        if Path(path).name == "buggy.json":
            raise RecursionError("maximum recursion depth exceeded")
        return read(path, lexicon)

    monkeypatch.setattr(azee_mj.batch, "read_score", buggy)
    code, _, err = _run(capsys, "realize", src, "-o", f"{out}/", "--fps", "10", "--jobs", "1")
    assert code == 1
    bad = src / "buggy.json"
    assert f"{ERR}{bad}: internal error (RecursionError: maximum recursion depth exceeded)" in err
    assert err.endswith(f"\nazee-mj: failed: {bad}\n")
    assert [p.name for p in out.iterdir()] == ["good.npz"]


def test_the_limits_page_states_every_limit():
    from azee_mj import errors, files, mouthing, rollout_io, timing
    from azee_mj.azee.syntax import MAX_NESTING
    from azee_mj.export.player import MAX_PLAYER_FRAMES
    from azee_mj.score import validation

    text = (ROOT / "docs" / "limits.md").read_text()
    said = [
        f"{timing.MAX_DURATION:g} s",
        f"{timing.MAX_FRAMES:,}",
        f"from {timing.MIN_FPS:g} to {timing.MAX_FPS:g}",
        f"+-{validation.MAX_NUMBER:.0e}".replace("e+0", "e"),
        f"{validation.MAX_DEPTH} levels",
        f"{MAX_NESTING} levels",
        f"{files.MAX_TEXT_BYTES // 2**20} MB",
        f"{mouthing.MAX_WORD} characters",
        f"{rollout_io.MAX_BYTES / 2**30:.1f} GB",
        f"{MAX_PLAYER_FRAMES:,} frames",
        f"{errors.MAX_SHOWN} characters",
        f"| {errors.MAX_RUN} (",
        f"{errors.MAX_MESSAGE} characters",
        f"| {validation.MAX_LISTED} (",
    ]
    assert [s for s in said if s not in text] == []


@pytest.mark.parametrize(
    ("content", "problem"),
    [
        ("{not json", "not a scheduler file"),
        ("[]", "not a scheduler file"),
        ('{"address": 5}', "not a scheduler file"),
        (None, "not a regular file"),
    ],
)
def test_a_bad_scheduler_file_is_one_clear_line(tmp_path, capsys, content, problem):
    pytest.importorskip("distributed", reason="--scheduler needs azee_mj[cluster]")
    out = tmp_path / "out"
    out.mkdir()
    sched = tmp_path / "s.json"
    if content is None:
        sched.symlink_to("/dev/zero")  # never read
    else:
        sched.write_text(content)
    code, _, err = _run(capsys, "realize", GOOD, "-o", f"{out}/", "--scheduler", sched)
    assert code == 2  # a file that is not JSON was an internal error (AssertionError)
    assert err.startswith(f"{ERR}--scheduler {sched}: {problem}")
    assert err.endswith(
        "; give the file a scheduler wrote (dask scheduler --scheduler-file FILE.json)\n"
    )
    assert list(out.iterdir()) == []


def test_resume_takes_no_row_that_is_not_one(tmp_path, capsys):
    src, out = tmp_path / "src", tmp_path / "out"
    src.mkdir()
    out.mkdir()
    shutil.copy(GOOD, src / "a.json")
    manifest = tmp_path / "m.jsonl"
    argv = ["realize", src, "-o", f"{out}/", "--fps", "10", "--jobs", "1", "--manifest", manifest]
    assert _run(capsys, *argv)[0] == 0
    row = json.loads(manifest.read_text())
    lines = [
        json.dumps(row | {"output": [str(out / "a.npz")]}),  # unhashable: was exit 3
        json.dumps(row | {"findings": {"x": 1}}),
        "[" * 100_000,  # RecursionError in json: was exit 3
        json.dumps(row),
    ]
    manifest.write_text("\n".join(lines) + "\n")
    assert [r["output"] for r in read_manifest(manifest)] == [row["output"]]
    code, _, err = _run(capsys, *argv, "--resume")
    assert code == 0, err
    assert "azee-mj: 1 score: 0 realized, 1 done before (--resume), 0 failed in " in err
    assert read_manifest(manifest) == [row]


def test_a_csv_manifest_the_csv_module_cannot_read_is_one_clear_line(tmp_path, capsys):
    manifest = tmp_path / "m.csv"
    manifest.write_text("input,output\n" + "x" * 300_000 + ",y\n")
    with pytest.raises(AzeeError) as e:
        read_manifest(manifest)
    assert str(e.value) == (
        f"{manifest}: cannot read the manifest (field larger than field limit (131072))"
    )


def test_dynamics_follows_the_tempo_and_rest_options(tmp_path, capsys):
    def frames(*opts) -> tuple[int, str]:
        code, said, err = _run(
            capsys, "realize", GOOD, "-o", tmp_path / "d.npz", "--dynamics", *opts
        )
        assert code == 0, err
        head = said.splitlines()[0]
        return int(head.split(": ")[1].split()[0]), head.split("; ")[-1]

    plain, met = frames()
    assert met == "3/3 constraints within tolerance"
    fast, fast_met = frames("--tempo", "2")  # was ignored: the same frames as plain
    assert fast < plain and fast_met == met  # the simulation follows the score at its tempo
    still, _ = frames("--no-rest")
    assert still < plain


def test_a_rollout_at_another_tempo_is_checked_and_drawn_at_that_tempo(capsys, tmp_path):
    from azee_mj.markers import load_clip
    from azee_mj.rollout_io import recorded_tempo

    score, out = ROOT / "examples" / "armoire.json", tmp_path / "fast.npz"
    code, said, _ = _run(capsys, "realize", score, "-o", out, "--tempo", "2")
    assert code == 0 and "10/10 constraints within tolerance" in said
    assert recorded_tempo(out) == 2.0
    code, said, _ = _run(capsys, "check", out, "--score", score)
    assert "10/10 constraints within tolerance" in said.splitlines()  # was 0/10 at tempo 1
    clip = load_clip(out, score=score)
    assert clip.score.duration == pytest.approx(json.loads(score.read_text())["root"]["end"] / 2)
