"""``replay --live --watch``: the node's output topics as one line a second on the terminal.

The ros2 command-line tools (``ros2 topic echo``) are not on the package index the venv installs
from, so the live replay shows what a person would watch with them: the latest posterior
settlements with their 95 % intervals, the temperature-compensated forces with the window they
close, and the level of the settlement diagnostics. It reads the messages the live replay's
``Player`` records from the node's output topics (the same DDS graph, no extra subscriber).
"""

from __future__ import annotations

import sys
import time
from typing import Any, TextIO

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
from rclpy.serialization import deserialize_message
from std_msgs.msg import Float64MultiArray

from bridge_shadow.contract import (
    CHANNELS,
    COMPENSATED_TOPICS,
    COVARIANCE_TOPIC,
    DIAGNOSTICS_TOPIC,
    MEAN_TOPIC,
)
from bridge_shadow.ros.convert import array_from_msg
from bridge_shadow.timefmt import iso_utc

__all__ = ["TopicWatch", "watch_line"]

_LEVEL = {0: "OK", 1: "WARN", 2: "ERROR", 3: "STALE"}


def _last(records: dict[str, list[tuple[int, bytes]]], topic: str, msg_type: Any) -> Any:
    items = records.get(topic) or []
    return deserialize_message(items[-1][1], msg_type) if items else None


def watch_line(records: dict[str, list[tuple[int, bytes]]], fraction: float | None = None) -> str:
    """One line of the latest outputs in ``records`` (contract topic -> [(receive_ns, raw)]).

    Example: ``[ 42%] window to 2022-03-15T06:13Z: south +0.702 ± 0.031 mm, north -0.688 ±
    0.029 mm | compensated 238.91 / 238.87 kN | settlement OK | 1207 windows``.
    """
    head = f"[{100 * fraction:3.0f}%] " if fraction is not None else ""
    n = len(records.get(MEAN_TOPIC) or [])
    mean_msg = _last(records, MEAN_TOPIC, Float64MultiArray)
    if mean_msg is None:
        return head + "no window closed yet"
    mean, _ = array_from_msg(mean_msg)
    cov_msg = _last(records, COVARIANCE_TOPIC, Float64MultiArray)
    sd = np.full(2, np.nan)
    if cov_msg is not None:
        cov, _ = array_from_msg(cov_msg)
        sd = np.sqrt(np.clip(np.diag(np.asarray(cov).reshape(2, 2)), 0.0, None))
    parts = [
        ", ".join(
            f"{side} {1e3 * m:+.3f} ± {1e3 * 1.96 * s:.3f} mm"
            for side, m, s in zip(("south", "north"), mean, sd, strict=True)
        )
    ]
    wrenches = [_last(records, COMPENSATED_TOPICS[ch], WrenchStamped) for ch in CHANNELS]
    when = ""
    if all(w is not None for w in wrenches):
        stamp = wrenches[0].header.stamp
        when = f"window to {iso_utc(stamp.sec * 1_000_000_000 + stamp.nanosec)}: "
        parts.append("compensated " + " / ".join(f"{w.wrench.force.z / 1e3:.2f}" for w in wrenches) + " kN")
    diag = _last(records, DIAGNOSTICS_TOPIC, DiagnosticArray)
    if diag is not None:
        for status in diag.status:
            if status.name.endswith("settlement"):
                level = status.level[0] if isinstance(status.level, bytes) else int(status.level)
                parts.append(f"settlement {_LEVEL.get(level, level)}")
    parts.append(f"{n} windows")
    return head + when + " | ".join(parts)


class TopicWatch:
    """A progress callback that prints ``watch_line`` at most every ``period_s`` (and at the end)."""

    def __init__(
        self, records: dict[str, list[tuple[int, bytes]]], period_s: float = 1.0, stream: TextIO | None = None
    ) -> None:
        self.records = records
        self.period_s = float(period_s)
        self.stream = stream if stream is not None else sys.stderr
        self._shown = -float("inf")

    def __call__(self, fraction: float) -> None:
        """Show the line if ``period_s`` has passed since the last one, or at the end."""
        now = time.monotonic()
        if fraction < 1.0 and now - self._shown < self.period_s:
            return
        self._shown = now
        self.show(fraction)

    def show(self, fraction: float | None = None) -> None:
        """Print the line now."""
        print(watch_line(self.records, fraction), file=self.stream, flush=True)
