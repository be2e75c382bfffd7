"""A :class:`~azee_mj.timeline.Rollout` to and from a ``.npz`` file (no pickle).

Every array is time first: ``qpos`` (T, nq), ``site_pos`` (T, S, 3), ``residuals`` (T, C)
for the C constraint traces. The schedule is stored as four parallel arrays and restored as
:class:`~azee_mj.schedule.TrackInterval` records. A file holding only the required arrays
(``time``, ``qpos``, ``fps``, ``site_names``, ``site_pos``) loads with an empty schedule,
no traces and zero stats.
"""

from __future__ import annotations

import os

import numpy as np

from azee_mj.errors import InputFileError
from azee_mj.files import save_npz
from azee_mj.schedule import TrackInterval
from azee_mj.timeline import ConstraintTrace, Mode, Rollout, SolveStats

#: Arrays every rollout file holds.
REQUIRED = ("time", "qpos", "fps", "site_names", "site_pos")

_STATS = ("problems", "key_problems", "iterations", "not_converged", "solve_time", "total_time")


def rollout_arrays(rollout: Rollout) -> dict[str, np.ndarray]:
    """The arrays of the ``.npz`` file (numeric or fixed-width text), time first."""
    r, tr = rollout, rollout.traces
    ivs = [i for v in r.schedule.values() for i in v]
    s = r.stats
    return {
        "time": r.time,
        "qpos": r.qpos,
        "fps": np.array(r.fps),
        "mode": np.array(r.mode.value),
        "site_names": np.array(r.site_names),
        "site_pos": r.site_pos,
        "residual_names": np.array([f"{t.block}#{t.index}" for t in tr], dtype=str),
        "residual_kinds": np.array([t.kind for t in tr], dtype=str),
        "residual_units": np.array([t.unit for t in tr], dtype=str),
        "residual_tol": np.array([t.tol for t in tr]),
        "residual_span": np.array([(t.start, t.end) for t in tr]).reshape(len(tr), 2),
        "residuals": np.array([t.values for t in tr]).reshape(len(tr), len(r.time)).T,
        "schedule_track": np.array([i.track for i in ivs], dtype=str),
        "schedule_block": np.array([i.block for i in ivs], dtype=str),
        "schedule_span": np.array([(i.start, i.end) for i in ivs]).reshape(len(ivs), 2),
        "stats": np.array([float(getattr(s, k)) for k in _STATS]),
        "stats_iterations": np.asarray(s.per_problem_iterations),
    }


def save_rollout(path: str | os.PathLike, rollout: Rollout, inputs=()) -> None:
    """Write ``rollout`` to ``path`` atomically (``inputs``: files it may not replace)."""
    save_npz(path, rollout_arrays(rollout), inputs)


def load_rollout(path: str | os.PathLike, nq: int) -> Rollout:
    """Read a rollout ``.npz`` written for a model with ``nq`` joint coordinates; raise
    :class:`InputFileError` naming what is wrong."""
    try:
        with np.load(path, allow_pickle=False) as z:
            a = {k: z[k] for k in z.files}
    except FileNotFoundError:
        raise InputFileError(f"{path}: no such file") from None
    except (OSError, ValueError) as e:
        raise InputFileError(f"{path}: not a rollout .npz file ({e})") from None
    missing = [k for k in REQUIRED if k not in a]
    if missing:
        raise InputFileError(
            f"{path}: missing array(s) {', '.join(missing)}; a rollout holds "
            f"{', '.join(REQUIRED)}"
        )
    q, time = a["qpos"], a["time"]
    if q.ndim != 2 or len(q) != len(time):
        raise InputFileError(f"{path}: qpos must be (T, nq) with T = len(time) = "
                             f"{len(time)}; got shape {q.shape}")  # fmt: skip
    if q.shape[1] != nq:
        raise InputFileError(f"{path}: qpos has {q.shape[1]} columns; the bundled signer "
                             f"has nq={nq}")  # fmt: skip
    schedule: dict[str, list[TrackInterval]] = {}
    for track, block, (start, end) in zip(a.get("schedule_track", ()), a.get("schedule_block", ()),
                                          a.get("schedule_span", ()), strict=True):  # fmt: skip
        schedule.setdefault(str(track), []).append(
            TrackInterval(str(track), str(block), float(start), float(end)))
    traces = []
    if "residual_kinds" in a:
        for j, name in enumerate(a["residual_names"]):
            block, index = str(name).rsplit("#", 1)
            start, end = a["residual_span"][j]
            traces.append(ConstraintTrace(
                block, int(index), str(a["residual_kinds"][j]), float(a["residual_tol"][j]),
                str(a["residual_units"][j]), float(start), float(end), a["residuals"][:, j]))
    st = a["stats"] if "stats" in a else np.zeros(len(_STATS))
    stats = SolveStats(int(st[0]), int(st[1]), int(st[2]), int(st[3]), float(st[4]),
                       float(st[5]), a.get("stats_iterations", np.zeros(0, int)))  # fmt: skip
    mode = Mode(str(a["mode"])) if "mode" in a else Mode.MULTITRACK
    return Rollout(float(a["fps"]), mode, time, q, tuple(str(n) for n in a["site_names"]),
                   a["site_pos"], {k: tuple(v) for k, v in schedule.items()}, tuple(traces),
                   stats)  # fmt: skip
