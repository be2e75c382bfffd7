"""The realization report: HTML with embedded figures, or a PNG set."""

from __future__ import annotations

import base64
import re
from pathlib import Path

import pytest

from azee_mj.cli import main

pytest.importorskip("matplotlib", reason="the report needs matplotlib (azee_mj[plot])")

GOOD = Path(__file__).parent / "data" / "good.json"
PNG = b"\x89PNG\r\n\x1a\n"
BLOCKS = ("GOOD", "GOOD.PERM", "GOOD.K1", "GOOD.T", "GOOD.K2")


def test_html_report_is_self_contained_and_names_the_blocks(tmp_path, capsys):
    out = tmp_path / "report.html"
    assert main(["report", str(GOOD), "-o", str(out)]) == 0
    assert f"{out}: written" in capsys.readouterr().out
    text = out.read_text()
    for name in BLOCKS:
        assert f"<td>{name}</td>" in text
    images = re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', text)
    assert len(images) == 4
    for b64 in images:
        assert base64.b64decode(b64).startswith(PNG)
    assert 'src="http' not in text and "<script" not in text  # nothing fetched
    assert list(tmp_path.iterdir()) == [out]  # no temp file left


def test_png_set(tmp_path):
    d = tmp_path / "figs"
    d.mkdir()
    assert main(["report", str(GOOD), "-o", f"{d}/"]) == 0
    names = sorted(p.name for p in d.iterdir())
    assert names == ["convergence.png", "ik_problems.png", "residuals.png", "timeline.png"]
    for p in d.iterdir():
        assert p.read_bytes().startswith(PNG) and p.stat().st_size > 5000


def test_recorded_problems_match_the_rollout_stats():
    from azee_mj.report import realize_recorded

    r = realize_recorded(GOOD)
    s = r.rollout.stats
    assert len(r.records) == s.problems
    assert [res.iterations for _, res in r.records] == list(s.per_problem_iterations)
    assert all(len(res.history) == res.iterations for _, res in r.records)


def test_bad_output_is_a_clear_error(tmp_path, capsys):
    assert main(["report", str(GOOD), "-o", str(tmp_path / "r.pdf")]) == 2
    err = capsys.readouterr().err
    assert "-o: expected REPORT.html or a directory DIR/" in err
    assert list(tmp_path.iterdir()) == []
