"""``bridge_shadow.ros.main`` with the window-closing drains timed by part (``live_latency.py --parts``).

Run as ``python -m _node_parts [node arguments]`` with this folder on ``PYTHONPATH``. Every drain
that publishes a window is timed: the whole drain, its decode-and-ingest, and the time from its
start to the window's first posterior message (what the latency measures on the node's side).
At exit the rows (ms) go to the JSON file named by ``BRIDGE_SHADOW_PARTS_OUT``.

``closing_parts_in_process`` feeds the same messages through the same node's subscription
callbacks in one process (no DDS traffic in, the drain timer called every 50 ms of the stream): the
node's own code, the baseline the DDS run is read against. Fed as fast as it goes, the close runs
warm, back to back; paced (``tick_s``: each tick waits for its time, as the player's), it runs
once every window's 0.1 s of wall clock, as in the node.
"""

from __future__ import annotations

import atexit
import json
import os
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from bridge_shadow.ros import main as node_main
from bridge_shadow.ros.node import ShadowNode

__all__ = ["PARTS", "closing_parts_in_process", "time_closing_drains"]

#: The timed parts of a window-closing drain, in the rows' order (ms).
PARTS = ("drain", "ingest", "to_first_publish")


def time_closing_drains(node_class: type[ShadowNode] = ShadowNode) -> list[tuple[float, float, float]]:
    """Wrap the class's drain, ingest and posterior publishing; return the list the rows go to."""
    rows: list[tuple[float, float, float]] = []
    now: dict[str, float] = {}
    drain, ingest, publish = node_class.drain, node_class.ingest_pending, node_class._publish_posterior

    def timed_drain(self: ShadowNode, everything: bool = False) -> None:
        now.clear()
        t0 = now["t0"] = time.perf_counter()
        published = self.windows_published
        drain(self, everything)
        if self.windows_published > published and "pub" in now:
            ms = 1e3
            rows.append(((time.perf_counter() - t0) * ms, now["ingest"] * ms, (now["pub"] - t0) * ms))

    def timed_ingest(self: ShadowNode, everything: bool = False) -> None:
        t = time.perf_counter()
        ingest(self, everything)
        now["ingest"] = time.perf_counter() - t

    def timed_publish(self: ShadowNode, *args: Any) -> None:
        now.setdefault("pub", time.perf_counter())
        publish(self, *args)

    node_class.drain = timed_drain  # type: ignore[method-assign]
    node_class.ingest_pending = timed_ingest  # type: ignore[method-assign]
    node_class._publish_posterior = timed_publish  # type: ignore[method-assign]
    return rows


def closing_parts_in_process(
    args: Sequence[str],
    streams: Sequence[Sequence[bytes]],
    temp_every: int,
    drain_every: int,
    tick_s: float = 0.0,
) -> list[tuple[float, float, float]]:
    """Feed ``streams`` (frc_01, frc_02, air) through one node's callbacks in-process; return the rows.

    ``args``: the node's command line (``--ros-args -p name:=value ...``), read by rclpy as the node
    process reads it.

    Tick ``j`` delivers the air message ``j // temp_every`` when ``j % temp_every == 0``, then
    frc_01 and frc_02 of tick ``j``; the drain timer runs every ``drain_every`` ticks (half-way
    between window ends). With ``tick_s`` > 0, tick ``j`` waits (sleeping) until ``j * tick_s``
    after the first: the stream's pace in wall-clock time.
    """
    import rclpy

    class Timed(ShadowNode):
        pass

    rows = time_closing_drains(Timed)
    rclpy.init(args=["_node_parts", *args])
    try:
        node = Timed()
        f1, f2, air = (sub.callback for sub in node._subs)
        t0 = time.perf_counter()
        for j in range(len(streams[0])):
            lag = t0 + j * tick_s - time.perf_counter()
            if lag > 0.0:
                time.sleep(lag)
            if j % temp_every == 0:
                air(streams[2][j])
            f1(streams[0][j])
            if j % drain_every == drain_every // 2:
                node._on_drain_timer()
            f2(streams[1][j])
        node.destroy_node()
    finally:
        rclpy.try_shutdown()
    return rows


if __name__ == "__main__":
    timed = time_closing_drains()
    out = os.environ.get("BRIDGE_SHADOW_PARTS_OUT")
    if out:
        atexit.register(lambda: Path(out).write_text(json.dumps({"parts": PARTS, "rows": timed})))
    raise SystemExit(node_main.main())
