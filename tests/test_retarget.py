"""Another MJCF signer with its own map: the bundled signer renamed and scaled."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from azee_mj import timeline
from azee_mj.errors import ModelError
from azee_mj.model import MODEL_PATH, check_map, load_model
from azee_mj.schedule import make_solver
from azee_mj.sites import DEFAULT_MAP

DATA = Path(__file__).parent / "data"


def _renamed_spec(prefix: str, scale: float = 1.0) -> mujoco.MjSpec:
    """The bundled signer with every body, joint and site renamed, optionally scaled."""
    spec = mujoco.MjSpec.from_file(str(MODEL_PATH))
    for group in (spec.bodies, spec.joints, spec.sites):
        for el in group:
            if el.name and el.name != "world":
                el.name = prefix + el.name
    for ex in spec.excludes:
        ex.bodyname1, ex.bodyname2 = prefix + ex.bodyname1, prefix + ex.bodyname2
    if scale != 1.0:
        for b in spec.bodies:
            b.pos = np.asarray(b.pos) * scale
        for s in spec.sites:
            s.pos = np.asarray(s.pos) * scale
        for g in spec.geoms:
            g.pos = np.asarray(g.pos) * scale
            g.size = np.asarray(g.size) * scale
            if g.fromto is not None and not np.isnan(g.fromto[0]):
                g.fromto = np.asarray(g.fromto) * scale
    return spec


def _renamed_map(prefix: str):
    return DEFAULT_MAP.renamed(lambda s: prefix + s, lambda b: prefix + b, lambda j: prefix + j)


def test_the_renamed_map_fits_the_renamed_model():
    spec = _renamed_spec("sg_")
    model = spec.compile()
    check_map(model, _renamed_map("sg_"))
    with pytest.raises(
        ModelError, match="site 'HEAD' maps to model site 'HEAD', which the model lacks"
    ):
        check_map(model, DEFAULT_MAP)


def test_load_model_checks_the_map(tmp_path):
    path = tmp_path / "renamed.xml"
    path.write_text(_renamed_spec("sg_").to_xml())
    assert load_model(path, _renamed_map("sg_")).nq == load_model().nq


def test_a_renamed_signer_realizes_the_same_motion():
    original = timeline.realize(DATA / "good.json", solver=make_solver(seed=0))
    solver = make_solver(_renamed_spec("sg_"), _renamed_map("sg_"), seed=0)
    renamed = timeline.realize(DATA / "good.json", solver=solver, signer_map=_renamed_map("sg_"))
    assert renamed.site_names == original.site_names  # AZee names, whatever the model calls them
    assert np.abs(renamed.site_pos - original.site_pos).max() < 1e-3
    assert all(t.ok for t in renamed.traces)


def test_a_smaller_signer_meets_the_same_constraints():
    """A 0.9-scale signer (1.53 m) with the same map: the score's targets are relative to
    its own body (sites and loci), so every constraint still holds."""
    solver = make_solver(_renamed_spec("", 0.9), DEFAULT_MAP, seed=0)
    small = timeline.realize(DATA / "good.json", solver=solver)
    assert all(t.ok for t in small.traces), [(t.block, t.worst) for t in small.traces]
    tall = timeline.realize(DATA / "good.json", solver=make_solver(seed=0))
    head = small.site_names.index("HEAD")
    assert small.site_pos[0, head, 2] == pytest.approx(0.9 * tall.site_pos[0, head, 2], rel=0.02)
