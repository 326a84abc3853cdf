"""Feed chunks through a ``Shadow`` by its public methods, as ``Shadow.run`` does, with timings."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from bridge_shadow.bagio.cdr import frame_value
from bridge_shadow.replay.chunks import FeedChunk

__all__ = ["StreamReplay", "feed_shadow"]


@dataclass
class StreamReplay:
    """What a streamed replay measured besides the shadow's own result.

    Attributes:
        messages: input messages fed.
        pipeline_s: wall seconds inside the shadow's methods (ingest, poll, flush).
        read_s: wall seconds the shadow waited for data: opening, reading, decoding the bag and
            cutting chunks (with a prefetching reader, only what it did not overlap).
        reader_s: wall seconds of reading work (opening included), overlapped or not.
        write_s: wall seconds handing outputs on (``--out`` bag, plot history).
        windows_out: window outputs produced (all of them, whatever was kept).
        backend: how the bag was read (``sqlite3``, ``mcap`` or ``rosbags``).
        closed_at_end, updates_at_end: windows closed and updates made by the end-of-data close
            (``replay_bag``): a replay resumed from a checkpoint written before it makes them again.
        held_air: air messages past the last force that the checkpoint holds unfed (``air_tail``);
            fed for this result too, and again, merged, by the next bag's replay.
        checkpoint_kept: the checkpoint resumed from was left as it was: the bag had load-cell
            messages and none was used (data older than the checkpoint's: ``replay_bag``).
        forces: load-cell messages fed (``replay_bag``; the rest is air).

    """

    messages: int = 0
    pipeline_s: float = 0.0
    read_s: float = 0.0
    reader_s: float = 0.0
    write_s: float = 0.0
    windows_out: int = 0
    backend: str = ""
    closed_at_end: int = 0
    updates_at_end: int = 0
    held_air: int = 0
    checkpoint_kept: bool = False
    forces: int = 0


def _frames_arg(frames: np.ndarray) -> np.ndarray | str:
    """Return the frame_id argument of ``ingest_*``: the value of a uniform view, else the array."""
    value = frame_value(frames)
    return frames if value is None else value


def feed_shadow(
    shadow: Any,
    chunks: Iterable[FeedChunk],
    on_outputs: Callable[[list[Any]], None] | None = None,
    progress: Callable[[int], None] | None = None,
    flush: bool = True,
    before_flush: Callable[[], Any] | None = None,
) -> StreamReplay:
    """Feed chunks through ``shadow`` (ingest per topic, then poll; flush at the end).

    Args:
        shadow: an ``estimate.Shadow`` (only its public methods are used).
        chunks: from ``arrival_chunks``.
        on_outputs: called with each non-empty list of closed-window outputs, in order.
        progress: called with the log time (ns) of the last message fed, after each chunk.
        flush: close the open windows at the end (end of a replay).
        before_flush: called just before that close (the checkpoint of a replay: its state then).

    Returns:
        counts and timings (``pipeline_s`` is the time inside the shadow; the rest, until the
        chunks iterator is exhausted, is ``read_s``).

    """
    stats = StreamReplay()
    it = iter(chunks)
    clock = time.perf_counter
    while True:
        t0 = clock()
        feed = next(it, None)
        t1 = clock()
        stats.read_s += t1 - t0
        if feed is None:
            break
        # one frame_id for a whole topic (the usual case) goes in as a str: no work per message
        for c, (stamp, force, frame) in enumerate(feed.forces):
            if len(stamp):
                shadow.ingest_forces(c, stamp, force, _frames_arg(frame))
        stamp, temp, frame = feed.temperature
        if len(stamp):
            shadow.ingest_temperature(stamp, temp, _frames_arg(frame))
        outs = shadow.poll()
        t2 = clock()
        stats.pipeline_s += t2 - t1
        stats.messages += feed.messages
        if outs:
            stats.windows_out += len(outs)
            if on_outputs is not None:
                on_outputs(outs)
        if progress is not None:
            progress(feed.last_log_ns)
        stats.write_s += clock() - t2
    if flush:
        if before_flush is not None:
            before_flush()
        t0 = clock()
        outs = shadow.flush()
        t1 = clock()
        stats.pipeline_s += t1 - t0
        if outs:
            stats.windows_out += len(outs)
            if on_outputs is not None:
                on_outputs(outs)
        stats.write_s += clock() - t1
    return stats
