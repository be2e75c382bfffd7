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


def _connect(distributed, scheduler: str):
    shown = shorten(scheduler, 100)
    if scheduler.endswith(".json"):
        if not os.path.isfile(scheduler):
            raise AzeeError(f"--scheduler {shown}: no such scheduler file")
        kwargs: dict[str, Any] = {"scheduler_file": scheduler}
    else:
        kwargs = {"address": scheduler}
    try:
        return distributed.Client(**kwargs, timeout=CONNECT_TIMEOUT)
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
