"""CSV: one row a frame, the time, every AZee site's position and the face's ARKit
weights, for spreadsheets and R.

Columns: ``time`` [s], then ``SITE_x``, ``SITE_y``, ``SITE_z`` [m] in the signer frame
(x forward, y left, z up) for every AZee site of the map, then the signing-space loci, in
the catalogue's order, then the 52 ARKit blend-shape weights in [0, 1] named as ARKit
names them (``eyeBlinkLeft`` ...; :mod:`azee_mj.export.arkit` reads them from the rig).
Numbers are written with 9 significant digits. Needs no extra.
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
    pos = mo.site_positions(model, np.asarray(qpos, float), model_sites)
    shapes = face.weights(model, qpos, signer_map)
    t = np.arange(len(qpos)) / fps
    with open(path, "w", newline="") as f:
        w = _csv.writer(f)
        w.writerow(["time", *(f"{n}_{a}" for n in names for a in "xyz"), *arkit.ARKIT_SHAPES])
        for k in range(len(qpos)):
            w.writerow(
                [
                    f"{t[k]:.9g}",
                    *(f"{v:.9g}" for v in pos[k].reshape(-1)),
                    *(f"{v:.9g}" for v in shapes[k]),
                ]
            )
