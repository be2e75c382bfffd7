"""Arrays of frames that are never whole in memory: time-first arrays produced a block of
frames at a time, computed (:class:`SitePositions`) or read from a ``.npz`` member
(:class:`NpzFrames`).

A :class:`Frames` looks enough like a read-only NumPy array for the code that walks a
rollout: ``shape``, ``dtype``, ``len``, a frame (``a[f]``), a range of frames (``a[i:j]``,
any step) and ``a[f, ...]``; :meth:`Frames.blocks` walks it a block at a time, and
``np.asarray(a)`` makes the whole array (only where that is wanted). Units are the array's.
"""

from __future__ import annotations

import threading
import zipfile
import zlib
from collections.abc import Iterator

import mujoco
import numpy as np

from azee_mj.errors import InputFileError

#: Frames per block (about 5 MB of site positions for the bundled signer).
BLOCK = 1024


class Frames(np.lib.mixins.NDArrayOperatorsMixin):
    """A read-only (T, ...) array produced a block of frames at a time (subclasses give
    :meth:`_read`); the last block read is kept, so walking frame by frame reads each block
    once. Arithmetic and NumPy functions work on the whole array (made for them)."""

    def __array_ufunc__(self, ufunc, method, *inputs, **kwargs):
        inputs = tuple(np.asarray(x) if isinstance(x, Frames) else x for x in inputs)
        return getattr(ufunc, method)(*inputs, **kwargs)

    def __init__(self, shape: tuple[int, ...], dtype):
        self.shape, self.dtype = tuple(int(n) for n in shape), np.dtype(dtype)
        self._cache: tuple[int, np.ndarray] | None = None
        self._lock = threading.RLock()

    def _read(self, start: int, stop: int) -> np.ndarray:
        """Frames ``start`` to ``stop`` (exclusive), a new array."""
        raise NotImplementedError

    @property
    def ndim(self) -> int:
        return len(self.shape)

    @property
    def size(self) -> int:
        return int(np.prod(self.shape))

    def __len__(self) -> int:
        return self.shape[0]

    def blocks(self, size: int = BLOCK) -> Iterator[tuple[int, np.ndarray]]:
        """``(first frame, frames)`` of every block of ``size`` frames, in order."""
        for start in range(0, len(self), size):
            yield start, self._read(start, min(start + size, len(self)))

    def _frame(self, f: int) -> np.ndarray:
        with self._lock:
            c = self._cache
            if c is None or not c[0] <= f < c[0] + len(c[1]):
                start = f - f % BLOCK
                c = self._cache = (start, self._read(start, min(start + BLOCK, len(self))))
            return c[1][f - c[0]]

    def __getitem__(self, key):
        rest: tuple = ()
        if isinstance(key, tuple):
            key, rest = key[0], key[1:]
        if isinstance(key, (int, np.integer)):
            f = int(key) + len(self) if key < 0 else int(key)
            if not 0 <= f < len(self):
                raise IndexError(f"frame {key} of {len(self)}")
            out = self._frame(f).copy()
            return out[rest] if rest else out
        if isinstance(key, slice):
            start, stop, step = key.indices(len(self))
            if step == 1:
                out = self._read(start, max(start, stop))
            else:
                frames = [self._frame(f) for f in range(start, stop, step)]
                out = np.array(frames, self.dtype).reshape((-1, *self.shape[1:]))
            return out[(slice(None), *rest)] if rest else out
        return np.asarray(self)[(key, *rest)]

    def __array__(self, dtype=None, copy=None):
        out = np.empty(self.shape, self.dtype)
        for start, block in self.blocks():
            out[start : start + len(block)] = block
        return out if dtype is None else out.astype(dtype, copy=False)

    def __repr__(self) -> str:
        return f"{type(self).__name__}(shape={self.shape}, dtype={self.dtype})"


def nonfinite_frames(v: np.ndarray | Frames) -> np.ndarray:
    """Frames (indices) of the time-first array ``v`` holding NaN or infinity, a block at a
    time when ``v`` is a :class:`Frames` (never whole in memory)."""
    if not isinstance(v, Frames):
        v = np.asarray(v)
        return np.flatnonzero(~np.isfinite(v.reshape(len(v), -1)).all(axis=1))
    bad = [
        start + np.flatnonzero(~np.isfinite(b.reshape(len(b), -1)).all(axis=1))
        for start, b in v.blocks()
    ]
    return np.concatenate(bad) if bad else np.zeros(0, int)


class SitePositions(Frames):
    """Positions (T, S, 3) [m] of the sites ``site_ids`` of ``model`` at postures ``qpos``
    (T, nq), computed a block at a time by forward kinematics."""

    def __init__(self, model: mujoco.MjModel, qpos: np.ndarray, site_ids):
        super().__init__((len(qpos), len(site_ids), 3), np.float64)
        self.model, self.qpos = model, qpos
        self.site_ids = np.asarray(site_ids, dtype=int)
        self._data = mujoco.MjData(model)

    def _read(self, start: int, stop: int) -> np.ndarray:
        out = np.empty((stop - start, len(self.site_ids), 3))
        d = self._data
        for k, f in enumerate(range(start, stop)):
            d.qpos[:] = self.qpos[f]
            mujoco.mj_kinematics(self.model, d)
            out[k] = d.site_xpos[self.site_ids]
        return out

    def __getstate__(self):
        return {k: v for k, v in self.__dict__.items() if k not in ("_data", "_lock", "_cache")}

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._data, self._lock, self._cache = mujoco.MjData(self.model), threading.RLock(), None


class NpzFrames(Frames):
    """The C-order array member ``name`` of the ``.npz`` file at ``path``, whose data start
    ``offset`` bytes into the member: read a block at a time (deflated or stored)."""

    def __init__(self, path, name: str, shape, dtype, offset: int):
        super().__init__(shape, dtype)
        self.path, self.name, self.offset = path, name, offset
        self._row = int(np.prod(self.shape[1:], dtype=np.int64)) * self.dtype.itemsize
        self._file: tuple[zipfile.ZipFile, object] | None = None

    def _read(self, start: int, stop: int) -> np.ndarray:
        with self._lock:
            if self._file is None:
                zf = zipfile.ZipFile(self.path)
                self._file = (zf, zf.open(self.name))
            f = self._file[1]
            # sequential reads continue where the last ended; a seek back re-reads the member
            n = (stop - start) * self._row
            try:
                f.seek(self.offset + start * self._row)
                raw = f.read(n)
            except (zipfile.BadZipFile, zlib.error, EOFError) as e:
                raise InputFileError(f"{self.path}: not a rollout .npz file, or damaged ({e})")
        if len(raw) != n:
            raise InputFileError(f"{self.path}: array {self.name!r} ends before frame {stop}")
        return np.frombuffer(raw, self.dtype).reshape((stop - start, *self.shape[1:])).copy()

    def close(self) -> None:
        """Close the file (it reopens when read again)."""
        with self._lock:
            if self._file is not None:
                self._file[1].close()
                self._file[0].close()
                self._file = None

    def __del__(self):
        if getattr(self, "_file", None) is not None:
            self.close()

    def __getstate__(self):
        return {k: v for k, v in self.__dict__.items() if k not in ("_file", "_lock", "_cache")}

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._file, self._lock, self._cache = None, threading.RLock(), None
