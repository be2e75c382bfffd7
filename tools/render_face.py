#!/usr/bin/env python3
"""Render ``docs/face.png``: the 52 ARKit blend shapes at weight 1 from the ``face`` camera.

Run from the repository root (needs the ``render`` extra and an offscreen GL)::

    MUJOCO_GL=egl python tools/render_face.py [OUT.png] [--tile W H] [--only NAME ...]
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from azee_mj import face
from azee_mj.arkit import ARKIT_SHAPES
from azee_mj.model import load_model
from azee_mj.render import FrameRenderer


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", nargs="?", default=str(ROOT / "docs" / "face.png"))
    ap.add_argument("--tile", nargs=2, type=int, default=(320, 240), metavar=("W", "H"))
    ap.add_argument("--only", nargs="*", help="these shapes (default: neutral and all 52)")
    ap.add_argument("--cols", type=int, default=8, help="tiles per row (default 8)")
    args = ap.parse_args()
    from PIL import Image, ImageDraw

    model = load_model()
    names = args.only or ["neutral", *ARKIT_SHAPES]
    w, h = args.tile
    cols = min(len(names), args.cols)
    rows = math.ceil(len(names) / cols)
    sheet = Image.new("RGB", (cols * w, rows * h), "white")
    draw = ImageDraw.Draw(sheet)
    with FrameRenderer(camera="face", size=(w, h)) as fr:
        for k, name in enumerate(names):
            weights = {} if name == "neutral" else {name: 1.0}
            x, y = (k % cols) * w, (k // cols) * h
            sheet.paste(Image.fromarray(fr.render(face.morph_posture(model, weights))), (x, y))
            draw.rectangle((x, y, x + 8 + 7 * len(name), y + 16), fill=(0, 0, 0))
            draw.text((x + 4, y + 2), name, fill=(255, 255, 255))
    sheet.save(args.out)
    print(f"wrote {args.out} ({len(names)} tiles)")


if __name__ == "__main__":
    main()
