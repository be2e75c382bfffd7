"""Dask for many machines: run calls on a Dask cluster, on this machine or on many.

Needs the ``cluster`` extra (``pip install 'azee_mj[cluster]'``: dask and distributed).
:func:`open_client` gives a ``distributed.Client`` for ``local`` (a cluster of worker
processes on this machine, started here and ended with this process) or for an existing
scheduler (its address, e.g. ``tcp://10.0.0.5:8786``, or the scheduler file a job queue
wrote); :func:`as_completed_on` runs calls on it and yields each result as it ends. Workers
of a remote cluster must see the input and output files at the same paths (a shared file
system); see ``docs/cluster.md``. Units: seconds.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import uuid
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from azee_mj.errors import AzeeError, shorten

#: Seconds to wait for a scheduler to answer before giving up.
CONNECT_TIMEOUT = 20.0
#: What the command line accepts for a cluster started here.
LOCAL = "local"


def require():
    """The ``distributed`` module; :class:`AzeeError` saying how to install it if missing."""
    try:
        import distributed
    except ImportError:
        raise AzeeError(
            "--scheduler needs Dask: install the cluster extra (pip install 'azee_mj[cluster]')"
        ) from None
    return distributed


def _lifeline_plugin(distributed, parent: int):
    """A worker plugin that ends each worker process with process ``parent``."""

    class Lifeline(distributed.WorkerPlugin):
        name = "azee-mj-lifeline"

        def setup(self, worker) -> None:
            from azee_mj.lifeline import lifeline

            lifeline(parent)

    return Lifeline()


@contextlib.contextmanager
def open_client(scheduler: str, workers: int = 1) -> Iterator[Any]:
    """A ``distributed.Client``: for ``scheduler`` ``"local"``, on a new cluster of
    ``workers`` processes of one thread each on this machine (closed on exit; its workers
    also end if this process is killed); otherwise connected to the scheduler at that
    address or described by that scheduler file (``.json``), which is left running.
    Raises :class:`AzeeError` for an empty ``scheduler``, when Dask is missing or when the
    scheduler does not answer."""
    if not scheduler.strip():
        raise AzeeError(
            "--scheduler is empty; give 'local', an address such as tcp://HOST:8786, or a "
            "scheduler file (.json)"
        )
    distributed = require()
    with contextlib.ExitStack() as stack:
        if scheduler == LOCAL:
            cluster = stack.enter_context(
                distributed.LocalCluster(
                    n_workers=workers,
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address=None,
                    silence_logs=logging.ERROR,
                )
            )
            client = stack.enter_context(distributed.Client(cluster))
            client.register_plugin(_lifeline_plugin(distributed, os.getpid()))
        else:
            client = stack.enter_context(_connect(distributed, scheduler))
        yield client


#: Largest scheduler file read [bytes] (Dask writes a few hundred).
MAX_SCHEDULER_FILE = 2**20


def scheduler_file_address(path: str) -> str:
    """The scheduler address in the scheduler file ``path`` (the JSON object a scheduler
    started with ``--scheduler-file`` writes); :class:`AzeeError` saying what is wrong with
    a file that is missing, not a regular file, too large, or not such an object (Dask
    itself would wait, then fail with an internal error)."""
    shown = shorten(path, 100)
    if not os.path.exists(path):
        raise AzeeError(f"--scheduler {shown}: no such scheduler file")
    hint = "give the file a scheduler wrote (dask scheduler --scheduler-file FILE.json)"
    if not os.path.isfile(path):  # a fifo or /dev/zero: never read
        raise AzeeError(f"--scheduler {shown}: not a regular file; {hint}")
    try:
        with open(path, "rb") as f:
            data = f.read(MAX_SCHEDULER_FILE + 1)
    except OSError as e:
        raise AzeeError(f"--scheduler {shown}: cannot read the scheduler file ({e.strerror})")
    if len(data) > MAX_SCHEDULER_FILE:
        raise AzeeError(
            f"--scheduler {shown}: over {MAX_SCHEDULER_FILE // 2**20} MB, not a scheduler "
            f"file; {hint}"
        )
    try:
        info = json.loads(data.decode("utf-8"))
    except ValueError:  # also UnicodeDecodeError
        info = None
    address = info.get("address") if isinstance(info, dict) else None
    if not isinstance(address, str) or not address.strip():
        raise AzeeError(
            f'--scheduler {shown}: not a scheduler file (a JSON object with an "address" '
            f"text); {hint}"
        )
    return address


def _connect(distributed, scheduler: str):
    shown = shorten(scheduler, 100)
    address = scheduler_file_address(scheduler) if scheduler.endswith(".json") else scheduler
    try:
        return distributed.Client(address=address, timeout=CONNECT_TIMEOUT)
    except (OSError, TimeoutError, ValueError, TypeError) as e:
        what = shorten(str(e).splitlines()[0] if str(e) else type(e).__name__, 120)
        raise AzeeError(
            f"--scheduler {shown}: cannot reach a Dask scheduler ({what}); give 'local', "
            "an address such as tcp://HOST:8786, or a scheduler file (.json)"
        ) from None


def as_completed_on(
    client: Any,
    calls: Sequence[tuple[Callable, tuple, str]],
    priority: Sequence[int] | None = None,
) -> Iterator[tuple[int, Any]]:
    """Run every ``(function, args, name)`` of ``calls`` on ``client``'s workers; yield
    ``(index, result)`` as each ends, the exception as the result of a call that failed
    (e.g. whose worker died). Calls of higher ``priority`` start first. Closing the iterator
    early (an exception, Ctrl-C) cancels the calls not finished."""
    distributed = require()
    run = uuid.uuid4().hex[:8]
    futures = {
        client.submit(
            fn,
            *args,
            key=f"azee-mj-{name}-{run}",
            priority=priority[i] if priority else 0,
            pure=False,
        ): i
        for i, (fn, args, name) in enumerate(calls)
    }
    try:
        for future in distributed.as_completed(futures):
            try:
                result = future.result()
            except Exception as e:  # noqa: BLE001 - the worker's failure is the result
                result = e
            yield futures[future], result
            future.release()
    finally:
        client.cancel([f for f in futures if not f.done()])
