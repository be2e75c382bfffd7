"""Fixtures shared by several test modules: the bundled signer, a solver on it, and an
OpenGL back-end for rendering (a module defining its own fixture of the same name keeps it)."""

import pytest

from azee_mj import load_model
from azee_mj import render as rd
from azee_mj.errors import AzeeError
from azee_mj.schedule import make_solver


@pytest.fixture(scope="module")
def solver():
    return make_solver()


@pytest.fixture(scope="module")
def model():
    return load_model()


@pytest.fixture(scope="module")
def gl() -> str:
    try:
        return rd.gl_backend()
    except AzeeError as e:
        pytest.skip(f"no OpenGL backend works here, so nothing can be rendered: {e}")
