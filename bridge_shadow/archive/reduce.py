"""Reduce one bag of an archive, on its own: decode, gate and close its 60 s windows (the parallel part).

A bag is read as ``replay`` reads it (``bagio.stream.MonitoringStream``, arrival order, bounded
memory) and fed to a shadow of its own that starts fresh at the bag's first message and only
gates and windows (``Shadow.close_windows``, never the estimator). That shadow cannot know what
the bags before left in the gates (last stamps, a message held after a gap, a clock jump waiting
for confirmation) or in the window buffer (samples of a window that straddles the seam, the last
temperature reading before it). So the reduction keeps what the sequential join needs to take
the bag over exactly (``archive.join``):

- the *head*: the messages of the bag's first ``HEAD_WINDOWS`` windows of log time, one feed
  chunk per window, and a snapshot of the front end (``FrontState``) after each chunk;
- every window closed after each chunk (``closed_at``: the chunk index, ``len(head)`` for later);
- the front end after the whole bag (``end``): gates, open windows, bookkeeping.

The join feeds the head to the archive's shadow until its front end behaves as this one's at a
snapshot; from there on this one's windows and end state are the archive's, to the bit.

``HEAD_WINDOWS``: after a seam the two front ends agree once (1) every window holding samples
of the bag before has closed (one window, plus up to ``topic_timeout_s`` for the slowest topic),
(2) each gate has taken two messages of this bag (its last step), also after a gap (the first
message after a gap is held for one message) or a clock jump (``clock_jump_confirm`` = 2
messages), and (3) the temperature kept as the left bracket is a reading of this bag: with
readings once a minute, two windows. Ten windows (10 min of log time) cover that with room for
a slower temperature topic; a bag whose seam does not settle within them is fed whole by the
join (exact, only slower), and the join counts it. With the traffic screen on, (4) a record that
runs through the seam is held by the bag's fresh front end until it passes ``traffic_hold_s``
and is released as the archive's was, so the head grows by that hold (``head_windows``); and a
silence of a few minutes in it (a recording that started again, ``_Record.resume``) holds it on
for a hold after that silence, so the head goes on, a window at a time, while the fresh front end
still holds its first record, up to ``head_windows`` more (without it 24 of the 30 daily bags of
the 1 Hz benchmark archive, whose sensors drop out for minutes, were fed whole).
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bridge_shadow.archive.frontstate import FrontState, front_state
from bridge_shadow.estimate.inputs.windows import WindowBatch
from bridge_shadow.replay.chunks import DEFAULT_CHUNK, FeedChunk, arrival_chunks
from bridge_shadow.replay.feed import feed_shadow
from bridge_shadow.series import ForceSeries, MonitoringData, TemperatureSeries

__all__ = ["HEAD_WINDOWS", "BagReduction", "head_windows", "reduce_bag", "split_log", "take_head"]

#: Windows of log time at a bag's start fed again by the join (see the module docstring).
HEAD_WINDOWS = 10


@dataclass
class BagReduction:
    """What the join needs of one bag (see the module docstring).

    Attributes:
        bag: the bag's path (of a merged unit: its first bag, and ``bags`` holds them all).
        messages: input messages read (all three topics).
        first_log_ns, last_log_ns: log-time span of the bag (None when it holds no input message).
        head_end_ns: log time at which the head ends (the rest starts there), or None.
        head: one feed chunk per head window (an empty chunk where the window held no message).
        snapshots: the front end after each head chunk and its poll, ``len(head)`` of them.
        windows: every window the bag's own front end closed, in window order.
        closed_at: (n,) int64, after which chunk each window closed (``len(head)``: later).
        end: the front end after the whole bag (its last poll; open windows stay open).
        backend: how the bag was read; seconds: wall time of the reduction.

    """

    bag: str
    messages: int = 0
    first_log_ns: int | None = None
    last_log_ns: int | None = None
    head_end_ns: int | None = None
    head: list[FeedChunk] = field(default_factory=list)
    snapshots: list[FrontState] = field(default_factory=list)
    windows: WindowBatch = field(default_factory=WindowBatch.empty)
    closed_at: np.ndarray = field(default_factory=lambda: np.empty(0, np.int64))
    end: FrontState | None = None
    backend: str = ""
    seconds: float = 0.0
    #: the bags read as one merged stream when they overlap in time (``bag`` is the first); a
    #: class default, so a reduction cached before the field existed reads as one bag
    bags: tuple[str, ...] = ()

    def windows_after(self, j: int) -> WindowBatch:
        """Return the windows closed after head chunk ``j`` (by later chunks of this bag)."""
        return self.windows.select(self.closed_at > j)


def _force_slice(s: ForceSeries, sl: slice) -> ForceSeries:
    return ForceSeries(s.stamp_ns[sl], s.force_n[sl], s.frame_id[sl], s.log_ns[sl])


def split_log(piece: MonitoringData, cut_ns: int) -> tuple[MonitoringData, MonitoringData]:
    """Split a piece at a log time: (messages with log time < ``cut_ns``, the others).

    Arrival order is log time first, so the first part wholly precedes the second.
    """
    forces_a, forces_b = {}, {}
    for ch, s in piece.forces.items():
        i = int(np.searchsorted(s.log_ns, cut_ns, side="left"))
        forces_a[ch], forces_b[ch] = _force_slice(s, slice(0, i)), _force_slice(s, slice(i, None))
    t = piece.temperature
    i = int(np.searchsorted(t.log_ns, cut_ns, side="left"))
    cut = [
        TemperatureSeries(t.stamp_ns[sl], t.temp_c[sl], t.variance[sl], t.frame_id[sl], t.log_ns[sl])
        for sl in (slice(0, i), slice(i, None))
    ]
    return MonitoringData(forces_a, cut[0]), MonitoringData(forces_b, cut[1])


def take_head(
    pieces: Iterator[MonitoringData], cuts: list[int]
) -> tuple[list[list[MonitoringData]], Iterator[MonitoringData] | None]:
    """Cut the first pieces of a stream at increasing log times ``cuts``.

    Returns ``parts`` (``parts[j]``: the messages with log time in ``[cuts[j - 1], cuts[j])``,
    the first from the stream's start) and an iterator over the rest (log time >= ``cuts[-1]``),
    None when the stream ended before ``cuts[-1]``.
    """
    parts: list[list[MonitoringData]] = [[] for _ in cuts]
    j = 0
    for piece in pieces:
        while j < len(cuts):
            before, piece = split_log(piece, cuts[j])
            if before.n_messages:
                parts[j].append(before)
            if not piece.n_messages:
                break
            j += 1
        if j == len(cuts):
            rest = [piece] if piece.n_messages else []
            return parts, _chain(rest, pieces)
    return parts, None


def _chain(first: list[MonitoringData], more: Iterator[MonitoringData]) -> Iterator[MonitoringData]:
    yield from first
    yield from more


def _empty_chunk() -> FeedChunk:
    none = (np.empty(0, np.int64), np.empty(0), np.empty(0, dtype=object))
    return FeedChunk([none, none], none, 0, 0)


def one_chunk(parts: Iterable[MonitoringData]) -> FeedChunk:
    """All messages of ``parts`` (in arrival order) as one feed chunk."""
    chunk = next(arrival_chunks(parts, chunk=2**62), None)
    return chunk if chunk is not None else _empty_chunk()


class _Windowing:
    """A shadow seen through ``feed_shadow`` whose ``poll`` only closes windows, and records them."""

    def __init__(self, shadow: Any) -> None:
        self.shadow = shadow
        self.batches: list[WindowBatch] = []
        self.at: list[int] = []
        self.chunk = 0  # index of the poll that closes the next windows

    def ingest_forces(self, *args: Any) -> int:
        return self.shadow.ingest_forces(*args)

    def ingest_temperature(self, *args: Any) -> int:
        return self.shadow.ingest_temperature(*args)

    def poll(self) -> list[Any]:
        batch = self.shadow.close_windows()
        if len(batch):
            self.batches.append(batch)
            self.at.append(self.chunk)
        return []

    def windows(self) -> tuple[WindowBatch, np.ndarray]:
        """Every window closed, and after which chunk."""
        b = self.batches
        if not b:
            return WindowBatch.empty(), np.empty(0, np.int64)
        at = np.concatenate([np.full(len(x), a, np.int64) for x, a in zip(b, self.at, strict=True)])
        return WindowBatch.concat(b), at


def _head_chunk(red: BagReduction, front: _Windowing, part: list[MonitoringData]) -> None:
    """Feed one head window's messages to the bag's front end; keep them and the state after."""
    red.head.append(one_chunk(part))
    red.messages += feed_shadow(front, [red.head[-1]], flush=False).messages
    red.snapshots.append(front_state(front.shadow))
    front.chunk += 1


def head_windows(config: Any) -> int:
    """Windows of log time in a bag's head: ``HEAD_WINDOWS`` plus the traffic screen's hold."""
    hold = -(-round(config.traffic_hold_s * 1e9) // round(config.window_s * 1e9))
    return HEAD_WINDOWS + int(hold)


def head_cuts(first_log_ns: int, window_ns: int, n: int = HEAD_WINDOWS) -> list[int]:
    """Log times that end the head chunks: the next ``n`` window boundaries after the first message."""
    k0 = first_log_ns // window_ns + 1
    return [(k0 + j) * window_ns for j in range(n)]


def reduce_bag(
    bag: str | Path | Sequence[str | Path],
    config: Any,
    surrogate: Any,
    chunk: int = DEFAULT_CHUNK,
    continuing: bool = False,
) -> BagReduction:
    """Decode, gate and window one bag on its own (see the module docstring).

    Args:
        bag: a rosbag2 bag (directory, ``.db3`` or ``.mcap``), or several bags that overlap in
            time, read as one stream merged by log time (``bagio.merged.MergedStream``; ties in
            the order given).
        config: the bridge's ``ShadowConfig`` (its front-end parameters matter here).
        surrogate: the bridge's surrogate (the front end does not use it; a shadow needs one).
        chunk: messages per feed after the head.
        continuing: the bag goes on from the one before within ``gap_s`` (the bags' log times
            say so): with the traffic screen on, its front end starts inside a record already
            released, as the archive's is when a long record runs through the seam, so the seam
            settles within ``HEAD_WINDOWS`` instead of after the hold. Only a guess: the join
            checks it as any other state, and a wrong one costs a bag fed whole, never a result.

    Raises:
        BagError: the bag cannot be opened or read (one line naming it).

    """
    from bridge_shadow.bagio.merged import open_monitoring
    from bridge_shadow.estimate.shadow import Shadow

    t0 = time.perf_counter()
    shadow = Shadow(config.replace(checkpoint_path=""), surrogate)
    paths = [bag] if isinstance(bag, str | Path) else list(bag)
    red = BagReduction(str(paths[0]), bags=tuple(map(str, paths)) if len(paths) > 1 else ())
    front = _Windowing(shadow)
    with open_monitoring(paths, topics=config.input_topics(), required=False) as stream:
        red.backend = stream.backend
        pieces: Iterator[MonitoringData] | None = iter(stream)
        if stream.first_ns is not None:
            n_head = head_windows(config)
            if continuing and shadow.buffer.hold_ns > 0:
                shadow.buffer.record.released(int(stream.first_ns))
            cuts = head_cuts(int(stream.first_ns), shadow.buffer.w_ns, n_head)
            parts, pieces = take_head(pieces, cuts)
            for part in parts:
                _head_chunk(red, front, part)
            # a record the fresh front end still holds (held on after a silence in it): one more
            # window at a time, until it lets the record go or the stream ends
            while pieces is not None and shadow.buffer.record.holding and len(cuts) < 2 * n_head:
                cuts.append(cuts[-1] + shadow.buffer.w_ns)
                (part,), pieces = take_head(pieces, cuts[-1:])
                _head_chunk(red, front, part)
            red.head_end_ns = cuts[-1]
        if pieces is not None:
            red.messages += feed_shadow(front, arrival_chunks(pieces, chunk), flush=False).messages
    red.first_log_ns = None if stream.first_ns is None else int(stream.first_ns)
    red.last_log_ns = None if stream.last_ns is None else int(stream.last_ns)
    red.windows, red.closed_at = front.windows()
    red.end = front_state(shadow)
    red.seconds = time.perf_counter() - t0
    return red
