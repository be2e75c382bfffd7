"""Exports of a realized motion for other tools: glTF / GLB, BVH, ``.pose``, CSV and a web
player page.

:func:`export` is the entry point (the ``azee-mj export`` command calls it); the writer of
each format takes the model, the postures ``qpos`` (T, nq) and the fps (and, for the player,
the schedule's block names), so that it can be used on any motion:

=========  ===================================  ==========================================
suffix     writer                               library (``pip install azee_mj[export]``)
=========  ===================================  ==========================================
``.glb``   :func:`gltf.write_gltf` (binary)      pygltflib
``.gltf``  :func:`gltf.write_gltf` (JSON)        pygltflib
``.bvh``   :func:`bvh.write_bvh`                 (none; bvhio reads it back in the tests)
``.pose``  :func:`pose.write_pose`               pose-format
``.csv``   :func:`csv.write_csv`                 (none)
``.livelink.csv``  :func:`arkit.write_livelink` (none): the face as Live Link Face writes it
``.html``  :func:`player.write_player`           pygltflib (three.js is bundled)
=========  ===================================  ==========================================

Every file is written to a temporary name beside the output and renamed when complete, so
a failure leaves no partial file.
"""

from __future__ import annotations

import os
from pathlib import Path

import mujoco
import numpy as np

from azee_mj.errors import AzeeError, InputFileError
from azee_mj.export.motion import MissingExtraError, Motion, schedule_tuples
from azee_mj.files import atomic_path
from azee_mj.sites import DEFAULT_MAP, SignerMap
from azee_mj.timing import check_fps

#: Output suffix -> format name.
FORMATS = {
    ".glb": "glb",
    ".gltf": "gltf",
    ".bvh": "bvh",
    ".pose": "pose",
    ".livelink.csv": "livelink",
    ".csv": "csv",
    ".html": "html",
}

__all__ = ["FORMATS", "MissingExtraError", "Motion", "export", "load_motion", "write"]


def load_motion(
    path: str | os.PathLike,
    *,
    score: str | os.PathLike | None = None,
    fps: float = 50.0,
    model: mujoco.MjModel | None = None,
) -> Motion:
    """The motion of ``SCORE.json`` (realized at ``fps``) or of ``ROLLOUT.npz`` (checked
    against ``model``, the bundled signer by default; its schedule is the one stored in the
    rollout, or that of ``score`` when given).

    This is the exporters' one dependency on how rollouts are stored.
    """
    from azee_mj import score as sc
    from azee_mj import timeline
    from azee_mj.model import load_model
    from azee_mj.rollout_io import load_rollout, realized_score
    from azee_mj.schedule import schedule, shifted

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".json":
        s = sc.load_score(path)
        r = timeline.realize(s, fps=fps)
        return Motion(r.qpos, float(r.fps), schedule_tuples(r.schedule), path.stem)
    if suffix != ".npz":
        raise InputFileError(
            f"{path}: expected a SCORE.json or a ROLLOUT.npz, got suffix {path.suffix!r}"
        )
    bundled = model is None
    model = model or load_model()
    r = load_rollout(path, model.nq)
    if bundled and list(r.site_names) != list(DEFAULT_MAP.sites):
        raise InputFileError(
            f"{path}: not a rollout of this signer: its site_names are not "
            f"the catalogue's {len(DEFAULT_MAP.sites)} AZee sites"
        )
    sched = r.schedule
    if score is not None:
        given = realized_score(sc.load_score(Path(score)), path)
        sched = shifted(schedule(given), r.score_start)
    return Motion(np.asarray(r.qpos, float), float(r.fps), schedule_tuples(sched), path.stem)


def write(
    output: str | os.PathLike,
    motion: Motion,
    *,
    model: mujoco.MjModel | None = None,
    signer_map: SignerMap = DEFAULT_MAP,
    inputs=(),
) -> Path:
    """Write ``motion`` to ``output`` in the format its suffix names (:data:`FORMATS`),
    atomically, by the output rule of :mod:`azee_mj.files` (``inputs``: files it may not
    replace). Returns the output path."""
    from azee_mj.export import motion as mo

    output = Path(output)
    fmt = format_of(output)
    if model is None:
        from azee_mj.model import load_model

        model = load_model()
    mo.check_qpos(model, motion.qpos, motion.fps, where=motion.name or "qpos")
    writer = _writer(fmt)  # imports the extra before any file is made
    if fmt == "html":
        from azee_mj.export.player import check_frames

        check_frames(output, len(motion.qpos))
    with atomic_path(output, inputs=inputs) as tmp:
        writer(tmp, model, motion, signer_map)
    return output


def format_of(output: str | os.PathLike) -> str:
    """The format name of an output path; :class:`AzeeError` for an unknown suffix."""
    name = Path(output).name.lower()
    if name.endswith(".livelink.csv"):
        return "livelink"
    suffix = Path(output).suffix.lower()
    if suffix not in FORMATS:
        raise AzeeError(
            f"{output}: unknown export suffix {Path(output).suffix!r}; use one of "
            f"{', '.join(FORMATS)}"
        )
    return FORMATS[suffix]


def _writer(fmt: str):
    from azee_mj.export import motion as mo

    if fmt in ("glb", "gltf", "html"):
        mo.require("pygltflib", "glTF" if fmt != "html" else "The web player's")
    if fmt == "pose":
        mo.require("pose_format", ".pose")
    if fmt in ("glb", "gltf"):
        from azee_mj.export.gltf import write_gltf

        return lambda p, m, mot, smap: write_gltf(p, m, mot.qpos, mot.fps)
    if fmt == "bvh":
        from azee_mj.export.bvh import write_bvh

        return lambda p, m, mot, smap: write_bvh(p, m, mot.qpos, mot.fps, signer_map=smap)
    if fmt == "pose":
        from azee_mj.export.pose import write_pose

        return lambda p, m, mot, smap: write_pose(p, m, mot.qpos, mot.fps, signer_map=smap)
    if fmt == "livelink":
        from azee_mj.export.arkit import write_livelink

        return lambda p, m, mot, smap: write_livelink(p, m, mot.qpos, mot.fps, signer_map=smap)
    if fmt == "csv":
        from azee_mj.export.csv import write_csv

        return lambda p, m, mot, smap: write_csv(p, m, mot.qpos, mot.fps, signer_map=smap)
    from azee_mj.export.player import write_player

    return lambda p, m, mot, smap: write_player(
        p, m, mot.qpos, mot.fps, mot.schedule, mot.name or "azee_mj"
    )


def export(
    source,
    output: str | os.PathLike,
    *,
    score: str | os.PathLike | None = None,
    fps: float = 50.0,
    model: mujoco.MjModel | None = None,
    signer_map: SignerMap = DEFAULT_MAP,
) -> Path:
    """Export a motion to ``output`` (``.glb``, ``.gltf``, ``.bvh``, ``.pose``, ``.csv``,
    ``.livelink.csv`` or ``.html``, see :data:`FORMATS`).

    Args:
      source: ``SCORE.json`` (realized first, at ``fps`` frames per second),
        ``ROLLOUT.npz``, a :class:`~azee_mj.timeline.Rollout` or a :class:`Motion`.
      output: the file to write (atomically: no partial file on failure).
      score: for a ``ROLLOUT.npz``, the score it realizes (the player shows its block names).
      fps: frames per second when realizing a score [1/s].
      model: the signer (default: the bundled one).

    Raises :class:`~azee_mj.errors.AzeeError` (one message naming the file and what is
    valid) for an unknown suffix, an input that is not a rollout of this signer, or a
    missing optional library (:class:`MissingExtraError`).
    """
    _writer(format_of(output))  # an unknown suffix or a missing extra fails before realizing
    fps = check_fps(fps, "fps")
    if isinstance(source, Motion):
        motion = source
    elif hasattr(source, "qpos") and hasattr(source, "schedule"):
        motion = Motion(
            np.asarray(source.qpos), float(source.fps), schedule_tuples(source.schedule)
        )
    else:
        motion = load_motion(source, score=score, fps=fps, model=model)
    inputs = [p for p in (source, score) if isinstance(p, str | os.PathLike)]
    return write(output, motion, model=model, signer_map=signer_map, inputs=inputs)
