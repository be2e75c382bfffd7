"""A :class:`~azee_mj.timeline.Rollout` to and from a ``.npz`` file (no pickle).

Every array is time first: ``qpos`` (T, nq), ``site_pos`` (T, S, 3). The residual traces
are stored sparsely, each over its block's frames only: ``residual_first`` (C,) first frame,
``residual_count`` (C,) frames, ``residual_values`` (sum of counts,) concatenated, and
``residual_reasons`` (C,) why each missed constraint missed ("" if met; optional); files
written before this layout hold a dense ``residuals`` (T, C) (NaN outside) and still load.
The schedule is stored as parallel arrays and restored as
:class:`~azee_mj.schedule.TrackInterval` records. A file holding only the required arrays
(``time``, ``qpos``, ``fps``, ``site_names``, ``site_pos``) loads with an empty schedule,
no traces and zero stats. A rollout of the physics mode
(:class:`~azee_mj.physics.DynamicRollout`) adds ``torque_joints`` (nu,), ``torque`` and
``torque_peak`` (T, nu), ``torque_limit`` (nu,), ``effort``, ``energy``, ``tracking_site``,
``tracking_joint`` and ``tie_force`` (T,) and ``timestep``, and loads back as one. The solve times
are not stored (they read 0 after loading), so that a file depends only on the score, the
options and the package version. ``score_start`` (the rollout time [s] of the score's time 0:
the lead-in from rest lies before it) reads 0 and ``findings`` empty when absent (files
written before them).

Long rollouts stay out of memory: the site positions, nine tenths of a rollout's data
(about 16 MB per minute at 50 fps), are written a block of frames at a time from a
:class:`~azee_mj.frames.Frames` (a realized rollout computes them from its postures as they
are written) and read back lazily, a block at a time (``Rollout.site_pos`` of a loaded file
is a :class:`~azee_mj.frames.NpzFrames`). The file is the same ``.npz`` as ever, byte for
byte: ``np.load`` reads it whole, and so do files written before.

:func:`load_rollout` validates everything it reads (names, shapes, dtypes, finite values,
fps, sizes announced by array headers before reading them) and raises
:class:`~azee_mj.errors.InputFileError` with one line; it never lets a corrupt or hostile
file end in a traceback or a huge allocation.
"""

from __future__ import annotations

import os
import zipfile

import numpy as np

from azee_mj import heap
from azee_mj.errors import InputFileError, shorten
from azee_mj.files import Chain, save_npz
from azee_mj.frames import Frames, NpzFrames, nonfinite_frames
from azee_mj.physics import DynamicRollout
from azee_mj.schedule import TrackInterval
from azee_mj.score import Score
from azee_mj.timeline import ConstraintTrace, Finding, Mode, Rollout, SolveStats
from azee_mj.timing import MAX_FPS, MAX_FRAMES, MIN_FPS

#: Arrays every rollout file holds.
REQUIRED = ("time", "qpos", "fps", "site_names", "site_pos")
#: Largest array data a rollout file may announce, counted as loaded (numbers as float64)
#: [bytes]: the longest rollout (MAX_FRAMES frames of the bundled signer) needs about 1 GB.
MAX_BYTES = 3 * 2**29


_STATS = ("problems", "key_problems", "iterations", "not_converged", "solve_time", "total_time")


def rollout_arrays(rollout: Rollout, lazy: bool = False) -> dict[str, np.ndarray | Frames]:
    """The arrays of the ``.npz`` file (numeric or fixed-width text), time first; with
    ``lazy``, ``site_pos`` as the rollout holds it (a :class:`~azee_mj.frames.Frames`, to
    be written a block at a time), else as an array."""
    r, tr = rollout, rollout.traces
    ivs = [i for v in r.schedule.values() for i in v]
    s = r.stats
    return {
        "time": r.time,
        "qpos": r.qpos,
        "fps": np.array(r.fps),
        "mode": np.array(r.mode.value),
        "site_names": np.array(r.site_names),
        "site_pos": r.site_pos if lazy else np.asarray(r.site_pos),
        "residual_names": np.array([f"{t.block}#{t.index}" for t in tr], dtype=str),
        "residual_kinds": np.array([t.kind for t in tr], dtype=str),
        "residual_units": np.array([t.unit for t in tr], dtype=str),
        "residual_reasons": np.array([t.reason for t in tr], dtype=str),
        "residual_tol": np.array([t.tol for t in tr], dtype=float),
        "residual_span": np.array([(t.start, t.end) for t in tr], dtype=float).reshape(len(tr), 2),
        "residual_first": np.array([t.first for t in tr], dtype=np.int64),
        "residual_count": np.array([len(t.active) for t in tr], dtype=np.int64),
        "residual_values": (
            Chain([t.active for t in tr], float)
            if lazy
            else (np.concatenate([t.active for t in tr]) if tr else np.zeros(0))
        ),
        "schedule_track": np.array([i.track for i in ivs], dtype=str),
        "schedule_block": np.array([i.block for i in ivs], dtype=str),
        "schedule_span": np.array([(i.start, i.end) for i in ivs], dtype=float).reshape(
            len(ivs), 2
        ),
        # wall-clock times stay out of the file (0 here; --report has them): the same score
        # and options give the same bytes in any process
        "stats": np.array([float(getattr(s, k)) if "time" not in k else 0.0 for k in _STATS]),
        "stats_iterations": np.asarray(s.per_problem_iterations, dtype=np.int64),
        "score_start": np.array(float(r.score_start)),
        "finding_text": np.array(
            [[f.kind, f.block, f.what, f.unit] for f in r.findings], dtype=str
        ).reshape(len(r.findings), 4),
        "finding_values": np.array(
            [[f.value, f.limit, f.start, f.end, f.frames] for f in r.findings], dtype=float
        ).reshape(len(r.findings), 5),
    }


#: The per-frame (T,) arrays of a physics rollout.
DYNAMIC_SERIES = ("effort", "energy", "tracking_site", "tracking_joint", "tie_force")

#: Every array a rollout file may hold (any other member of the file is never read).
ARRAYS = (
    *REQUIRED,
    "mode",
    "residual_names",
    "residual_kinds",
    "residual_units",
    "residual_reasons",
    "residual_tol",
    "residual_span",
    "residual_first",
    "residual_count",
    "residual_values",
    "residuals",
    "schedule_track",
    "schedule_block",
    "schedule_span",
    "stats",
    "stats_iterations",
    "score_start",
    "finding_text",
    "finding_values",
    # a physics rollout's
    "torque_joints",
    "torque",
    "torque_peak",
    "torque_limit",
    "timestep",
    *DYNAMIC_SERIES,
)


def dynamic_arrays(r: DynamicRollout) -> dict[str, np.ndarray]:
    """The extra arrays of a physics rollout."""
    out = {
        "torque_joints": np.array(r.joints, dtype=str),
        "torque": r.torque,
        "torque_peak": r.torque_peak,
        "torque_limit": r.torque_limit,
        "timestep": np.array(r.timestep),
    }
    return out | {k: getattr(r, k) for k in DYNAMIC_SERIES}


def _dynamic(r: Rollout, numeric, text, bad) -> DynamicRollout:
    """``r`` with the physics arrays of its file, checked."""
    T = len(r.time)
    joints = text("torque_joints")
    nu = len(joints)
    arrays = {}
    for k, shape in (
        ("torque", (T, nu)),
        ("torque_peak", (T, nu)),
        ("torque_limit", (nu,)),
        *((k, (T,)) for k in DYNAMIC_SERIES),
    ):
        v = numeric(k)
        if v.shape != shape or not np.isfinite(v).all():
            raise bad(f"array '{k}' must be finite with shape {shape}; got {v.shape}")
        arrays[k] = v
    step = numeric("timestep")
    if step.size != 1 or not 0.0 < float(step.reshape(())) <= 0.002:
        raise bad("timestep must be one number in (0, 0.002] s")
    if (arrays["torque_limit"] <= 0.0).any():
        raise bad("torque_limit must be positive")
    fields = {f: getattr(r, f) for f in Rollout.__dataclass_fields__}
    return DynamicRollout(
        **fields,
        joints=tuple(str(j) for j in joints),
        timestep=float(step.reshape(())),
        **arrays,
    )


def save_rollout(path: str | os.PathLike, rollout: Rollout, inputs=(), options: str = "") -> None:
    """Write ``rollout`` to ``path`` atomically (``inputs``: files it may not replace);
    ``options``, the realization options' fingerprint
    (:func:`azee_mj.batch.fingerprint`), is kept in the file (member ``options``) when
    given, for ``--resume`` to compare (:func:`rollout_options`)."""
    arrays = rollout_arrays(rollout, lazy=True)
    if isinstance(rollout, DynamicRollout):
        arrays |= dynamic_arrays(rollout)
    if options:
        arrays["options"] = np.array(options)
    # what realizing freed given back before the file's buffers come, and those after:
    # each stage of a long score reuses the memory of the one before
    heap.release()
    save_npz(path, arrays, inputs)
    heap.release()


#: The longest options fingerprint :func:`rollout_options` reads [bytes].
MAX_OPTIONS = 1 << 16


def rollout_options(path: str | os.PathLike) -> str | None:
    """The options fingerprint the rollout file at ``path`` records (see
    :func:`save_rollout`), ``None`` if it records none (written before fingerprints, or
    by a program that gave none) or cannot be read."""
    try:
        with zipfile.ZipFile(path) as zf:
            info = zf.getinfo("options.npy")
            if info.file_size > MAX_OPTIONS:
                return None
            with zf.open(info) as f:
                a = np.lib.format.read_array(f, allow_pickle=False)
    except (KeyError, OSError, ValueError, zipfile.BadZipFile, EOFError):
        return None
    return str(a) if a.shape == () and a.dtype.kind == "U" else None


def recorded_tempo(path: str | os.PathLike) -> float:
    """The ``--tempo`` the rollout file at ``path`` was realized at (its options
    fingerprint's ``tempo``; 1 when it records none)."""
    for part in (rollout_options(path) or "").split(";"):
        key, _, value = part.partition("=")
        if key == "tempo":
            try:
                tempo = float(value)
            except ValueError:
                break
            return tempo if np.isfinite(tempo) and tempo > 0 else 1.0
    return 1.0


def realized_score(score: Score, path: str | os.PathLike) -> Score:
    """``score`` as the rollout at ``path`` realized it: at its recorded tempo
    (:func:`recorded_tempo`), so block times match the rollout's frames."""
    tempo = recorded_tempo(path)
    return score.at_tempo(tempo) if tempo != 1.0 else score


#: Arrays read lazily, a block of frames at a time (when stored as C-order float64).
LAZY = ("site_pos",)


def _read_arrays(path) -> dict[str, np.ndarray | Frames]:
    """The arrays of the ``.npz`` at ``path`` that a rollout holds (:data:`ARRAYS`; others
    are never read), after checking each header's announced size against the member's
    size and the whole against :data:`MAX_BYTES` (:func:`_announced`); those of
    :data:`LAZY` as :class:`~azee_mj.frames.NpzFrames` (never whole in memory)."""
    try:
        lazy: dict[str, Frames] = {}
        with zipfile.ZipFile(path) as zf:
            total, members = 0, []
            for info in zf.infolist():
                if info.filename.removesuffix(".npy") not in ARRAYS:
                    continue
                with zf.open(info) as f:
                    version = np.lib.format.read_magic(f)
                    if version == (1, 0):
                        shape, fortran, dtype = np.lib.format.read_array_header_1_0(f)
                    else:
                        shape, fortran, dtype = np.lib.format.read_array_header_2_0(f)
                    offset = f.tell()
                total += _announced(path, info, shape, dtype, total)
                name = info.filename.removesuffix(".npy")
                members.append(name)
                if name in LAZY and not fortran and dtype == np.float64 and len(shape) >= 1:
                    lazy[name] = NpzFrames(path, info.filename, shape, dtype, offset)
        with np.load(path, allow_pickle=False) as z:
            return {**{k: z[k] for k in members if k not in lazy}, **lazy}
    except InputFileError:
        raise
    except FileNotFoundError:
        raise InputFileError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise InputFileError(f"{path}: is a directory, not a rollout .npz file") from None
    except PermissionError:
        raise InputFileError(f"{path}: cannot be read (permission denied)") from None
    except Exception as e:  # noqa: BLE001 - zipfile, zlib and numpy raise many kinds on damage
        what = shorten(str(e).splitlines()[0] if str(e) else type(e).__name__, 100)
        raise InputFileError(f"{path}: not a rollout .npz file, or damaged ({what})") from None


def _announced(path, info: zipfile.ZipInfo, shape, dtype: np.dtype, before: int) -> int:
    """The bytes a member announces as loaded numbers (numbers become float64, so an
    ``int8`` array counts 8 bytes an element), refused over the member's size, or when
    ``before`` + it passes :data:`MAX_BYTES`: checked before a byte of it is read."""
    if dtype.hasobject:
        raise InputFileError(
            f"{path}: array {info.filename!r} holds Python objects; a rollout holds "
            "numbers and text"
        )
    count = int(np.prod(shape, dtype=object))
    shown = shorten(str(shape), 60)
    if count * dtype.itemsize > info.file_size:
        raise InputFileError(
            f"{path}: array {info.filename!r} announces shape {shown}, more than the file "
            "holds or than a rollout may be"
        )
    need = count * (max(dtype.itemsize, 8) if dtype.kind in "biuf" else dtype.itemsize)
    if before + need > MAX_BYTES:
        raise InputFileError(
            f"{path}: array {info.filename!r} announces shape {shown}, {need // 2**20} MB as "
            f"numbers; a rollout's arrays may take at most {MAX_BYTES // 2**20} MB in all"
        )
    return need


def load_rollout(path: str | os.PathLike, nq: int, *, allow_nonfinite: bool = False) -> Rollout:
    """Read a rollout ``.npz`` written for a model with ``nq`` joint coordinates; raise
    :class:`InputFileError` naming what is wrong. Non-finite postures are an error unless
    ``allow_nonfinite`` (``check`` reports them as findings instead)."""
    with np.errstate(all="ignore"):  # hostile values are reported, not warned about
        return _load(path, nq, allow_nonfinite)


def _load(path, nq: int, allow_nonfinite: bool) -> Rollout:
    a = _read_arrays(path)

    def bad(what: str) -> InputFileError:
        return InputFileError(f"{path}: {what}")

    if missing := [k for k in REQUIRED if k not in a]:
        raise bad(f"missing array(s) {', '.join(missing)}; a rollout holds {', '.join(REQUIRED)}")

    def get(k: str) -> np.ndarray:
        if k not in a:
            group = k.split("_")[0]
            raise bad(f"missing array '{k}' (the {group}_* arrays come together)")
        return a[k]

    def numeric(k: str, ndim: int | None = None) -> np.ndarray:
        v = get(k)
        if v.dtype.kind not in "fiu":
            raise bad(f"array '{k}' must hold numbers, got dtype {v.dtype}")
        if ndim is not None and v.ndim != ndim:
            raise bad(f"array '{k}' must have {ndim} dimension(s), got shape {v.shape}")
        if isinstance(v, Frames):
            return v
        return v.astype(float) if v.dtype.kind != "f" or v.dtype != np.float64 else v

    def text(k: str) -> np.ndarray:
        v = get(k)
        if v.dtype.kind != "U" or v.ndim != 1:
            raise bad(f"array '{k}' must be a list of names, got dtype {v.dtype} shape {v.shape}")
        return v

    fps_a = numeric("fps")
    if fps_a.size != 1:
        raise bad(f"fps must be one number, got shape {fps_a.shape}")
    fps = float(fps_a.reshape(()))
    if not (np.isfinite(fps) and MIN_FPS <= fps <= MAX_FPS):
        raise bad(f"fps must be a number from {MIN_FPS:g} to {MAX_FPS:g}, got {fps:g}")
    time, q = numeric("time", 1), numeric("qpos")
    T = len(time)
    if not 1 <= T <= MAX_FRAMES:
        raise bad(f"{T} frames; a rollout has 1 to {MAX_FRAMES}")
    if not np.isfinite(time).all() or (T > 1 and not (np.diff(time) > 0).all()):
        raise bad("time must be finite and increasing")
    if q.ndim != 2 or len(q) != T:
        raise bad(f"qpos must be (T, nq) with T = len(time) = {T}; got shape {q.shape}")
    if q.shape[1] != nq:
        raise bad(f"qpos has {q.shape[1]} columns; the bundled signer has nq={nq}")
    names = text("site_names")
    sp = numeric("site_pos")
    if sp.shape != (T, len(names), 3):
        raise bad(f"site_pos must be (T, S, 3) = ({T}, {len(names)}, 3); got shape {sp.shape}")
    if not allow_nonfinite:
        for k, v in (("qpos", q), ("site_pos", sp)):
            try:
                badf = nonfinite_frames(v)
            except Exception as e:  # noqa: BLE001 - zipfile and zlib raise many kinds on damage
                what = shorten(str(e).splitlines()[0] if str(e) else type(e).__name__, 100)
                raise bad(f"array '{k}' cannot be read whole ({what})") from None
            if badf.size:
                raise bad(f"{k} is not finite at {badf.size} frame(s), first at frame {badf[0]}")

    schedule = _schedule(a, numeric, text, bad)
    traces = _traces(a, T, numeric, text, bad) if "residual_names" in a else []
    stats = _stats(a, numeric, bad)
    start = _score_start(a, numeric, bad, T, fps)
    findings = _findings(a, numeric, bad) if "finding_text" in a else []
    r = Rollout(
        fps,
        _mode(a, bad),
        time,
        q,
        tuple(str(n) for n in names),
        sp,
        {k: tuple(v) for k, v in schedule.items()},
        tuple(traces),
        stats,
        start,
        tuple(findings),
    )
    return _dynamic(r, numeric, text, bad) if "torque_joints" in a else r


def _mode(a, bad) -> Mode:
    """The realization mode of the rollout arrays ``a`` (multitrack if they hold none)."""
    mode_s = str(a["mode"]) if "mode" in a and a["mode"].dtype.kind == "U" else "multitrack"
    if mode_s not in {m.value for m in Mode}:
        raise bad(f"mode must be multitrack or flattened, got {shorten(mode_s, 40)!r}")
    return Mode(mode_s)


def _schedule(a, numeric, text, bad) -> dict[str, list[TrackInterval]]:
    """The schedule of the rollout arrays ``a`` (empty if it holds none)."""
    schedule: dict[str, list[TrackInterval]] = {}
    if "schedule_track" in a:
        tracks, blocks = text("schedule_track"), text("schedule_block")
        spans = numeric("schedule_span", 2)
        if not (len(tracks) == len(blocks) == len(spans) and spans.shape[1:] == (2,)):
            raise bad(
                "schedule_track, schedule_block and schedule_span must have one row each "
                "per interval, spans (N, 2)"
            )
        if not np.isfinite(spans).all():
            raise bad("schedule_span must hold finite times")
        for track, block, (start, end) in zip(tracks, blocks, spans):
            schedule.setdefault(str(track), []).append(
                TrackInterval(str(track), str(block), float(start), float(end))
            )
    return schedule


def _stats(a, numeric, bad) -> SolveStats:
    """The solve statistics of the rollout arrays ``a`` (zero if it holds none)."""
    st = numeric("stats", 1) if "stats" in a else np.zeros(len(_STATS))
    if (
        len(st) != len(_STATS)
        or not np.isfinite(st).all()
        or (st[:4] < 0).any()
        or (st[:4] > 2**53).any()
    ):
        raise bad(f"stats must be {len(_STATS)} finite counts and times")
    its = numeric("stats_iterations", 1) if "stats_iterations" in a else np.zeros(0)
    stats = SolveStats(
        int(st[0]),
        int(st[1]),
        int(st[2]),
        int(st[3]),
        float(st[4]),
        float(st[5]),
        its.astype(np.int64, copy=False) if np.isfinite(its).all() else np.zeros(0, np.int64),
    )
    return stats


def _score_start(a, numeric, bad, T: int, fps: float) -> float:
    """The rollout time [s] of the score's time 0 (0 in files written before it)."""
    start = numeric("score_start") if "score_start" in a else np.zeros(())
    if start.size != 1 or not (
        np.isfinite(start).all() and 0.0 <= float(start.reshape(())) < T / fps
    ):
        raise bad("score_start must be one time [s] within the rollout")
    return float(start.reshape(()))


def _findings(a, numeric, bad) -> list[Finding]:
    text, vals = a["finding_text"], numeric("finding_values", 2)
    if text.dtype.kind != "U" or text.ndim != 2 or text.shape[1:] != (4,):
        raise bad("finding_text must be (N, 4) text")
    if vals.shape != (len(text), 5) or not np.isfinite(vals).all():
        raise bad("finding_values must be (N, 5) finite numbers, one row per finding")
    return [
        Finding(
            *(str(x) for x in t[:3]),
            float(v[0]),
            float(v[1]),
            str(t[3]),
            float(v[2]),
            float(v[3]),
            int(v[4]),
        )
        for t, v in zip(text, vals)
    ]


def _traces(a, T, numeric, text, bad) -> list[ConstraintTrace]:
    names, kinds, units = text("residual_names"), text("residual_kinds"), text("residual_units")
    tol, span = numeric("residual_tol", 1), numeric("residual_span", 2)
    C = len(names)
    # Files written before the diagnosed reasons were stored have none.
    reasons = text("residual_reasons") if "residual_reasons" in a else np.full(C, "")
    if not (
        len(kinds) == len(units) == len(tol) == len(span) == len(reasons) == C
        and span.shape[1:] == (2,)
    ):
        raise bad("the residual_* arrays must have one row per constraint")
    if "residual_values" in a:  # sparse
        first, count = numeric("residual_first", 1), numeric("residual_count", 1)
        if not (
            np.isfinite(first).all()
            and np.isfinite(count).all()
            and (first == np.round(first)).all()
            and (count == np.round(count)).all()
            and (np.abs(first) <= MAX_FRAMES).all()
            and (np.abs(count) <= MAX_FRAMES).all()
        ):
            raise bad("residual_first and residual_count must be whole numbers")
        first, count = first.astype(np.int64), count.astype(np.int64)
        vals = numeric("residual_values", 1)
        if (
            len(first) != C
            or len(count) != C
            or (first < 0).any()
            or (count < 0).any()
            or (first + count > T).any()
            or count.sum() != len(vals)
        ):
            raise bad("residual_first / residual_count do not match the frames and residual_values")
        offsets = np.concatenate([[0], np.cumsum(count)])
        parts = [(int(first[j]), vals[offsets[j] : offsets[j + 1]]) for j in range(C)]
    else:  # dense (T, C), NaN outside each block
        dense = numeric("residuals", 2)
        if dense.shape != (T, C):
            raise bad(f"residuals must be (T, C) = ({T}, {C}); got shape {dense.shape}")
        parts = []
        for j in range(C):
            inside = np.flatnonzero(~np.isnan(dense[:, j]))
            f0 = int(inside[0]) if inside.size else 0
            f1 = int(inside[-1]) + 1 if inside.size else 0
            parts.append((f0, dense[f0:f1, j].copy()))
    out = []
    for j, name in enumerate(names):
        block, sep, index = str(name).rpartition("#")
        if not sep or not index.isdigit() or len(index) > 9:
            raise bad(f"residual name {shorten(str(name), 60)!r} is not BLOCK#INDEX")
        f0, active = parts[j]
        out.append(
            ConstraintTrace(
                block,
                int(index),
                str(kinds[j]),
                float(tol[j]),
                str(units[j]),
                float(span[j][0]),
                float(span[j][1]),
                f0,
                active,
                T,
                str(reasons[j]),
            )
        )
    return out
