"""The compiled solver core (``azee_mj/_ikcore.c``), built by ``pip install -e .``.

Units: metres, radians.
"""

from __future__ import annotations

import functools


@functools.cache
def core():
    """The ``azee_mj._ikcore`` extension; a clear ImportError when the package was not
    built."""
    import mujoco  # noqa: F401  (loads libmujoco, which the extension links against)

    try:
        from azee_mj import _ikcore
    except ImportError as e:  # pragma: no cover - depends on the installation
        raise ImportError(
            "azee_mj's compiled solver core is not built: run `pip install -e .` (or "
            "`python setup.py build_ext --inplace`) in the source tree; it needs a C compiler"
        ) from e
    return _ikcore
