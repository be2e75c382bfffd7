"""Files: rollouts to and from ``.npz``, reports to JSON. Writes are atomic (temp + rename),
so a failure never leaves a partial output file."""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from pathlib import Path

import numpy as np

from azee_mj.errors import InputFileError

#: Arrays every rollout file holds.
REQUIRED = ("time", "qpos", "fps", "site_names", "site_pos")


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, suffix: str = ""):
    """Yield a temporary path beside ``path``; move it onto ``path`` only on success."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix or path.suffix,
                               dir=path.parent)  # fmt: skip
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes it owner-only; outputs are ordinary files
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def save_npz(path: str | os.PathLike, arrays: dict[str, np.ndarray]) -> None:
    """Write numeric / fixed-width text arrays to ``path`` (loads with allow_pickle=False)."""
    for k, v in arrays.items():
        if np.asarray(v).dtype == object:
            raise TypeError(f"array {k!r} has dtype object; it would need pickle")
    with atomic_path(path, ".npz") as tmp, open(tmp, "wb") as f:
        np.savez_compressed(f, **arrays)


def save_json(path: str | os.PathLike, obj) -> None:
    """Write ``obj`` as indented JSON, atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(obj, indent=1) + "\n")


def load_rollout_arrays(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Read a rollout ``.npz``; raise :class:`InputFileError` naming what is wrong."""
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except FileNotFoundError:
        raise InputFileError(f"{path}: no such file") from None
    except (OSError, ValueError) as e:
        raise InputFileError(f"{path}: not a rollout .npz file ({e})") from None
    missing = [k for k in REQUIRED if k not in arrays]
    if missing:
        raise InputFileError(
            f"{path}: missing array(s) {', '.join(missing)}; a rollout holds "
            f"{', '.join(REQUIRED)}"
        )
    q = arrays["qpos"]
    if q.ndim != 2 or len(q) != len(arrays["time"]):
        raise InputFileError(f"{path}: qpos must be (T, nq) with T = len(time) = "
                             f"{len(arrays['time'])}; got shape {q.shape}")  # fmt: skip
    return arrays
