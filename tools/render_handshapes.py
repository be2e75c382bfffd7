#!/usr/bin/env python3
"""Render the named handshapes (morphs ``hs_NAME``) as a labelled picture grid.

Run from the repository root (headless: ``MUJOCO_GL=egl``)::

    MUJOCO_GL=egl python tools/render_handshapes.py [-o docs/handshapes.png] [--only a,b]

The strong (right) hand is raised in front of the chest, palm forward and fingers up (one
IK solve), then each handshape is set on the hand joints exactly as a score's morph at
weight 1 sets it (rest value plus the morph's change, clipped to the joint range) and
drawn by two close-up cameras: in front of the palm (slightly to the thumb side) and from
the thumb side.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import mujoco
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from azee_mj.render import gl_backend, scene_model
from azee_mj.sites import DEFAULT_MAP, HANDSHAPES

RAISE = {
    "format": "azee-score",
    "version": 1,
    "strong_side": "R",
    "root": {
        "name": "RAISE",
        "kind": "sync",
        "start": 0,
        "end": 0.4,
        "children": [
            {
                "name": "HAND",
                "kind": "cstr",
                "start": 0,
                "end": 0.4,
                "constraints": [
                    {"type": "morph", "id": "hs_flat", "weight": 1.0, "side": "s"},
                    {
                        "type": "place",
                        "site": "@PA(s)",
                        "at": {"translate": "^ssp", "by": {"scale": "up", "by": 0.15}},
                    },
                    {
                        "type": "orient",
                        "bone": "!palm(s)",
                        "axis": "nrm",
                        "rel": "along",
                        "vector": "fwd",
                    },
                    {
                        "type": "orient",
                        "bone": "!palm(s)",
                        "axis": "dir",
                        "rel": "along",
                        "vector": "up",
                    },
                ],
            }
        ],
    },
}


def raised_posture(model: mujoco.MjModel) -> np.ndarray:
    """qpos with the right hand raised, palm forward (realized from :data:`RAISE`)."""
    from azee_mj.timeline import realize

    return realize(RAISE, fps=10).qpos[-1].copy()


def with_shape(model: mujoco.MjModel, qpos: np.ndarray, shape: str, side: str = "R"):
    """``qpos`` with morph ``hs_<shape>`` at weight 1 on the hand of ``side``."""
    q = qpos.copy()
    for j, v in DEFAULT_MAP.morphs[f"hs_{shape}"].joint_changes(side).items():
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j)
        adr = model.jnt_qposadr[jid]
        lo, hi = model.jnt_range[jid]
        q[adr] = np.clip(model.qpos0[adr] + v, lo, hi)
    return q


#: (azimuth, elevation) [deg] of the two views of each handshape: front and thumb side.
VIEWS = ((200.0, -8.0), (250.0, -8.0))


def render_grid(names: list[str], out: Path, tile: int = 200, cols: int = 4) -> None:
    from PIL import Image, ImageDraw, ImageFont

    gl_backend()
    model = scene_model(tile, tile)
    data = mujoco.MjData(model)
    base = raised_posture(model)
    renderer = mujoco.Renderer(model, height=tile, width=tile)
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.distance = 0.32
    rows = (len(names) + cols - 1) // cols
    label_h, gap = 26, 6
    width = len(VIEWS) * tile + gap
    sheet = Image.new("RGB", (cols * width, rows * (tile + label_h)), "white")
    draw = ImageDraw.Draw(sheet)
    try:
        font = ImageFont.truetype("DejaVuSans.ttf", 17)
    except OSError:
        font = ImageFont.load_default()
    pa = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "PA_R")
    for k, name in enumerate(names):
        data.qpos[:] = with_shape(model, base, name)
        mujoco.mj_forward(model, data)
        cam.lookat[:] = data.site_xpos[pa] + np.array([0.0, 0.0, 0.04])
        x, y = (k % cols) * width, (k // cols) * (tile + label_h)
        for v, (azimuth, elevation) in enumerate(VIEWS):
            cam.azimuth, cam.elevation = azimuth, elevation
            renderer.update_scene(data, cam)
            sheet.paste(Image.fromarray(renderer.render()), (x + v * tile, y + label_h))
        draw.text((x + 8, y + 4), f"hs_{name}", fill="black", font=font)
    renderer.close()
    out.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(out)
    print(f"{out}: {len(names)} handshapes")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("-o", "--output", default=str(ROOT / "docs" / "handshapes.png"))
    p.add_argument("--only", help="comma-separated handshape names (default: all)")
    p.add_argument("--tile", type=int, default=200, help="size of one view in pixels")
    a = p.parse_args(argv)
    names = a.only.split(",") if a.only else list(HANDSHAPES)
    render_grid(names, Path(a.output), tile=a.tile)
    return 0


if __name__ == "__main__":
    sys.exit(main())
