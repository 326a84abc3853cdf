"""Shared test set-up: DDS confined to loopback in a domain of this run, paths to real data."""

from __future__ import annotations

import os
import signal
from pathlib import Path

import pytest

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


#: The longest test files, heaviest first (seconds of test time on this 2-core machine, a whole
#: suite on 2026-11-30: 106, 57, 45, 29, 28, 20, 18, 16, 15, 15, 13, 13; the other 62 files 2-11 s
#: each, 570 s in all). ``make test`` hands whole files to its two processes in collection order
#: (``--dist loadfile --no-loadscope-reorder``); with these first, the small files fill the gaps
#: and the two finish within seconds of each other. xdist's own order (files by their number of
#: tests) started the node's 57 s file near the end: one process ran 294 s of tests, the other 276.
HEAVIEST_FIRST = (
    "test_loadtest_days.py",
    "test_ros_node.py",
    "test_archive.py",
    "test_estimate_coverage.py",
    "test_engine.py",
    "test_estimate_pipeline.py",
    "test_ramp.py",
    "test_import_csv.py",
    "test_gap_twin.py",
    "test_gap_realdata.py",
    "test_estimate_events.py",
    "test_gap_detection.py",
)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Run the files of ``HEAVIEST_FIRST`` first, in that order; the rest keep theirs (a stable sort)."""
    rank = {name: i for i, name in enumerate(HEAVIEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))


@pytest.fixture(scope="session")
def munich_data() -> Path:
    """The real munich-bridge-data records in ../shared (read in place, never copied)."""
    path = shared_data_dir()
    assert path.is_dir(), (
        f"real data not found at {path}: clone beside ../shared (or from a checkout that is), "
        "or set BRIDGE_SHADOW_DATA"
    )
    return path


@pytest.fixture(scope="module")
def engine():
    """A Dask engine for the seed studies (``engine.client_mapper``): one worker thread of this process.

    The suite's two test processes keep both cores busy, so worker processes of its own only
    contend for them: back to back, ``test_loadtest_days.py`` and ``test_estimate_coverage.py`` in
    one process took 154 s of CPU with one worker thread against 170 s with two worker processes
    (2026-11-29; two threads fight for the GIL and took more). The tasks still go through Dask's
    scatter, map and gather; worker processes run in ``test_engine.py`` (twin days pickled to one),
    ``test_archive.py`` (the command's default cluster) and ``test_synth_stream.py`` (an archive
    written on two). One cluster per test file, closed after it; its event loop's tick
    monitor every second instead of every 20 ms (which only makes a blocked-loop warning late).
    """
    import dask
    import distributed  # noqa: F401  (its defaults first: leaving the ``with`` restores the config as found)

    from bridge_shadow.engine import client_mapper, dask_client

    with (
        dask.config.set({"distributed.admin.tick.interval": "1s"}),
        dask_client(workers=1, processes=False) as client,
    ):
        yield client_mapper(client)


@pytest.fixture(scope="session")
def root() -> Path:
    """The source checkout."""
    path = repo_root()
    assert path is not None
    return path
