"""Output files, one rule for every command that writes: :func:`check_output` before any
work, then :func:`atomic_path` (temp file in the same directory + rename); and the one
way text inputs are read (:func:`read_text`: a regular file of at most
:data:`MAX_TEXT_BYTES`, never a device or fifo that would never end).

The rule:

* an output that exists must be a regular file (never a directory, device, fifo or socket),
  and must not be one of the command's inputs;
* a symbolic link is written *through*: the file it points to is replaced, the link stays;
* the output's directory must exist and be writable (checked before any work starts, so a
  long run never ends on an unwritable ``--report``);
* the data goes to a hidden temporary file beside the output, renamed onto it only when
  complete; the temporary file is removed on any failure, on Ctrl-C (SIGINT) and, once
  :func:`install_signal_handlers` ran, on SIGTERM, SIGHUP (a closed terminal or dropped ssh
  session) and SIGQUIT. (SIGKILL cannot be caught: a ``.NAME.*`` file may then remain.)
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import signal
import stat
import tempfile
import zipfile
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from azee_mj.errors import OutputError, shorten

#: Largest score, expression or lexicon sign file read [bytes].
MAX_TEXT_BYTES = 16 * 1024**2

#: Temporary files being written now (removed by :func:`remove_temporaries`).
_PENDING: set[str] = set()


class Terminated(BaseException):
    """SIGTERM, SIGHUP or SIGQUIT arrived (raised by the handler
    :func:`install_signal_handlers` installs)."""


#: Signals that end a command as SIGTERM does (temporary files removed, exit 143).
TERMINATING = tuple(
    getattr(signal, name) for name in ("SIGTERM", "SIGHUP", "SIGQUIT") if hasattr(signal, name)
)


def _shown(path) -> str:
    return shorten(str(path), 200)


def read_text(path: str | os.PathLike, limit: int = MAX_TEXT_BYTES) -> str:
    """The UTF-8 text of the regular file ``path`` (a leading byte-order mark dropped).

    Raises ``OSError`` (its ``strerror`` says why) for a device, fifo or socket (``/dev/zero``
    would never end, a fifo would wait for a writer) and for a file over ``limit`` bytes;
    ``UnicodeDecodeError`` for text that is not UTF-8."""
    flags = os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0)
    fd = os.open(path, flags)  # non-blocking: a fifo opens at once, then is refused
    try:
        mode = os.fstat(fd).st_mode
        if stat.S_ISDIR(mode):
            raise IsADirectoryError(errno.EISDIR, "Is a directory")
        if not stat.S_ISREG(mode):
            raise OSError(errno.EINVAL, "not a regular file (a device, fifo or socket)")
        with os.fdopen(os.dup(fd), "rb") as f:
            data = f.read(limit + 1)
    finally:
        os.close(fd)
    if len(data) > limit:
        raise OSError(
            errno.EFBIG,
            f"larger than {limit // 2**20} MB, the limit for a score, expression or sign file",
        )
    return data.decode("utf-8-sig")


def check_output(
    path: str | os.PathLike, inputs: Iterable[str | os.PathLike] = (), directory: bool = False
) -> Path:
    """The file ``path`` will replace (symlinks resolved), after checking it may be written;
    raise :class:`~azee_mj.errors.OutputError` (one line) otherwise.

    ``inputs`` are the command's input files (an output may not be one of them);
    ``directory`` is for an output directory (it may exist as a directory, or be created in
    a writable parent)."""
    target = Path(os.path.realpath(path))
    shown = _shown(path)
    try:
        st = os.stat(target)
    except FileNotFoundError:
        st = None
    except OSError as e:  # e.g. a file used as a parent directory (ENOTDIR), a loop
        raise OutputError(f"{shown}: cannot be written: {e.strerror}") from None
    if st is not None:
        if directory:
            if not stat.S_ISDIR(st.st_mode):
                raise OutputError(f"{shown}: exists and is not a directory")
            if not os.access(target, os.W_OK | os.X_OK):
                raise OutputError(f"{shown}: the directory is not writable")
            return target
        if stat.S_ISDIR(st.st_mode):
            raise OutputError(f"{shown}: is a directory; give a file name")
        if not stat.S_ISREG(st.st_mode):
            raise OutputError(
                f"{shown}: exists and is not a regular file (a device, fifo or "
                "socket); refusing to replace it"
            )
        for i in inputs:
            with contextlib.suppress(OSError):
                if os.path.samefile(i, target):
                    raise OutputError(
                        f"{shown}: is also an input ({_shown(i)}); write to another file"
                    )
    parent = target.parent
    if not parent.exists():
        raise OutputError(f"{shown}: the directory {_shown(parent)} does not exist")
    if not parent.is_dir():
        raise OutputError(f"{shown}: {_shown(parent)} is not a directory")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(f"{shown}: the directory {_shown(parent)} is not writable")
    return target


def check_output_dir(path: str | os.PathLike) -> Path:
    """The existing directory ``path`` (symlinks resolved) that outputs will be written into,
    after checking it is a writable directory; raise :class:`~azee_mj.errors.OutputError`
    otherwise. Unlike ``check_output(..., directory=True)``, which accepts a directory yet
    to be made in a writable parent, it must exist, as a single output's directory must."""
    if not os.path.exists(os.path.realpath(path)):  # 'FILE/' is a file, not missing
        raise OutputError(f"{_shown(path)}: the directory does not exist")
    return check_output(path, directory=True)


@contextlib.contextmanager
def atomic_path(
    path: str | os.PathLike, suffix: str = "", inputs: Iterable[str | os.PathLike] = ()
):
    """Yield a temporary path beside ``path`` (checked with :func:`check_output`); move it
    onto ``path`` (through a symlink) only on success, remove it otherwise."""
    target = check_output(path, inputs)
    fd, tmp = tempfile.mkstemp(
        prefix=f".{target.name}.", suffix=suffix or target.suffix, dir=target.parent
    )
    _PENDING.add(tmp)
    try:
        os.close(fd)
        if target.exists():  # keep the replaced file's permissions
            mode = stat.S_IMODE(os.stat(target).st_mode)
        else:  # mkstemp makes it owner-only; outputs are ordinary files
            umask = os.umask(0)
            os.umask(umask)
            mode = 0o666 & ~umask
        os.chmod(tmp, mode)
        yield Path(tmp)
        os.replace(tmp, target)
    except OSError as e:
        raise OutputError(f"{_shown(path)}: cannot be written: {e.strerror or e}") from None
    finally:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        _PENDING.discard(tmp)


def remove_temporaries() -> None:
    """Remove every temporary file being written now."""
    for tmp in list(_PENDING):
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        _PENDING.discard(tmp)


def install_signal_handlers() -> None:
    """Make SIGTERM, SIGHUP and SIGQUIT (:data:`TERMINATING`) raise :class:`Terminated` (so
    temporary files are removed as the stack unwinds) and SIGINT raise
    ``KeyboardInterrupt``; main thread only."""

    def on_term(signum, frame):
        remove_temporaries()
        raise Terminated(signum)

    for sig in TERMINATING:
        signal.signal(sig, on_term)
    signal.signal(signal.SIGINT, signal.default_int_handler)


def save_npz(
    path: str | os.PathLike, arrays: dict[str, np.ndarray], inputs: Iterable[str | os.PathLike] = ()
) -> None:
    """Write numeric / fixed-width text arrays to ``path`` as a compressed ``.npz`` (loads
    with ``np.load(..., allow_pickle=False)``); the same arrays always give the same bytes.
    A value with a ``blocks()`` method (a :class:`~azee_mj.frames.Frames`) is written a
    block of frames at a time, never whole in memory, to the same bytes."""
    for k, v in arrays.items():
        if not hasattr(v, "blocks") and np.asarray(v).dtype == object:
            raise TypeError(f"array {k!r} has dtype object; it would need pickle")
    with (
        atomic_path(path, ".npz", inputs) as tmp,
        zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED, allowZip64=True) as zf,
    ):
        for k, v in arrays.items():
            # A fixed timestamp: the same arrays give the same bytes (np.savez stamps now).
            info = zipfile.ZipInfo(f"{k}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            with zf.open(info, "w", force_zip64=True) as f:
                _write_member(f, v)


def _write_member(f, v) -> None:
    """One ``.npy`` member: a value with ``blocks()`` and an array over :data:`ROWS_BYTES`
    a block at a time, any other array as ``numpy`` writes it (the same bytes)."""
    if hasattr(v, "blocks"):
        _write_blocks(f, v)
        return
    a = np.asanyarray(v)
    if a.ndim >= 1 and a.nbytes > ROWS_BYTES and a.flags.c_contiguous:
        step = max(1, ROWS_BYTES // max(1, a[:1].nbytes))
        _write_blocks(f, Chain((a[i : i + step] for i in range(0, len(a), step)), a.dtype))
    else:
        np.lib.format.write_array(f, a, allow_pickle=False)


#: Arrays larger than this [bytes] are written a block of rows at a time (``write_array``
#: copies up to 16 MB twice to write one into a compressed member).
ROWS_BYTES = 1 << 20


class Chain:
    """Arrays ``parts`` one after another, as one (N, ...) array of ``dtype`` for
    :func:`save_npz` to write a part at a time (never concatenated in memory)."""

    def __init__(self, parts, dtype):
        self.dtype = np.dtype(dtype)
        self.parts = [np.asarray(p, self.dtype) for p in parts]
        rest = self.parts[0].shape[1:] if self.parts else ()
        self.shape = (sum(len(p) for p in self.parts), *rest)

    def blocks(self):
        a = 0
        for p in self.parts:
            yield a, p
            a += len(p)


def _write_blocks(f, frames) -> None:
    """An ``.npy`` of ``frames`` (C order) written a block at a time, as ``write_array``
    writes the whole array."""
    header = {
        "descr": np.lib.format.dtype_to_descr(frames.dtype),
        "fortran_order": False,
        "shape": frames.shape,
    }
    np.lib.format.write_array_header_1_0(f, header)
    for _, block in frames.blocks():
        f.write(np.ascontiguousarray(block, frames.dtype).tobytes())


def save_json(path: str | os.PathLike, obj, inputs: Iterable[str | os.PathLike] = ()) -> None:
    """Write ``obj`` as indented JSON, atomically."""
    with atomic_path(path, inputs=inputs) as tmp:
        tmp.write_text(json.dumps(obj, indent=1) + "\n")
