"""Builds the compiled solver core (``azee_mj._ikcore``) against the MuJoCo C library that
the ``mujoco`` wheel ships (its ``include/`` headers and ``libmujoco.so``); everything else
is in pyproject.toml. Needs a C compiler."""

import glob
import os

import mujoco
from setuptools import Extension, setup

MJ = os.path.dirname(mujoco.__file__)
LIBS = sorted(glob.glob(os.path.join(MJ, "libmujoco.so*")))
if not LIBS:
    raise RuntimeError(f"no libmujoco.so in the mujoco package at {MJ}")

setup(
    ext_modules=[
        Extension(
            "azee_mj._ikcore",
            sources=sorted(glob.glob("azee_mj/_ikcore*.c")),
            depends=["azee_mj/_ikcore_shared.h"],
            include_dirs=[os.path.join(MJ, "include")],
            library_dirs=[MJ],
            libraries=[":" + os.path.basename(LIBS[0])],
            # Installed beside mujoco in site-packages; `import mujoco` (done first by
            # azee_mj) has loaded the same library in any case.
            runtime_library_dirs=["$ORIGIN/../mujoco"],
            extra_compile_args=["-O2", "-std=c11"],
        )
    ]
)
