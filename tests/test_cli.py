"""The azee-mj command line: catalogue, realize, check; exit codes and messages."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from azee_mj import __version__
from azee_mj.cli import build_parser, main
from azee_mj.model import load_model
from azee_mj.sites import DEFAULT_MAP
from azee_mj.timing import DEFAULT_FPS

DATA = Path(__file__).parent / "data"


def test_version(capsys):
    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0
    assert capsys.readouterr().out == f"azee-mj {__version__}\n"


def test_sites_json_is_one_object_matching_the_map(capsys):
    assert main(["sites", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out) == {"sites", "bones", "loci", "morphs", "normals", "interior"}
    assert out["normals"]["H_BACK_R"] == [0.0, -1.0, 0.0]
    assert out["interior"] == ["TO", "WR_L", "WR_R"]
    assert out["sites"] == dict(DEFAULT_MAP.sites)
    assert out["loci"] == {"ssp": "ssp", "Rssp": "Rssp", "Lssp": "Lssp"}
    assert out["morphs"] == list(DEFAULT_MAP.morphs)
    assert len(out["bones"]) == 44
    b = DEFAULT_MAP.bones["palm_R"]
    assert out["bones"]["palm_R"] == {"body": b.body, "dir": list(b.dir), "nrm": list(b.nrm)}


def test_sites_text_lists_the_catalogue(capsys):
    assert main(["sites"]) == 0
    out = capsys.readouterr().out
    assert "223 sites" in out and "44 bones" in out and "^ssp -> ssp" in out


def test_realize_writes_a_rollout_and_a_report(tmp_path, capsys):
    out, rep = tmp_path / "good.npz", tmp_path / "good.json"
    assert (
        main(
            [
                "realize",
                str(DATA / "good.json"),
                "-o",
                str(out),
                "--fps",
                "25",
                "--report",
                str(rep),
            ]
        )
        == 0
    )
    assert "3/3 constraints within tolerance" in capsys.readouterr().out
    with np.load(out, allow_pickle=False) as z:
        T, start = len(z["time"]), float(z["score_start"])
        # the lead-in from rest before the score's 1.2 s, the return to rest after
        assert start > 0.0 and z["time"][-1] > start + 1.2
        assert z["qpos"].shape == (T, load_model().nq)
        np.testing.assert_allclose(z["time"], np.arange(T) / 25.0)
        assert float(z["fps"]) == 25.0
        assert z["site_pos"].shape == (T, len(DEFAULT_MAP.sites), 3)
        assert list(z["site_names"]) == list(DEFAULT_MAP.sites)
    report = json.loads(rep.read_text())
    assert report["score_start_s"] == pytest.approx(start)
    assert report["findings"] == []
    assert report["all_within_tolerance"] is True
    assert {c["block"] for c in report["constraints"]} == {"GOOD.K1", "GOOD.K2"}
    assert report["stats"]["ik_problems"] > 0


def _bad_score(tmp_path):
    score = json.loads((DATA / "good.json").read_text())
    score["root"]["children"][1]["constraints"][0]["site"] = "@T_TPI(s)"
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(score))
    return path


def test_bad_score_exits_2_with_one_message_and_no_file(tmp_path, capsys):
    out = tmp_path / "out.npz"
    assert main(["realize", str(_bad_score(tmp_path)), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err == (
        "azee-mj: error: GOOD.K1: constraint 1 (place): unknown site '@T_TPI(s)'; "
        "did you mean '@T_TIP(s)'? (azee-mj sites lists all)\n"
    )
    assert not out.exists()
    assert list(tmp_path.iterdir()) == [tmp_path / "bad.json"]


def test_console_script_prints_no_traceback(tmp_path):
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "azee_mj.cli",
            "realize",
            str(_bad_score(tmp_path)),
            "-o",
            str(tmp_path / "o.npz"),
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert proc.stderr.count("\n") == 1


def test_check_exit_codes(tmp_path, capsys):
    out = tmp_path / "good.npz"
    assert main(["realize", str(DATA / "good.json"), "-o", str(out), "--fps", "25"]) == 0
    assert main(["check", str(out), "--score", str(DATA / "good.json")]) == 0
    text = capsys.readouterr().out
    assert "clean" in text and "3/3 constraints within tolerance" in text
    # A rollout whose right forearm passes through the chest fails the check.
    with np.load(out) as z:
        arrays = {k: z[k] for k in z.files}
    from azee_mj.schedule import make_solver

    s = make_solver()
    for j, v in (("arm_R_flex", 0.3), ("arm_R_abd", -0.5), ("f_arm_R_flex", 0.0)):
        arrays["qpos"][:, s.model.jnt_qposadr[s.joint_id(j)]] = v
    bad = tmp_path / "bad.npz"
    np.savez(bad, **arrays)
    assert main(["check", str(bad)]) == 1
    assert "penetration(s) over the limit" in capsys.readouterr().out
    assert main(["check", str(tmp_path / "missing.npz")]) == 2
    assert capsys.readouterr().err == f"azee-mj: error: {tmp_path / 'missing.npz'}: no such file\n"


def test_realize_rejects_a_bad_fps(tmp_path, capsys):
    assert (
        main(["realize", str(DATA / "good.json"), "-o", str(tmp_path / "o.npz"), "--fps", "0"]) == 2
    )
    assert (
        capsys.readouterr().err == "azee-mj: error: --fps must be a number from 1 to 1000, got 0\n"
    )


def _same_rollout(a, b):
    """The same file byte for byte (rollout files hold no wall-clock times)."""
    assert a.read_bytes() == b.read_bytes()


def _realize(*args) -> int:
    """``azee-mj realize`` with ``args`` (paths and numbers written as text)."""
    return main(["realize", *map(str, args)])


def _dirs(tmp_path, *names):
    out = [tmp_path / n for n in names]
    for d in out:
        d.mkdir()
    return out


def test_realize_many_scores_in_parallel_matches_each_alone(tmp_path, capsys):
    scores = [DATA / "good.json", DATA / "kinds.json"]
    alone, out, reports = _dirs(tmp_path, "alone", "many", "reports")
    for s in scores:
        assert main(["realize", str(s), "-o", str(alone / f"{s.stem}.npz"), "--fps", "25"]) == 0
    capsys.readouterr()
    assert _realize(*scores, "-o", f"{out}/", "--fps", 25, "--jobs", 2, "--report", reports) == 0
    text = capsys.readouterr().out
    assert sorted(p.name for p in out.iterdir()) == ["good.npz", "kinds.npz"]
    for s in scores:
        _same_rollout(alone / f"{s.stem}.npz", out / f"{s.stem}.npz")
        assert f"{out / s.stem}.npz: " in text
    assert "3/3 constraints within tolerance" in text
    report = json.loads((reports / "good.json").read_text())
    assert report["all_within_tolerance"] is True


def test_realize_many_reports_each_bad_score_and_finishes_the_others(tmp_path, capsys):
    bad = _bad_score(tmp_path)
    (out,) = _dirs(tmp_path, "out")
    three = (DATA / "good.json", bad, DATA / "kinds.json")
    assert _realize(*three, "-o", out, "--fps", 25, "--jobs", 2) == 1
    captured = capsys.readouterr()
    first, summary, failed = captured.err.splitlines()
    assert first == (
        f"azee-mj: error: {bad}: GOOD.K1: constraint 1 (place): unknown "
        "site '@T_TPI(s)'; did you mean '@T_TIP(s)'? (azee-mj sites lists "
        "all)"
    )
    # the time taken is the machine's (a loaded one may take over a minute): any is right
    assert re.fullmatch(r"azee-mj: 3 scores: 2 realized, 1 failed in \d+m\d\ds", summary)
    assert failed == f"azee-mj: failed: {bad}"
    assert sorted(p.name for p in out.iterdir()) == ["good.npz", "kinds.npz"]
    assert captured.out.count("constraints within tolerance") == 2


def test_realize_a_directory_of_scores_and_expressions(tmp_path, capsys):
    src, out, empty = _dirs(tmp_path, "scores", "out", "empty")
    for name in ("good.json", "kinds.json"):
        (src / name).write_text((DATA / name).read_text())
    (src / "five.azee").write_text(":nb-5\n")
    (src / "notes.txt").write_text("not a score")
    assert main(["realize", str(src), "-o", str(out), "--fps", "25", "--jobs", "1"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["five.npz", "good.npz", "kinds.npz"]
    for stem, score in (("good", DATA / "good.json"), ("five", src / "five.azee")):
        single = tmp_path / f"{stem}.npz"
        assert main(["realize", str(score), "-o", str(single), "--fps", "25"]) == 0
        _same_rollout(single, out / f"{stem}.npz")
    capsys.readouterr()
    assert main(["realize", str(empty), "-o", str(out)]) == 2
    assert capsys.readouterr().err == (
        f"azee-mj: error: {empty}: no *.json or *.azee scores in this directory\n"
    )


def test_realize_many_compiles_expressions_with_the_lexicon(tmp_path, capsys):
    lex, out = _dirs(tmp_path, "signs", "out")
    (lex / "hello.azee").write_text(":seq(:bien, :nb-5)\n")
    src = tmp_path / "x.azee"
    src.write_text(":hello\n")
    single = tmp_path / "x.npz"
    assert main(["realize", str(src), "-o", str(single), "--fps", "10", "--lexicon", str(lex)]) == 0
    both = (src, DATA / "good.json", "-o", out)
    assert _realize(*both, "--fps", 10, "--lexicon", lex, "--jobs", 2) == 0
    _same_rollout(single, out / "x.npz")
    capsys.readouterr()
    # Without the lexicon the sign is unknown: that expression fails, naming its file.
    assert _realize(*both, "--fps", 10, "--jobs", 1) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"azee-mj: error: {src}:1:1: ") and "hello" in err
    assert err.count("\n") == 3 and err.endswith(f"azee-mj: failed: {src}\n")
    missing = tmp_path / "nope"
    assert _realize(*both, "--lexicon", missing) == 2
    assert capsys.readouterr().err == (
        f"azee-mj: error: {missing}: not a directory of signs (--lexicon)\n"
    )


def test_realize_many_rejects_clashing_names_and_bad_jobs(tmp_path, capsys):
    other = tmp_path / "good.json"
    other.write_text((DATA / "good.json").read_text())
    (out,) = _dirs(tmp_path, "o")
    assert main(["realize", str(DATA / "good.json"), str(other), "-o", str(out)]) == 2
    assert capsys.readouterr().err == (
        f"azee-mj: error: {DATA / 'good.json'} and {other} would "
        f"both write {out / 'good.npz'}; rename one\n"
    )
    assert (
        main(["realize", str(DATA / "good.json"), "-o", str(tmp_path / "o.npz"), "--jobs", "0"])
        == 2
    )
    assert capsys.readouterr().err == "azee-mj: error: --jobs must be at least 1, got 0\n"
    assert list(out.iterdir()) == []


def test_realize_many_follows_the_output_rule_before_any_work(tmp_path, capsys):
    scores = [str(DATA / "good.json"), str(DATA / "kinds.json")]
    src, out = _dirs(tmp_path, "src", "out")
    (src / "good.json").write_text((DATA / "good.json").read_text())
    f = tmp_path / "file.npz"
    f.write_text("x")
    missing = tmp_path / "missing"
    cases = [
        ([*scores, "-o", f"{missing}/"], f"{missing}/: the directory does not exist"),
        ([DATA / "good.json", "-o", f"{missing}/"], f"{missing}/: the directory does not exist"),
        ([*scores, "-o", str(missing)], f"{missing}: the directory does not exist"),
        ([*scores, "-o", str(f)], f"{f}: exists and is not a directory"),
        ([*scores, "-o", f"{f}/"], f"{f}/: exists and is not a directory"),
        (
            [*scores, "-o", str(out), "--report", f"{missing}/"],
            f"{missing}/: the directory does not exist",
        ),
        # a report would replace the input src/good.json
        (
            [src, "-o", str(out), "--report", str(src)],
            f"{src / 'good.json'}: is also an input ({src / 'good.json'}); write to another file",
        ),
    ]
    for argv, message in cases:
        assert main(["realize", *map(str, argv)]) == 2, message
        assert capsys.readouterr().err == f"azee-mj: error: {message}\n"
    (out / "kinds.npz").mkdir()
    assert main(["realize", *scores, "-o", str(out)]) == 2
    assert capsys.readouterr().err == (
        f"azee-mj: error: {out / 'kinds.npz'}: is a directory; give a file name\n"
    )
    assert [p.name for p in out.iterdir()] == ["kinds.npz"]
    assert (src / "good.json").read_text() == (DATA / "good.json").read_text()


def test_realize_one_score_to_a_directory(tmp_path, capsys):
    (out,) = _dirs(tmp_path, "out")
    args = ["realize", str(DATA / "good.json"), "-o", f"{out}/", "--fps", "25", "--no-rest"]
    assert main(args) == 0  # no rest: the score's 1.2 s alone
    assert capsys.readouterr().out.startswith(f"{out / 'good.npz'}: 31 frames at 25 fps, ")
    assert [p.name for p in out.iterdir()] == ["good.npz"]


def test_realize_many_strict_exits_1_on_a_miss_or_a_bad_score(tmp_path, capsys):
    far = tmp_path / "far.json"  # a wrist target 1.2 m in front of the signing space
    far.write_text(
        json.dumps(
            {
                "format": "azee-score",
                "version": 1,
                "root": {
                    "name": "FAR",
                    "kind": "cstr",
                    "start": 0,
                    "end": 0.5,
                    "constraints": [
                        {
                            "type": "place",
                            "site": "@WR(s)",
                            "at": {"translate": "^ssp", "by": [1.2, 0, 0]},
                        }
                    ],
                },
            }
        )
    )
    (out,) = _dirs(tmp_path, "out")
    both = [str(far), str(DATA / "good.json"), "-o", str(out), "--fps", "10", "--jobs", "1"]
    assert main(["realize", *both]) == 0
    assert main(["realize", *both, "--strict"]) == 1
    text = capsys.readouterr().out
    assert "  FAR constraint 1 (place): worst " in text and ": out of reach by " in text
    assert main(["realize", str(_bad_score(tmp_path)), *both]) == 1


def test_every_command_realizing_a_score_defaults_to_timing_default_fps(capsys):
    parser = build_parser()
    for argv in (
        ["realize", "s.json", "-o", "o.npz"],
        ["export", "s.json", "-o", "o.csv"],
        ["report", "s.json", "-o", "r.html"],
    ):
        assert parser.parse_args(argv).fps == DEFAULT_FPS, argv
    for command in ("realize", "export", "report", "preview"):
        with pytest.raises(SystemExit):
            parser.parse_args([command, "--help"])
        assert f"(default {DEFAULT_FPS:g})" in " ".join(capsys.readouterr().out.split()), command
