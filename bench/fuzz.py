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
or 2 with one line. Writes bench/results/fuzz.json.
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


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--count", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--fps", type=float, default=10.0)
    ap.add_argument("--timeout", type=float, default=60.0)
    ap.add_argument("--rollouts", type=int, default=300, help="damaged rollouts for check")
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
    wall = time.perf_counter() - t0
    summary = {
        "count": args.count,
        "seed": args.seed,
        "fps": args.fps,
        "outcomes": dict(counts),
        "rollouts": args.rollouts,
        "check_outcomes": dict(checks),
        "failures": failures,
        "wall_s": wall,
    }
    res = ROOT / "bench" / "results"
    res.mkdir(exist_ok=True)
    (res / "fuzz.json").write_text(json.dumps(summary, indent=1) + "\n")
    print(
        f"{args.count} scores and {args.rollouts} rollouts in {wall:.0f} s: {dict(counts)}; "
        f"check: {dict(checks)}"
    )
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
