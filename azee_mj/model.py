"""Loading the bundled signer model (or another MJCF signer) and checking it against its map."""

from __future__ import annotations

from pathlib import Path

import mujoco

from azee_mj.errors import ModelError
from azee_mj.sites import DEFAULT_MAP, SignerMap

MODEL_PATH = Path(__file__).parent / "mjcf" / "signer.xml"
SCENE_PATH = Path(__file__).parent / "mjcf" / "scene.xml"


def load_model(
    path: str | Path = MODEL_PATH, signer_map: SignerMap = DEFAULT_MAP
) -> mujoco.MjModel:
    """Compile an MJCF signer and check that every name of ``signer_map`` exists in it."""
    model = mujoco.MjModel.from_xml_path(str(path))
    check_map(model, signer_map)
    return model


def check_map(model: mujoco.MjModel, signer_map: SignerMap) -> None:
    """Raise :class:`ModelError` naming the first map entry the model lacks."""

    def has(obj, name):
        return mujoco.mj_name2id(model, obj, name) >= 0

    for azee, site in [*signer_map.sites.items(), *signer_map.loci.items()]:
        if not has(mujoco.mjtObj.mjOBJ_SITE, site):
            raise ModelError(f"site {azee!r} maps to model site {site!r}, which the model lacks")
    for bone, b in signer_map.bones.items():
        if not has(mujoco.mjtObj.mjOBJ_BODY, b.body):
            raise ModelError(f"bone {bone!r} maps to body {b.body!r}, which the model lacks")
    joints = {j for m in signer_map.morphs.values() for j in m.joint_changes(None)}
    joints |= {j for t in signer_map.tracks.values() for j in t}
    for j in sorted(joints):
        if not has(mujoco.mjtObj.mjOBJ_JOINT, j):
            raise ModelError(f"the map names joint {j!r}, which the model lacks")
