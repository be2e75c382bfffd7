"""The azee-mj command line: catalogue, realize, check; exit codes and messages."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from azee_mj import __version__
from azee_mj.cli import main
from azee_mj.sites import DEFAULT_MAP

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
    assert "220 sites" in out and "44 bones" in out and "^ssp -> ssp" in out


def test_realize_writes_a_rollout_and_a_report(tmp_path, capsys):
    out, rep = tmp_path / "good.npz", tmp_path / "good.json"
    assert main(["realize", str(DATA / "good.json"), "-o", str(out), "--fps", "25",
                 "--report", str(rep)]) == 0
    assert "3/3 constraints within tolerance" in capsys.readouterr().out
    with np.load(out, allow_pickle=False) as z:
        assert z["qpos"].shape == (31, 83)
        assert z["time"][-1] == pytest.approx(1.2)
        assert float(z["fps"]) == 25.0
        assert z["site_pos"].shape == (31, len(DEFAULT_MAP.sites), 3)
        assert list(z["site_names"]) == list(DEFAULT_MAP.sites)
    report = json.loads(rep.read_text())
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
    assert err == ("azee-mj: error: GOOD.K1: constraint 1 (place): unknown site '@T_TPI(s)'; "
                   "did you mean '@T_TIP(s)'? (azee-mj sites lists all)\n")
    assert not out.exists()
    assert list(tmp_path.iterdir()) == [tmp_path / "bad.json"]


def test_console_script_prints_no_traceback(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "azee_mj.cli", "realize", str(_bad_score(tmp_path)),
                           "-o", str(tmp_path / "o.npz")], capture_output=True, text=True)
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
    assert main(["realize", str(DATA / "good.json"), "-o", str(tmp_path / "o.npz"), "--fps", "0"]) == 2
    assert capsys.readouterr().err == "azee-mj: error: --fps must be a number from 1 to 1000, got 0\n"
