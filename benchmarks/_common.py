"""Helpers shared by the benchmark scripts (imported as ``_common``: the scripts run from this folder)."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

__all__ = ["DEMO_EFFECTS", "best_of", "rosbags_raw"]

#: The effects of bags/demo_3d (see bags/README.md): the paper-like offset, sun-driven gradients, test car.
DEMO_EFFECTS: dict[str, float] = {
    "settlement_offset": 7e-4,
    "vertical_gradient": 4.0,
    "transverse_gradient": 3.0,
    "traffic": 2.5e4,
}


def best_of(repeat: int, fn: Callable[[], Any]) -> tuple[float, Any]:
    """Return the shortest wall time of ``repeat`` calls and the last result."""
    best, result = float("inf"), None
    for _ in range(repeat):
        t0 = time.perf_counter()
        result = fn()
        best = min(best, time.perf_counter() - t0)
    return best, result


def rosbags_raw(path: Path) -> int:
    """Baseline: iterate rosbags' ``Reader.messages()`` (bytes only, no decoding); return the count."""
    from rosbags.rosbag2 import Reader

    n = 0
    with Reader(path) as reader:
        for _ in reader.messages():
            n += 1
    return n
