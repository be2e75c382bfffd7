"""Hostile names in the web player and the report (issue 27): names are text, never markup,
never a template placeholder, never mathtext; the page loads, the player runs, nothing
injected runs."""

from __future__ import annotations

import html
import json
import re
import sys
from pathlib import Path

import numpy as np
import pytest
from headless_chromium import READY, launched

from azee_mj.cli import main
from azee_mj.errors import AzeeError, InputFileError
from azee_mj.model import load_model
from azee_mj.rollout_io import load_rollout, rollout_arrays
from azee_mj.score import load_score
from azee_mj.timeline import realize

sys.path.insert(0, str(Path(__file__).parent))

GOOD = Path(__file__).parent / "data" / "good.json"

#: Names that were markup, placeholders, mathtext, or that drive a terminal or the text's
#: direction (``window.pwned`` is set only if an injected script runs).
NAMES = (
    "<!--<script>",
    "</script><script>window.pwned=1</script>",
    "<img src=x onerror='window.pwned=2'>",
    "@GLB@",
    "@THREE@",
    "@INFO@",
    "@TITLE@",
    "]]><!--",
    "$\\frac{$",
    "COST_$5_$10",
    "$$",
    "$x_$",
    "\u202eevil\u2066x",
    "a\x00b\x1b[2J\x07",
    "&amp;&lt;",
)
TITLE = "</title><script>window.pwned=3</script>@GLB@<!--"


@pytest.fixture(scope="module")
def model():
    return load_model()


def _motion(model, names):
    from azee_mj.export import Motion

    qpos = np.repeat(model.qpos0[None], 11, axis=0)  # 1 s at 10 fps
    sched = {"hands": tuple((n, 0.1 * i / len(names), 1.0) for i, n in enumerate(names))}
    return Motion(qpos, 10.0, sched, TITLE)


def _info(text: str) -> dict:
    m = re.search(r'<script type="application/json" id="azee-info">(.*?)</script>', text, re.DOTALL)
    return json.loads(m.group(1))


def test_the_page_holds_every_name_as_data(model, tmp_path):
    pytest.importorskip("pygltflib", reason="the player needs azee_mj[export]")
    from azee_mj.export import write

    page = write(tmp_path / "p.html", _motion(model, NAMES), model=model)
    text = page.read_text()
    # the structure is the template's: one of each script, the info first
    assert text.count("<script") == 4 and text.count("</script") == 4
    assert "<!--" not in text.split("<script>", 1)[0].split("<title>", 1)[1]
    info = _info(text)
    assert [b for b, _, _ in info["schedule"]["hands"]] == list(NAMES)
    assert info["title"] == TITLE
    assert text.count(f"<title>{html.escape(TITLE)}</title>") == 1
    three = (
        Path(__file__).resolve().parent.parent / "azee_mj/export/vendor/three.min.js"
    ).read_text()
    assert text.count(three) == 1  # three.js once, only where the template puts it


def test_non_finite_block_times_are_refused(model, tmp_path):
    pytest.importorskip("pygltflib", reason="the player needs azee_mj[export]")
    from azee_mj.export import Motion, write

    for bad in (float("nan"), float("inf")):
        m = Motion(np.repeat(model.qpos0[None], 3, axis=0), 10.0, {"hands": (("B", 0.0, bad),)})
        with pytest.raises(AzeeError) as e:
            write(tmp_path / "p.html", m, model=model)
        assert str(e.value) == "schedule: block 'B' on track hands: times must be finite"
        assert list(tmp_path.iterdir()) == []
    r = realize(load_score(GOOD), fps=10)
    arrays = rollout_arrays(r)
    arrays["schedule_span"][0, 1] = np.nan
    path = tmp_path / "r.npz"
    np.savez(path, **arrays)
    with pytest.raises(InputFileError) as e:
        load_rollout(path, model.nq)
    assert str(e.value) == f"{path}: schedule_span must hold finite times"


@pytest.fixture(scope="module")
def browser():
    yield from launched((480, 360))


def test_the_player_runs_and_nothing_injected_runs(model, tmp_path, browser):
    pytest.importorskip("pygltflib", reason="the player needs azee_mj[export]")
    from azee_mj.export import write

    page = write(tmp_path / "p.html", _motion(model, NAMES), model=model)
    browser.events.clear()
    browser.open(page.resolve().as_uri() + "?t=0.95&paused=1", READY)
    assert browser.evaluate("window.pwned === undefined") is True
    assert browser.evaluate("document.title") == TITLE
    shown = browser.evaluate("azeePlayer.activeBlocks()")
    assert shown == "hands   " + ", ".join(NAMES)
    assert browser.evaluate("document.getElementById('blocks').textContent") == shown
    browser.evaluate("azeePlayer.play()")
    browser.open_wait("azeePlayer.time() < 0.9")  # it runs: looped past the end
    assert browser.errors() == []


def test_report_names_are_text_not_mathtext(tmp_path, capsys):
    pytest.importorskip("matplotlib", reason="the report needs matplotlib (azee_mj[plot])")
    data = json.loads(GOOD.read_text())
    kids = data["root"]["children"]
    for kid, name in zip(kids, ("$\\frac{$", "COST_$5_$10", "$$", "$x_$")):
        kid["name"] = name
    data["root"]["name"] = "$\\sqrt{$"
    score = tmp_path / "s.json"
    score.write_text(json.dumps(data))
    out = tmp_path / "r.html"
    assert main(["report", str(score), "-o", str(out)]) == 0, capsys.readouterr().err
    text = out.read_text()
    assert "<td>$\\sqrt{$.COST_$5_$10</td>" in text


def test_a_report_directory_must_exist_as_for_realize(tmp_path, capsys):
    pytest.importorskip("matplotlib", reason="the report needs matplotlib (azee_mj[plot])")
    d = tmp_path / "missing"
    for argv in (("realize", GOOD), ("report", GOOD)):
        assert main([*map(str, argv), "-o", f"{d}/"]) == 2
        assert capsys.readouterr().err == f"azee-mj: error: {d}/: the directory does not exist\n"
    assert not d.exists()
