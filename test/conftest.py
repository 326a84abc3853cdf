"""Shared test set-up: DDS confined to loopback in a domain of this run, paths to real data."""

from __future__ import annotations

import contextlib
import os
import signal
from collections.abc import Iterator
from pathlib import Path

import pytest

from bridge_shadow.engine import Mapper
from bridge_shadow.paths import repo_root, shared_data_dir
from bridge_shadow.ros.netenv import confine_to_loopback

pytest_plugins = ["twin_fixtures"]

# Network hygiene: set before any test can import rclpy (DESIGN 7).
confine_to_loopback(new_domain=True)
os.environ.setdefault("MPLBACKEND", "Agg")
os.environ.setdefault("AMENT_PREFIX_PATH", os.sys.prefix)
# A suite started as a shell's background job inherits SIGINT ignored; the tests that interrupt the
# command line with SIGINT (test_interrupted_writers.py) need Python's own handler, as in a terminal.
signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.fixture(scope="session")
def munich_data() -> Path:
    """The real munich-bridge-data records in ../shared (read in place, never copied)."""
    path = shared_data_dir()
    assert path.is_dir(), (
        f"real data not found at {path}: clone beside ../shared (or from a checkout that is), "
        "or set BRIDGE_SHADOW_DATA"
    )
    return path


@contextlib.contextmanager
def _engine(processes: bool) -> Iterator[Mapper]:
    """``engine.client_mapper`` of a local cluster of two workers (processes, or threads of this one)."""
    import dask
    import distributed  # noqa: F401  (its defaults first: leaving the ``with`` restores the config as found)

    from bridge_shadow.engine import client_mapper, dask_client

    with (
        dask.config.set({"distributed.admin.tick.interval": "1s"}),
        dask_client(workers=2, processes=processes) as client,
    ):
        yield client_mapper(client)


@pytest.fixture(scope="module")
def engine() -> Iterator[Mapper]:
    """Dask for the seed studies (``engine.client_mapper``): two workers as threads of the test process.

    The suite's two test processes already keep both cores busy, so worker processes would only
    compete with them for the cores and add their own start (about 3.5 s of CPU each, importing
    distributed, scipy and the package). Measured on this 2-core machine, the whole suite with
    threads and with processes: 377-384 s (704-718 s of CPU) against 399-415 s (765-818 s). The
    studies' tasks and results are the same either way; ``process_engine`` is for the tests of
    what crosses a process boundary. One cluster per test file, closed after it: a session's
    cluster idled through every later file, and an idle local cluster costs 0.13 of a core (0.06
    with its event loops' tick monitor every second instead of every 20 ms, which only makes a
    blocked-loop warning late).
    """
    with _engine(processes=False) as mapper:
        yield mapper


@pytest.fixture(scope="module")
def process_engine() -> Iterator[Mapper]:
    """``engine`` with two worker processes: tasks and results pickled across processes."""
    with _engine(processes=True) as mapper:
        yield mapper


@pytest.fixture(scope="session")
def root() -> Path:
    """The source checkout."""
    path = repo_root()
    assert path is not None
    return path
