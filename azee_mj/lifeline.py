"""Workers that never outlive their batch: :func:`lifeline` ends a worker process when the
process that started the batch ends, however it ends (SIGKILL, SIGHUP, a crash).

A worker ended this way first removes the temporary file it was writing (see
:mod:`azee_mj.files`), so a killed batch leaves whole outputs only. Units: seconds.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
import time
from collections.abc import Sequence
from pathlib import Path

#: How often a worker looks whether its batch process is still alive [s].
PERIOD = 0.5
#: The exit status of a worker whose batch process is gone (as if hung up).
EXIT_ORPHANED = 128 + signal.SIGHUP

_LINUX = sys.platform.startswith("linux")


def start_time(pid: int) -> str | None:
    """The start time of process ``pid`` in clock ticks since boot (Linux), ``None`` if it
    is gone or a zombie; telling a process from a later one given the same number."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    fields = stat[stat.rindex(")") + 2 :].split()
    return None if fields[0] in ("Z", "X") else fields[19]


def alive(pid: int, started: str | None) -> bool:
    """Whether process ``pid`` is still the one that had start time ``started``."""
    if _LINUX:
        return started is not None and start_time(pid) == started
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def lifeline(parent: int) -> None:
    """End this process when process ``parent`` (its batch) ends.

    Where ``parent`` started this process itself on Linux, the kernel sends SIGTERM when it
    dies (``PR_SET_PDEATHSIG``). A daemon thread also looks every :data:`PERIOD` seconds
    whether ``parent`` is still the process it was, which covers grandchildren (e.g. the
    workers of a fork server) and other systems; once it is gone, the thread removes the
    temporary file this process was writing and ends the process."""
    if _LINUX and parent == os.getppid():
        import ctypes

        with contextlib.suppress(OSError, AttributeError):
            ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    started = start_time(parent) if _LINUX else None

    def watch() -> None:
        from azee_mj.files import remove_temporaries

        while alive(parent, started):
            time.sleep(PERIOD)
        remove_temporaries()
        os._exit(EXIT_ORPHANED)

    threading.Thread(target=watch, name="azee-mj lifeline", daemon=True).start()


def worker_context(preload: Sequence[str]):
    """The multiprocessing context workers start from: ``forkserver`` where there is one,
    its server started now with ``preload`` imported once (not in every worker), else
    ``spawn``. The server starts with ``PYTHONSAFEPATH``: without it, Python (3.11) puts
    the working folder first on the server's module path, so a user's ``timeit.py`` or
    ``random.py`` there would be imported (run) instead of the standard module."""
    import multiprocessing
    import multiprocessing.forkserver

    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload(list(preload))
    old = os.environ.get("PYTHONSAFEPATH")
    os.environ["PYTHONSAFEPATH"] = "1"
    try:
        multiprocessing.forkserver.ensure_running()
    finally:
        if old is None:
            del os.environ["PYTHONSAFEPATH"]
        else:
            os.environ["PYTHONSAFEPATH"] = old
    return ctx
