"""CSV: one row a frame, the time, every AZee site's position and the face's ARKit
weights, for spreadsheets and R.

Columns: ``time`` [s], then ``SITE_x``, ``SITE_y``, ``SITE_z`` [m] in the signer frame
(x forward, y left, z up) for every AZee site of the map, then the signing-space loci, in
the catalogue's order (``docs/exports.md`` has the legend of the AZee names), then the 52
ARKit blend-shape weights in [0, 1] named as ARKit names them (``eyeBlinkLeft`` ...;
:mod:`azee_mj.export.arkit` reads them from the rig). Numbers are written with 9
significant digits, always as floats (``0.0``, never ``0``), a chunk of frames at a time
(bounded memory for any length). Needs no extra.
"""

from __future__ import annotations

import csv as _csv
import os

import mujoco
import numpy as np

from azee_mj import arkit
from azee_mj.export import arkit as face
from azee_mj.export import motion as mo
from azee_mj.sites import DEFAULT_MAP, SignerMap


def columns(signer_map: SignerMap = DEFAULT_MAP) -> tuple[str, ...]:
    """The AZee names whose positions the file holds, in column order."""
    return (*signer_map.sites, *signer_map.loci)


def write_csv(
    path: str | os.PathLike,
    model: mujoco.MjModel,
    qpos: np.ndarray,
    fps: float,
    *,
    signer_map: SignerMap = DEFAULT_MAP,
) -> None:
    """Write the sites' positions on every frame to ``path`` (the caller makes it atomic)."""
    mo.check_qpos(model, qpos, fps)
    names = columns(signer_map)
    model_sites = [{**signer_map.sites, **signer_map.loci}[n] for n in names]
    header = ["time", *(f"{n}_{a}" for n in names for a in "xyz"), *arkit.ARKIT_SHAPES]
    with open(path, "w", newline="") as f:
        _csv.writer(f).writerow(header)
        for k0, q in mo.chunks(qpos):
            pos = mo.site_positions(model, q, model_sites).reshape(len(q), -1)
            shapes = face.weights(model, q, signer_map)
            t = np.arange(k0, k0 + len(q)) / fps
            rows = np.column_stack([t, pos, shapes])
            f.write(mo.float_rows(rows, 9, ",", "\r\n", always_float=True))
