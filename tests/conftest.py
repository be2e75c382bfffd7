"""Fixtures shared by the test modules (the bundled signer, its data, a solver on it, an
OpenGL back-end for rendering) and the ``extra`` marker.

``@pytest.mark.extra("render", ...)`` skips a test, with a reason naming what to install,
when a package of one of those optional extras of ``pyproject.toml`` is missing (so a
checkout with only the ``[test]`` extra runs the rest of the suite cleanly).
"""

import importlib.util

import mujoco
import pytest

from azee_mj import load_model
from azee_mj import render as rd
from azee_mj.errors import AzeeError
from azee_mj.schedule import make_solver

#: The modules each optional extra provides (pyproject.toml's optional dependencies).
EXTRAS = {
    "render": ("imageio", "imageio_ffmpeg", "PIL"),
    "plot": ("matplotlib",),
    "export": ("pygltflib", "bvhio", "pose_format"),
    "mouthing": ("phonemizer",),
}


def missing(extra: str) -> list[str]:
    """The modules of ``extra`` that cannot be imported here."""
    return [m for m in EXTRAS[extra] if importlib.util.find_spec(m) is None]


def pytest_configure(config):
    config.addinivalue_line(
        "markers", "extra(*names): needs the optional extras named (skipped when missing)"
    )


def pytest_runtest_setup(item):
    for mark in item.iter_markers("extra"):
        for extra in mark.args:
            if gone := missing(extra):
                pytest.skip(
                    f"needs the [{extra}] extra ({', '.join(gone)} missing): "
                    f"pip install azee_mj[{extra}]"
                )


@pytest.fixture(scope="session")
def model() -> mujoco.MjModel:
    """The bundled signer (shared: tests read it, none writes it)."""
    return load_model()


@pytest.fixture
def data(model) -> mujoco.MjData:
    """Fresh data on the bundled signer, for one test."""
    return mujoco.MjData(model)


@pytest.fixture(scope="module")
def solver():
    """A solver on the bundled signer (seed 0), one per module: tests set its options
    (``on_solve``, ``seeder``, naturalness), so modules do not share one."""
    return make_solver()


@pytest.fixture(scope="module")
def gl() -> str:
    try:
        return rd.gl_backend()
    except AzeeError as e:
        pytest.skip(f"no OpenGL backend works here, so nothing can be rendered: {e}")
