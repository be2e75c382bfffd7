"""Fuzzing ``azee-mj realize`` with mutated scores: zero tracebacks, hangs and NaN outputs.

    python bench/fuzz.py [--count 1000] [--seed 0] [--fps 10]

A seeded mutator (:func:`mutants`) changes the bundled examples: values replaced by hostile
ones (huge, tiny, negative, non-finite, wrong types, control characters, 100 KB strings,
unknown names), keys deleted, blocks duplicated, times shifted, nesting made deep, and the
JSON text itself truncated, flipped or given giant integers. Each mutant goes through the
real command line in this process (:func:`run_one`); an outcome is ``ok`` (exit 0 and a
finite rollout that loads back), ``rejected`` (exit 2, one message line), or a failure:
``internal`` (exit 3 or any other status / a traceback), ``nan`` (a non-finite output) or
``hang`` (over ``--timeout`` seconds). Then ``--rollouts`` damaged rollout files
(:func:`rollout_mutants`: arrays deleted, reshaped, retyped, made NaN / infinite; bytes
truncated or flipped) go through ``azee-mj check --score`` (:func:`check_one`): exit 0 / 1,
or 2 with one line.

Then hostile names (:func:`hostile_names`: markup, template placeholders, mathtext,
bidirectional and control characters, huge) go into ``--pages`` web player pages
(:func:`page_one`: the names come back as data, the page structure is the template's;
with Chromium, the page loads, the player runs and shows them, nothing injected runs, no
element is added; a browser shows control characters in the title as it likes)
and ``--reports`` reports (:func:`report_one`: exit 0, every name HTML-escaped in the
page), and ``.azee`` expressions nested 1 to 2,000 deep in parentheses or layout go
through ``azee-mj compile`` (:func:`depth_one`: exit 0 or 2 with one line, never a
``RecursionError``). Then ``--manifests`` batch manifests with hostile values and lines
(:func:`manifest_one`) are read and written back as ``--resume`` does. Writes
bench/results/fuzz.json.
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import io
import json
import random
import signal
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = sorted((ROOT / "examples").glob("*.json"))

HOSTILE = [
    0,
    -1,
    1,
    2.5,
    1e-12,
    -1e-12,
    1e6,
    1e7,
    1e308,
    -1e308,
    3600,
    4000,
    0.1,
    None,
    True,
    False,
    "",
    "x",
    "@NOPE(s)",
    "@I_TIP(s)",
    "^ssp",
    "!head",
    "fwd",
    "nan",
    "lat(q)",
    "\x1b[31mred\x1b[0m",
    "a\nb",
    "\u202eevil",
    "A" * 100_000,
    [],
    {},
    [0, 0, 0],
    [1e308, 0, 0],
    [0, 0],
    {"translate": "@FH", "by": "up"},
    {"unit": [0, 0, 0]},
]


class Hang(Exception):
    pass


def _paths(v, path=()):
    """Every (container, key) path in a JSON value."""
    out = []
    if isinstance(v, dict):
        for k, x in v.items():
            out.append(path + (k,))
            out += _paths(x, path + (k,))
    elif isinstance(v, list):
        for i, x in enumerate(v):
            out.append(path + (i,))
            out += _paths(x, path + (i,))
    return out


def _get(v, path):
    for k in path:
        v = v[k]
    return v


def _deep(depth: int, leaf):
    v = leaf
    for _ in range(depth):
        v = {"unit": v}
    return v


def mutate(data: dict, rng: random.Random) -> dict | str:
    """One mutant of a score: a JSON object, or (for text mutations) JSON text."""
    d = copy.deepcopy(data)
    kind = rng.random()
    paths = _paths(d)
    p = rng.choice(paths)
    parent, key = _get(d, p[:-1]), p[-1]
    if kind < 0.45:  # a hostile value
        parent[key] = copy.deepcopy(rng.choice(HOSTILE))
    elif kind < 0.55:  # a key or item removed
        del parent[key]
    elif kind < 0.62:  # a number scaled or shifted by a multiple of 0.1 s
        nums = [
            q
            for q in paths
            if isinstance(_get(d, q), (int, float)) and not isinstance(_get(d, q), bool)
        ]
        if nums:
            q = rng.choice(nums)
            par = _get(d, q[:-1])
            par[q[-1]] = rng.choice(
                [
                    par[q[-1]] * rng.choice([-1, 0.5, 2, 1000]),
                    par[q[-1]] + 0.1 * rng.randint(-30, 30),
                ]
            )
    elif kind < 0.68:  # a block duplicated (same name twice, or renamed)
        blocks = [
            q
            for q in paths
            if isinstance(_get(d, q), dict)
            and "kind" in _get(d, q)
            and isinstance(_get(d, q[:-1]), list)
        ]
        if blocks:
            q = rng.choice(blocks)
            lst = _get(d, q[:-1])
            b = copy.deepcopy(lst[q[-1]])
            if rng.random() < 0.5:
                b["name"] = str(b.get("name")) + "_2"
            lst.append(b)
    elif kind < 0.74:  # deep nesting of blocks or expressions
        depth = rng.choice([50, 120])  # deeper: the text mutations
        if rng.random() < 0.5:
            parent[key] = _deep(depth, "up")
        else:
            b = {"name": "K", "kind": "cstr", "start": 0, "end": 1, "constraints": []}
            for i in range(depth):
                b = {"name": f"N{i}", "kind": "sync", "start": 0, "end": 1, "children": [b]}
            d["root"] = b
    elif kind < 0.80:  # a name with control characters or huge
        for q in paths:
            if q[-1] == "name" and rng.random() < 0.3:
                _get(d, q[:-1])["name"] = rng.choice(["a\nb\x1b[2J", "N" * 100_000, "\x00", "é"])
    else:  # the text itself
        text = json.dumps(d)
        r = rng.random()
        if r < 0.3:
            return text[: rng.randrange(len(text))]
        if r < 0.55:
            i = rng.randrange(len(text))
            return text[:i] + chr(rng.randrange(1, 256)) + text[i + 1 :]
        if r < 0.8:
            return text.replace(
                '"end": ', '"end": ' + "9" * rng.choice([20, 400, 5000]) + "+0*", 1
            ).replace("+0*", "", 1)
        if r < 0.9:  # an expression nested thousands deep
            n = rng.choice([600, 3000, 50_000])
            return text.replace('"up"', '{"unit": ' * n + '"up"' + "}" * n, 1)
        return "[" * rng.choice([100, 1000, 100_000]) + "]" * rng.choice([0, 100])
    return d


def mutants(count: int, seed: int = 0):
    """``count`` (label, mutant) pairs from the examples, the same for the same seed."""
    rng = random.Random(seed)
    bases = [(p.stem, json.loads(p.read_text())) for p in EXAMPLES]
    for i in range(count):
        name, data = bases[i % len(bases)]
        m = mutate(data, rng)
        if rng.random() < 0.25:  # sometimes two mutations
            try:
                m = mutate(m, rng) if isinstance(m, dict) else m
            except RecursionError:  # too deep to copy: keep the first mutation
                pass
        yield f"{name}#{i}", m


def run_one(mutant, tmp: Path, fps: float = 10.0, timeout: float = 60.0) -> tuple[str, str]:
    """(outcome, detail) of ``azee-mj realize`` on one mutant (see the module docstring)."""
    import numpy as np

    from azee_mj.cli import main
    from azee_mj.model import load_model
    from azee_mj.rollout_io import load_rollout

    src = tmp / "mutant.json"
    src.write_text(mutant if isinstance(mutant, str) else json.dumps(mutant))
    out = tmp / "out.npz"
    out.unlink(missing_ok=True)
    err = io.StringIO()

    def on_alarm(signum, frame):
        raise Hang()

    old = signal.signal(signal.SIGALRM, on_alarm)
    signal.setitimer(signal.ITIMER_REAL, timeout)
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            code = main(["realize", str(src), "-o", str(out), "--fps", str(fps)])
    except Hang:
        return "hang", f"over {timeout} s"
    except BaseException as e:  # noqa: BLE001 - anything escaping main() is a failure
        return "internal", f"{type(e).__name__}: {e}"[:300]
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
    msg = err.getvalue()
    if code == 2:
        ok = msg.startswith("azee-mj: error: ") and msg.count("\n") == 1 and not out.exists()
        return ("rejected", msg.strip()[:300]) if ok else ("internal", f"bad message {msg!r}"[:300])
    if code != 0:
        return "internal", msg.strip()[:300]
    r = load_rollout(out, load_model().nq)  # validates shapes and finite postures
    if not (np.isfinite(r.qpos).all() and np.isfinite(r.site_pos).all()):
        return "nan", "non-finite output"
    return "ok", f"{len(r.time)} frames"


def mutate_rollout(arrays: dict, rng: random.Random) -> dict | bytes:
    """One mutant of a rollout file's arrays (a dict to save), or damaged file bytes."""
    import numpy as np

    a = dict(arrays)
    r = rng.random()
    k = rng.choice(sorted(a))
    if r < 0.15:
        del a[k]
    elif r < 0.45:  # another value: wrong shape, dtype, or non-finite numbers
        v = a[k] if a[k].ndim else a[k].reshape(1)
        a[k] = rng.choice(
            [
                np.array(np.nan),
                np.array("text"),
                np.zeros((0,)),
                np.zeros((2, 2, 2, 2)),
                np.arange(3),
                np.array([1e308, -1e308]),
                np.array(["x#y", "#", "a#99999999999"]),
                np.full(v.shape, np.nan) if v.dtype.kind == "f" else v[:0],
                np.full(v.shape, np.inf) if v.dtype.kind == "f" else v[::-1],
                v.astype(np.float32) if v.dtype.kind == "f" else v.astype("U1"),
                v.reshape(-1),
                v[: max(0, len(v) - 1)],
            ]
        )
    elif r < 0.6:  # one value spoiled inside a numeric array
        v = a[k]
        if v.dtype.kind == "f" and v.size:
            v = v.copy()
            v.flat[rng.randrange(v.size)] = rng.choice([np.nan, np.inf, -1e308, 1e308])
            a[k] = v
    else:  # the file's bytes
        import io

        buf = io.BytesIO()
        np.savez_compressed(buf, **a)
        data = bytearray(buf.getvalue())
        if r < 0.75:
            return bytes(data[: rng.randrange(len(data))])
        for _ in range(rng.randint(1, 20)):
            data[rng.randrange(len(data))] = rng.randrange(256)
        return bytes(data)
    return a


def rollout_mutants(count: int, seed: int = 0):
    """``count`` (label, mutant) pairs from the rollout of tests/data/good.json."""
    from azee_mj.rollout_io import rollout_arrays
    from azee_mj.timeline import realize

    rng = random.Random(seed)
    base = rollout_arrays(realize(ROOT / "tests" / "data" / "good.json", fps=10))
    for i in range(count):
        yield f"rollout#{i}", mutate_rollout(base, rng)


def check_one(mutant, tmp: Path) -> tuple[str, str]:
    """(outcome, detail) of ``azee-mj check`` on one damaged rollout: ``ok`` (exit 0 or 1),
    ``rejected`` (exit 2, one line) or ``internal``."""
    import numpy as np

    from azee_mj.cli import main

    path = tmp / "mutant.npz"
    if isinstance(mutant, bytes):
        path.write_bytes(mutant)
    else:
        with open(path, "wb") as f:
            np.savez(f, **mutant)
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            code = main(["check", str(path), "--score", str(ROOT / "tests" / "data" / "good.json")])
    except BaseException as e:  # noqa: BLE001 - anything escaping main() is a failure
        return "internal", f"{type(e).__name__}: {e}"[:300]
    msg = err.getvalue()
    if code in (0, 1):
        return "ok", f"exit {code}"
    if code == 2 and msg.startswith("azee-mj: error: ") and msg.count("\n") == 1:
        return "rejected", msg.strip()[:300]
    return "internal", msg.strip()[:300]


#: Pieces of hostile names: markup, template placeholders, mathtext, bidirectional and
#: control characters, and text a player or a report must show as it is.
NAME_PIECES = [
    "<!--",
    "-->",
    "<script>",
    "</script>",
    "</SCRIPT >",
    "<script>window.pwned=1</script>",
    "<img src=x onerror=window.pwned=2>",
    "]]>",
    "&amp;",
    "&#60;",
    "\\u003c",
    "@GLB@",
    "@THREE@",
    "@INFO@",
    "@TITLE@",
    "$",
    "$$",
    "\\frac{",
    "$x_$",
    "COST_$5_$10",
    "^",
    "_",
    "{",
    "}",
    "\u202e",
    "\u2066",
    "\u200f",
    "\u2028",
    "\x00",
    "\x1b[2J",
    "\x07",
    "\r",
    "\n",
    "\t",
    "\ufeff",
    "e\u0301",
    "\U0001f600",
    "\\",
    '"',
    "'",
    "`${x}`",
    "ok",
]


def hostile_names(count: int, seed: int = 0) -> list[str]:
    """``count`` names, each 1 to 6 pieces of :data:`NAME_PIECES` (sometimes one 10,000
    characters long); never empty, never a '.' (block paths join names with it)."""
    rng = random.Random(seed)
    out = []
    for _ in range(count):
        name = "".join(rng.choice(NAME_PIECES) for _ in range(rng.randint(1, 6)))
        if rng.random() < 0.05:
            name = name * (10_000 // len(name) + 1)
        out.append(name.replace(".", "_"))
    return out


def page_one(names: list[str], tmp: Path, browser=None) -> tuple[str, str]:
    """(outcome, detail) of a web player page whose schedule, track names and title are
    ``names``: ``ok`` when the names come back as data, the page holds the template's
    four scripts, and (with ``browser``) it loads, runs and shows the names with nothing
    injected run; else ``broken`` or ``injected``."""
    import re

    import numpy as np

    from azee_mj.export import Motion, write
    from azee_mj.model import load_model

    model = load_model()
    q = np.repeat(model.qpos0[None], 11, axis=0)
    sched = {"hands": tuple((n, 0.0, 1.0) for n in names)}
    title = names[0]
    page = write(tmp / "page.html", Motion(q, 10.0, sched, title), model=model)
    text = page.read_text()
    if text.count("<script") != 4 or text.count("</script") != 4:
        return "injected", "the page's scripts are not the template's four"
    m = re.search(r'<script type="application/json" id="azee-info">(.*?)</script>', text, re.DOTALL)
    info = json.loads(m.group(1))
    if [b for b, _, _ in info["schedule"]["hands"]] != names or info["title"] != title:
        return "broken", "the names did not come back as data"
    if browser is None:
        return "ok", "page text"
    browser.events.clear()
    ready = "window.azeePlayer && (azeePlayer.ready || azeePlayer.error)"
    browser.open(page.resolve().as_uri() + "?t=0.5&paused=1", ready, timeout=60)
    if browser.evaluate("window.pwned !== undefined"):
        return "injected", "an injected script ran"
    if not browser.evaluate("azeePlayer.ready") or browser.errors():
        return "broken", f"player not ready: {browser.errors()[:1]}"[:300]
    if browser.evaluate("azeePlayer.activeBlocks()") != "hands   " + ", ".join(names):
        return "broken", "the blocks shown are not the names"
    structure = (
        "[document.scripts.length, document.getElementsByTagName('title').length,"
        " document.getElementById('title').children.length,"
        " document.getElementById('blocks').children.length]"
    )
    if browser.evaluate(structure) != [4, 1, 0, 0]:
        return "injected", "the page's elements are not the template's"
    return "ok", "page in chromium"


def report_one(names: list[str], tmp: Path) -> tuple[str, str]:
    """(outcome, detail) of ``azee-mj report`` on tests/data/good.json with its blocks
    renamed ``names``: ``ok`` (exit 0, every name HTML-escaped in the page), ``rejected``
    (exit 2, one line) or ``internal``."""
    import html

    from azee_mj.cli import main

    data = json.loads((ROOT / "tests" / "data" / "good.json").read_text())
    kids = data["root"]["children"]
    for kid, name in zip(kids, names):
        kid["name"] = name
    data["root"]["name"] = names[-1]
    src, out = tmp / "named.json", tmp / "report.html"
    src.write_text(json.dumps(data))
    out.unlink(missing_ok=True)
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            code = main(["report", str(src), "-o", str(out), "--fps", "10"])
    except BaseException as e:  # noqa: BLE001 - anything escaping main() is a failure
        return "internal", f"{type(e).__name__}: {e}"[:300]
    msg = err.getvalue()
    if code == 2 and msg.startswith("azee-mj: error: ") and msg.count("\n") == 1:
        return "rejected", msg.strip()[:300]
    if code != 0:
        return "internal", msg.strip()[:300]
    with open(out, encoding="utf-8", newline="") as f:  # as written: "\r" kept
        text = f.read()
    used = [k["name"] for k in kids] + [data["root"]["name"]]
    shown = all(html.escape(n) in text for n in used)
    return ("ok", "report") if shown else ("broken", "a name is missing from the page")


def depth_one(depth: int, layout: bool, tmp: Path) -> tuple[str, str]:
    """(outcome, detail) of ``azee-mj compile`` on ``:seq`` nested ``depth`` deep in
    parentheses or layout: ``ok`` (exit 0), ``rejected`` (exit 2, one line) or
    ``internal``."""
    from azee_mj.cli import main

    if layout:
        text = "".join(" " * i + ":seq\n" for i in range(depth)) + " " * depth + ":bien\n"
    else:
        text = ":seq(" * depth + ":bien" + ")" * depth
    src = tmp / "deep.azee"
    src.write_text(text)
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            code = main(["compile", str(src)])
    except BaseException as e:  # noqa: BLE001 - anything escaping main() is a failure
        return "internal", f"{type(e).__name__}: {e}"[:300]
    msg = err.getvalue()
    if code == 0:
        return "ok", f"depth {depth}"
    if code == 2 and msg.startswith("azee-mj: error: ") and msg.count("\n") == 1:
        return "rejected", msg.strip()[:300]
    return "internal", msg.strip()[:300]


def _browser():
    """A headless Chromium (tests/headless_chromium.py), or None where there is none."""
    sys.path.insert(0, str(ROOT / "tests"))
    from headless_chromium import Chromium, find_chromium

    exe = find_chromium()
    return Chromium(exe, size=(480, 360)) if exe else None


def names_round(pages: int, reports: int, seed: int, tmp: Path) -> tuple[Counter, list]:
    """Hostile names through ``pages`` player pages (in Chromium when there is one),
    ``reports`` reports and nesting depths 1 to 2,000: outcomes and failures."""
    outcomes: Counter = Counter()
    failures = []
    rng = random.Random(seed)
    browser = _browser() if pages else None
    try:
        runs = [("page", k) for k in range(pages)] + [("report", k) for k in range(reports)]
        for what, k in runs:
            names = hostile_names(
                rng.randint(1, 8), seed * 1000 + k + (500 if what == "report" else 0)
            )
            if what == "page":
                outcome, detail = page_one(names, tmp, browser)
            else:
                outcome, detail = report_one(names, tmp)
            outcomes[f"{what}:{outcome}"] += 1
            if outcome not in ("ok", "rejected"):
                failures.append(
                    {"mutant": f"{what}#{k} {names!r}"[:300], "outcome": outcome, "detail": detail}
                )
    finally:
        if browser is not None:
            browser.close()
    for depth in (1, 2, 10, 63, 64, 65, 100, 600, 2000):
        for layout in (False, True):
            outcome, detail = depth_one(depth, layout, tmp)
            outcomes[f"depth:{outcome}"] += 1
            # shallow nesting compiles; past the limit (64) it is one clean message
            expected = "ok" if depth <= 10 else "rejected" if depth > 64 else outcome
            if outcome not in ("ok", "rejected") or outcome != expected:
                failures.append(
                    {
                        "mutant": f"depth {depth} layout={layout}",
                        "outcome": outcome,
                        "detail": detail,
                    }
                )
    return outcomes, failures


#: A manifest row's fields and the kinds of values a hostile manifest gives them.
_MANIFEST_VALUES = [
    *HOSTILE,
    '=HYPERLINK("http://x")',
    "+1",
    "-1",
    "@SUM(A1)",
    "'=x",
    "\x9b2J",
    "\x00",
    [["nested"]],
    {"a": {"b": 1}},
]


def manifest_one(rng: random.Random, tmp: Path) -> tuple[str, str]:
    """A manifest (JSON Lines or CSV) of good rows with hostile values and hostile lines
    (brackets 100,000 deep, binary, half a row) through :func:`~azee_mj.corpus.read_manifest`
    and back through :class:`~azee_mj.corpus.Manifest` (what ``--resume`` does): ``ok`` when
    every row read is a dict of scalars and the file written holds no raw control character
    and no cell a spreadsheet runs, ``rejected`` for one clean error, else ``internal``."""
    import csv as _csv

    from azee_mj.corpus import FIELDS, Manifest, read_manifest
    from azee_mj.errors import AzeeError

    suffix = rng.choice([".jsonl", ".csv"])
    path = tmp / f"fuzz{suffix}"
    rows = []
    for _ in range(rng.randint(1, 5)):
        r = {k: rng.choice(_MANIFEST_VALUES) for k in rng.sample(FIELDS, rng.randint(1, 4))}
        rows.append({"input": "a.json", "output": "a.npz", "status": "done"} | r)
    if suffix == ".jsonl":
        lines = [json.dumps(r) for r in rows]
        lines.insert(rng.randrange(len(lines) + 1), rng.choice(["[" * 100_000, "\x00\xff", "{"]))
        path.write_text("\n".join(lines) + "\n", encoding="utf-8", errors="surrogateescape")
    else:
        buf = io.StringIO()
        w = _csv.writer(buf, lineterminator="\n")
        w.writerow(FIELDS)
        for r in rows:
            w.writerow([str(r.get(k, "")) for k in FIELDS])
        path.write_text(buf.getvalue())
    try:
        got = read_manifest(path)
        bad = [
            r
            for r in got
            if not all(v is None or isinstance(v, str | int | float) for v in r.values())
        ]
        if bad:
            return "internal", f"a row that is not one: {bad[0]!r}"[:300]
        out = tmp / f"again{suffix}"
        with Manifest(out, got):
            pass
        text = out.read_text(encoding="utf-8")
    except AzeeError as e:
        return "rejected", str(e)[:200]
    except Exception as e:  # noqa: BLE001 - the finding
        return "internal", f"{type(e).__name__}: {e}"[:300]
    raw = [c for c in "\x00\x1b\x9b\u202e" if c in text]
    if raw:
        return "internal", f"raw control characters {raw!r} written"
    if suffix == ".csv":
        cells = [c for row in _csv.reader(io.StringIO(text)) for c in row]
        runs = [c for c in cells if c[:1] in ("=", "+", "-", "@")]
        if runs:
            return "internal", f"a cell a spreadsheet runs: {runs[0][:80]!r}"
    return "ok", ""


def manifests_round(count: int, seed: int, tmp: Path) -> tuple[Counter, list]:
    """``count`` hostile manifests through :func:`manifest_one`: outcomes and failures."""
    rng = random.Random(seed)
    outcomes: Counter = Counter()
    failures = []
    for k in range(count):
        outcome, detail = manifest_one(rng, tmp)
        outcomes[outcome] += 1
        if outcome not in ("ok", "rejected"):
            failures.append({"mutant": f"manifest#{k}", "outcome": outcome, "detail": detail})
    return outcomes, failures


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--count", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--fps", type=float, default=10.0)
    ap.add_argument("--timeout", type=float, default=60.0)
    ap.add_argument("--rollouts", type=int, default=300, help="damaged rollouts for check")
    ap.add_argument("--pages", type=int, default=100, help="player pages with hostile names")
    ap.add_argument("--reports", type=int, default=20, help="reports with hostile names")
    ap.add_argument("--manifests", type=int, default=300, help="hostile batch manifests")
    args = ap.parse_args()
    sys.setrecursionlimit(1000)  # the default: deep input must not need more
    counts: Counter = Counter()
    failures = []
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as d:
        for label, m in mutants(args.count, args.seed):
            outcome, detail = run_one(m, Path(d), args.fps, args.timeout)
            counts[outcome] += 1
            if outcome not in ("ok", "rejected"):
                failures.append({"mutant": label, "outcome": outcome, "detail": detail})
                print(f"{label}: {outcome}: {detail}", flush=True)
        checks: Counter = Counter()
        for label, m in rollout_mutants(args.rollouts, args.seed):
            outcome, detail = check_one(m, Path(d))
            checks[outcome] += 1
            if outcome != "ok" and outcome != "rejected":
                failures.append({"mutant": label, "outcome": outcome, "detail": detail})
                print(f"{label}: {outcome}: {detail}", flush=True)
        names, bad = names_round(args.pages, args.reports, args.seed, Path(d))
        for f in bad:
            print(f"{f['mutant']}: {f['outcome']}: {f['detail']}", flush=True)
        failures += bad
        sheets, bad = manifests_round(args.manifests, args.seed, Path(d))
        for f in bad:
            print(f"{f['mutant']}: {f['outcome']}: {f['detail']}", flush=True)
        failures += bad
    wall = time.perf_counter() - t0
    summary = {
        "count": args.count,
        "seed": args.seed,
        "fps": args.fps,
        "outcomes": dict(counts),
        "rollouts": args.rollouts,
        "check_outcomes": dict(checks),
        "pages": args.pages,
        "reports": args.reports,
        "names_outcomes": dict(names),
        "manifests": args.manifests,
        "manifest_outcomes": dict(sheets),
        "failures": failures,
        "wall_s": wall,
    }
    res = ROOT / "bench" / "results"
    res.mkdir(exist_ok=True)
    (res / "fuzz.json").write_text(json.dumps(summary, indent=1) + "\n")
    print(
        f"{args.count} scores and {args.rollouts} rollouts in {wall:.0f} s: {dict(counts)}; "
        f"check: {dict(checks)}; names and depths: {dict(names)}; manifests: {dict(sheets)}"
    )
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
