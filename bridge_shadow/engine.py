"""The Dask engine of every job that scales out: archives, gap folds, calibration explanations, seed studies.

``dask_client`` starts a local cluster on loopback (``127.0.0.1``), one single-threaded worker
per core (the work is Python and numpy: processes, not threads, share the cores), or connects
to a running scheduler (``tcp://HOST:PORT``). ``client_mapper`` turns a client into the plain
``mapper(fn, items) -> list`` that the functional core takes where it loops over independent
pieces (``gap.fit.held_out``, ``calibrate.calibrate``); the built-in ``map`` is the serial one.
Nothing of the scheduling is written here: Dask's ``map``, ``submit`` and ``gather`` do it.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import os
from collections.abc import Callable, Iterable, Iterator
from typing import Any

from bridge_shadow.errors import InputError

__all__ = [
    "CONNECT_TIMEOUT_S",
    "Mapper",
    "add_engine_options",
    "check_engine_options",
    "client_mapper",
    "dask_client",
    "optional_mapper",
    "serial_mapper",
]

#: ``mapper(fn, items)``: ``[fn(x) for x in items]``, in order, computed however the mapper likes.
Mapper = Callable[[Callable[[Any], Any], Iterable[Any]], list[Any]]

#: Seconds to wait for a scheduler named by ``--scheduler`` before giving up with one line.
CONNECT_TIMEOUT_S = 10.0

#: What a local worker logs, as an ERROR with a traceback, when the cluster's close shuts the
#: scheduler's side of a heartbeat still in flight (a race of Dask's own shutdown, dask/distributed
#: issues 7105 and 7192): seen at the end of long runs, nothing of the job's.
HEARTBEAT_AT_CLOSE = "Failed to communicate with scheduler during heartbeat."


class _HeartbeatAtClose(logging.Filter):
    """Drop ``HEARTBEAT_AT_CLOSE`` (installed on a local cluster's workers: ``dask_setup``)."""

    def filter(self, record: logging.LogRecord) -> bool:
        return record.getMessage() != HEARTBEAT_AT_CLOSE


@contextlib.contextmanager
def dask_client(
    scheduler: str | None = None, workers: int | None = None, processes: bool = True
) -> Iterator[Any]:
    """Yield a ``distributed.Client``: of a new local cluster, or of the scheduler at ``scheduler``.

    Args:
        scheduler: ``tcp://host:port`` of a running scheduler (None: a local cluster).
        workers: local workers (default: one per core, ``os.cpu_count()``).
        processes: local workers as processes (the default) or as threads of this process
            (tests: no start-up cost; the Python work then shares one core).

    Raises:
        InputError: the scheduler cannot be reached, or ``workers`` is not positive.

    """
    import dask
    from distributed import Client, LocalCluster

    if scheduler:
        try:
            client = Client(scheduler, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError, ValueError) as err:
            raise InputError(f"cannot reach the Dask scheduler at {scheduler} ({err})") from None
        # the filter outlives the client: the interrupted call's cancel runs on the loop thread, at
        # the latest before the client's close (the loop's callbacks run in order)
        with _filtered(logging.getLogger("tornado.application"), _SyncCancelFailure()), client:
            yield client
        return
    n = workers if workers is not None else (os.cpu_count() or 1)
    if n < 1:
        raise InputError(f"--workers must be at least 1 (got {n})")
    where = {"host": "127.0.0.1"} if processes else {}
    # Dask's nanny starts workers with MALLOC_TRIM_THRESHOLD_=65536, which hands every freed numpy
    # buffer back to the kernel: decoding a bag (large short-lived arrays) then runs 1.35x slower
    # (benchmarks/archive_scale.py). glibc's own adaptive threshold instead; a worker's memory is
    # bounded by one bag's reduction anyway.
    environ = {k: v for k, v in dask.config.get("distributed.nanny.pre-spawn-environ").items()}
    environ.pop("MALLOC_TRIM_THRESHOLD_", None)
    with (
        # first, so removed last: the interrupted call's cancel runs on the loop thread, and the
        # block's exit went on to remove the filter before it ran (a CI run under load printed
        # distributed's traceback after the command's line); by the client's close it has run
        _filtered(logging.getLogger("tornado.application"), _SyncCancelFailure()),
        dask.config.set(
            {
                "distributed.nanny.pre-spawn-environ": environ,
                # the workers' statistical profiler samples the task thread's stack every 10 ms,
                # under the GIL of a task that is pure Python half the time: off
                "distributed.worker.profile.enabled": False,
                # Ctrl-C reaches the whole process group: each worker printed a KeyboardInterrupt
                # traceback (25-100 lines) after the command's one line; this module's dask_setup
                # has them ignore it (this process closes the cluster on its way out)
                "distributed.worker.preload": [__name__] if processes else [],
                # workers forked from one server process that has imported Dask and numpy once,
                # not each started anew (spawn): three clusters of two workers in one process
                # took 2.2-2.4 s instead of 4.7-5.1 s (scratch); the same workers, the same tasks
                "distributed.worker.multiprocessing-method": "forkserver",
            }
        ),
        LocalCluster(
            n_workers=n,
            threads_per_worker=1,
            processes=processes,
            # its HTTP servers (health and metrics; no dashboard without bokeh) on loopback too
            dashboard_address="127.0.0.1:0",
            worker_dashboard_address="127.0.0.1:0",
            silence_logs=logging.ERROR,
            **where,
        ) as cluster,
        Client(cluster) as client,
    ):
        try:
            yield client
        except KeyboardInterrupt:
            # the interrupted gather's tasks die with the client: asyncio would log each as "Task
            # exception was never retrieved" (AllExit), dozens of lines after the CLI's one
            logging.getLogger("asyncio").setLevel(logging.CRITICAL)
            raise


class _SyncCancelFailure(logging.Filter):
    """Drop tornado's report of distributed's own failing cancel after an interrupted ``sync``.

    On Ctrl-C distributed's ``sync()`` cancels its future from a loop callback that raises
    (``NameError: cannot access free variable 'future'``, a bug of distributed's); tornado logs it
    with its traceback, 15 lines after the command's one, whenever the call's coroutine had not
    started. The callback runs on the loop thread, possibly after the interrupted block's exit
    began: the filter is installed before the client and removed after its close.
    """

    def filter(self, record: logging.LogRecord) -> bool:
        """Keep every record but that one."""
        exc = record.exc_info[1] if record.exc_info else None
        return not (isinstance(exc, NameError) and "sync.<locals>.cancel" in record.getMessage())


@contextlib.contextmanager
def _filtered(logger: logging.Logger, flt: logging.Filter) -> Iterator[None]:
    """Install ``flt`` on ``logger`` for the block."""
    logger.addFilter(flt)
    try:
        yield
    finally:
        logger.removeFilter(flt)


def dask_setup(worker: Any) -> None:
    """Dask preload hook, run in each local worker process as it starts.

    SIGINT is the client's to handle (its close ends the workers), and the heartbeat that meets
    the close, at the end of a job or of an interrupted one, is not an error of the job's.
    """
    import signal
    import threading

    logging.getLogger("distributed.worker").addFilter(_HeartbeatAtClose())
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)


def serial_mapper(fn: Callable[[Any], Any], items: Iterable[Any]) -> list[Any]:
    """Apply ``fn`` to each item in this process, in order (the default mapper)."""
    return [fn(x) for x in items]


def client_mapper(client: Any) -> Mapper:
    """Return a mapper that runs ``fn`` on the items as Dask tasks of ``client`` (results in order)."""

    def mapper(fn: Callable[[Any], Any], items: Iterable[Any]) -> list[Any]:
        # the items go to the workers once, as data, not inside the task graph; under keys of their
        # own (hash=False): with content keys, equal items scattered by the previous call (fold 0,
        # 1, 2 of every candidate) share its keys, and its release can drop them under this call's
        # tasks, cancelled for "lost dependencies" (seen once in `gap --scheduler`; dask/distributed
        # issue 4612)
        return client.gather(client.map(fn, client.scatter(list(items), hash=False), pure=False))

    return mapper


def add_engine_options(parser: argparse.ArgumentParser, what: str) -> None:
    """Add ``--workers N`` and ``--scheduler ADDR`` for a job whose ``what`` may run on Dask.

    Without either the job runs here, one piece after the other (``optional_mapper``).
    """
    parser.add_argument(
        "--workers",
        type=int,
        metavar="N",
        help=f"{what} in parallel on a local Dask cluster of N processes (the same results); "
        "default: one after the other here",
    )
    parser.add_argument(
        "--scheduler", metavar="ADDR", help=f"{what} on a running Dask scheduler (tcp://HOST:PORT)"
    )


def check_engine_options(scheduler: str | None, workers: int | None) -> None:
    """InputError (one line) when both a local cluster's size and a scheduler are given."""
    if workers is not None and scheduler:
        raise InputError("--workers sizes the local cluster; a --scheduler has its own workers")


@contextlib.contextmanager
def optional_mapper(scheduler: str | None, workers: int | None) -> Iterator[Mapper | None]:
    """Yield a Dask mapper when ``--scheduler`` or ``--workers`` asks for one, else None (serial)."""
    check_engine_options(scheduler, workers)
    if workers is None and not scheduler:
        yield None
        return
    with dask_client(scheduler, workers) as client:
        yield client_mapper(client)
