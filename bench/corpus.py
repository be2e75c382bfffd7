"""A generated corpus: N seeded scores, realized by the process pool and by Dask.

    python bench/corpus.py [--n 1000] [--seed 0] [--configs pool-1 pool-2 dask-1 dask-2]
    python bench/corpus.py --write-only DIR --n 50     # only write the .azee scores

Each score is an AZee expression (``.azee``) composed at random from the bundled lexicon and
the rule catalogue: 1 to 12 signs, each sign possibly placed at a locus, put together by the
rules whose arguments are scores (``:seq``, ``:info-about``, ``:side-by-side``, ...), as
deep as the count allows. The same seed gives the same corpus. Every configuration
realizes the whole corpus at 50 fps with :func:`azee_mj.batch.realize_many` (outputs
written, then deleted): ``pool-1`` in this process, ``pool-2`` a pool of two worker
processes, ``dask-W`` a Dask ``LocalCluster`` of W one-thread worker processes (started
once, its start timed apart). The corpus is cut into ``--rounds`` slices and every
configuration realizes a slice in turn, so that other work on a shared machine weighs on
all configurations alike. Reports scores per second, per core, and the Dask overhead per score; writes
bench/results/corpus.json. Targets (issue 25): Dask's throughput per core within 10 % of
the pool's; two workers >= 1.8x one.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import random
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from machine import cpu as cpu_model

from azee_mj.azee import RULES, Lexicon
from azee_mj.batch import plan, realize_many, usable_cores

LOCI = ("^ssp", "^Rssp", "^Lssp")


class Composer:
    """Random AZee expressions over the bundled lexicon and the implemented rules."""

    def __init__(self, seed: int):
        self.rng = random.Random(seed)
        lex = Lexicon(())
        self.signs = [(n, [p.kind for p in lex.get(n).params]) for n in lex.names()]
        rules = [r for r in RULES if "not implemented" not in r.summary]
        self.unary, self.fixed, self.lists, self.digits = [], [], [], []
        for r in rules:
            kinds = [p.kind for p in r.params]
            if any(
                p.default is None and p.kind not in ("score", "locus", "digit") for p in r.params
            ):
                continue  # a required text (a mouthing's word): not composed here
            scores = [p for p in r.params if p.kind == "score"]
            if "digit" in kinds:
                self.digits.append(r)
            elif any(p.list for p in scores):
                self.lists.append(r)
            elif len(scores) == 1:
                self.unary.append(r)
            elif scores:
                self.fixed.append(r)

    def _call(self, rule, parts: list[str]) -> str:
        """``rule`` applied to the score expressions ``parts`` (loci drawn, numbers default)."""
        args, it = [], iter(parts)
        for p in rule.params:
            if p.kind == "score":
                args.extend(it if p.list else [next(it)])
            elif p.kind == "locus" and p.default is None:
                args.append(self.rng.choice(LOCI))
        return f":{rule.name}({', '.join(args)})"

    def _sign(self) -> str:
        name, kinds = self.rng.choice(self.signs)
        if kinds and kinds[0] == "locus" and self.rng.random() < 0.3:
            return f":{name}({self.rng.choice(LOCI)})"
        return f":{name}"

    def expression(self, k: int) -> str:
        """An expression of ``k`` signs."""
        rng = self.rng
        if k == 1:
            e = self._sign()
            return self._call(rng.choice(self.unary), [e]) if rng.random() < 0.15 else e
        if k == 2 and self.digits and rng.random() < 0.1:
            return f":{self.digits[0].name}(.nb-{rng.randint(1, 9)}, .nb-{rng.randint(0, 9)})"
        if rng.random() < 0.5:
            rule = rng.choice(self.fixed)
            n = sum(p.kind == "score" for p in rule.params)
        else:
            rule = rng.choice(self.lists)
            least = max(p.min_items for p in rule.params if p.list)
            if k < least:
                rule, n = self.fixed[0], 2
            else:
                n = rng.randint(least, min(k, 4))
        cuts = sorted(rng.sample(range(1, k), n - 1)) if n > 1 else []
        sizes = [b - a for a, b in zip([0, *cuts], [*cuts, k], strict=True)]
        return self._call(rule, [self.expression(s) for s in sizes])


def write_corpus(n: int, seed: int, folder: Path) -> list[Path]:
    """``n`` scores ``NNNNN.azee`` of 1 to 12 signs each, in ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    c = Composer(seed)
    paths = []
    for i in range(n):
        p = folder / f"{i:05d}.azee"
        p.write_text(c.expression(c.rng.randint(1, 12)) + "\n")
        paths.append(p)
    return paths


class Runner:
    """One configuration (``pool-W`` or ``dask-W``): its Dask cluster, if any, started once
    (timed apart) and kept for every round."""

    def __init__(self, config: str, tmp: Path):
        kind, w = config.split("-")
        self.config, self.kind, self.workers = config, kind, int(w)
        self.out = tmp / f"out-{config}"
        self.out.mkdir()
        self.client = self.cluster = None
        self.startup = self.elapsed = 0.0
        self.outcomes: list = []
        if kind == "dask":
            import logging

            import distributed

            t0 = time.perf_counter()
            self.cluster = distributed.LocalCluster(
                n_workers=self.workers,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                silence_logs=logging.ERROR,
            )
            self.client = distributed.Client(self.cluster)
            self.client.wait_for_workers(self.workers)
            self.startup = time.perf_counter() - t0

    def realize(self, paths: list[Path]) -> None:
        """Realize ``paths`` (outputs deleted after), adding to the totals."""
        jobs = plan(paths, self.out)
        t0 = time.perf_counter()
        self.outcomes += realize_many(jobs, workers=self.workers, client=self.client)
        self.elapsed += time.perf_counter() - t0
        for j in jobs:
            j.output.unlink(missing_ok=True)

    def close(self) -> None:
        if self.client is not None:
            self.client.close()
            self.cluster.close()

    def result(self) -> dict:
        n, outcomes = len(self.outcomes), self.outcomes
        failed = [o for o in outcomes if not o.ok]
        busy = sum(o.wall for o in outcomes)
        return {
            "config": self.config,
            "workers": self.workers,
            "scores": n,
            "failed": len(failed),
            "first_failures": [o.error for o in failed[:3]],
            "elapsed_s": self.elapsed,
            "startup_s": self.startup,
            "scores_per_s": n / self.elapsed,
            "scores_per_s_per_core": n / self.elapsed / self.workers,
            "worker_wall_s": busy,
            "worker_cpu_s": sum(o.cpu for o in outcomes),
            "cpu_per_score_s": sum(o.cpu for o in outcomes) / n,
            "score_s": sum(o.duration for o in outcomes),
            "per_score_overhead_ms": 1000 * (self.elapsed * self.workers - busy) / n,
        }


def machine() -> dict:
    import mujoco

    return {
        "cpu": cpu_model(),
        "cores": usable_cores(),
        "load_average": os.getloadavg(),
        "python": platform.python_version(),
        "mujoco": mujoco.__version__,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--configs", nargs="+", default=["pool-1", "pool-2", "dask-1", "dask-2"])
    ap.add_argument(
        "--rounds",
        type=int,
        default=2,
        help="slices run by every config in turn (a pool starts once a slice)",
    )
    ap.add_argument("--write-only", metavar="DIR", help="only write the scores into DIR")
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "corpus.json"))
    args = ap.parse_args()
    if args.write_only:
        paths = write_corpus(args.n, args.seed, Path(args.write_only))
        print(f"{len(paths)} scores written to {args.write_only}")
        return
    info = machine()
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        paths = write_corpus(args.n, args.seed, tmp / "in")
        runners = [Runner(c, tmp) for c in args.configs]
        try:
            # Round by round, every configuration realizes the same slice of the corpus (in
            # a turning order), so a change in the machine's other load falls on all alike.
            size = -(-len(paths) // args.rounds)
            for r, a in enumerate(range(0, len(paths), size)):
                turn = runners[r % len(runners) :] + runners[: r % len(runners)]
                for runner in turn:
                    runner.realize(paths[a : a + size])
                print(
                    f"round {r + 1}: {a + size} scores, load {os.getloadavg()[0]:.1f}", flush=True
                )
        finally:
            for runner in runners:
                runner.close()
        rows = [runner.result() for runner in runners]
    for r in rows:
        print(
            f"{r['config']}: {r['scores_per_s']:.3f} scores/s ({r['scores_per_s_per_core']:.3f} "
            f"per core), {r['elapsed_s']:.1f} s + start {r['startup_s']:.1f} s, "
            f"CPU {r['cpu_per_score_s']:.3f} s/score, {r['failed']} failed, overhead "
            f"{r['per_score_overhead_ms']:.1f} ms/score",
            flush=True,
        )
    info["load_average_after"] = os.getloadavg()
    by = {r["config"]: r for r in rows}
    ratios = {}
    if "pool-1" in by and "pool-2" in by:
        ratios["pool_2_over_1"] = by["pool-2"]["scores_per_s"] / by["pool-1"]["scores_per_s"]
    if "dask-1" in by and "dask-2" in by:
        ratios["dask_2_over_1"] = by["dask-2"]["scores_per_s"] / by["dask-1"]["scores_per_s"]
    for w in (1, 2):
        if f"pool-{w}" in by and f"dask-{w}" in by:
            p, q = by[f"pool-{w}"], by[f"dask-{w}"]
            ratios[f"dask_over_pool_per_core_{w}"] = (
                q["scores_per_s_per_core"] / p["scores_per_s_per_core"]
            )
            ratios[f"dask_overhead_ms_per_score_{w}"] = (
                1000 * (q["elapsed_s"] - p["elapsed_s"]) / q["scores"]
            )
    mean_signs = statistics.mean(r["score_s"] for r in rows) / args.n if rows else 0.0
    result = {
        "machine": info,
        "n": args.n,
        "seed": args.seed,
        "mean_score_s": mean_signs,
        "runs": rows,
        "ratios": ratios,
    }
    Path(args.out).parent.mkdir(exist_ok=True)
    Path(args.out).write_text(json.dumps(result, indent=1) + "\n")
    print(json.dumps(ratios, indent=1))


if __name__ == "__main__":
    main()
