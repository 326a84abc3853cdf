"""Offline replay in bounded memory: bag pieces -> ``Shadow`` -> window outputs, chunk by chunk.

``replay_bag`` is what ``bridge-shadow replay BAG`` does without ``--live``. It reads the bag as
``MonitoringData`` pieces in arrival order (``bagio.stream``), re-cuts them into chunks of
exactly ``chunk`` messages, and feeds each chunk through the shadow's public methods the way
``Shadow.run`` feeds in-memory data: per chunk ``ingest_forces`` (frc_01, then frc_02),
``ingest_temperature``, then ``poll``; ``flush`` at the end. With the same ``chunk`` the calls,
and so the results, are those of ``Shadow.run(read_monitoring(bag), chunk)``.

Nothing grows with the bag's length: one read piece and one chunk are held at a time, window
outputs go to the ``--out`` bag as they close (``OutputBag``), and what ``--plots`` draws is kept
decimated (``WindowHistory``: at most ``capacity`` windows, evenly spaced). The shadow keeps its
own state bounded (its refilter log is capped).
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bridge_shadow.bagio.cdr import concat_frames, frame_value
from bridge_shadow.contract import CHANNELS
from bridge_shadow.series import MonitoringData

__all__ = [
    "DEFAULT_CHUNK",
    "HISTORY_CAPACITY",
    "FeedChunk",
    "OutputBag",
    "Prefetch",
    "StreamReplay",
    "WindowHistory",
    "arrival_chunks",
    "feed_shadow",
    "replay_bag",
]

#: Messages per shadow call (``Shadow.run``'s default, so both feed alike).
DEFAULT_CHUNK = 200_000
#: Window outputs kept for ``--plots`` (a year of 60 s windows is decimated 64-fold to 8,213).
HISTORY_CAPACITY = 10_000


@dataclass
class FeedChunk:
    """Messages of one shadow call, per topic in arrival order.

    Attributes:
        forces: per channel ``(stamp_ns (n,) int64, force_n (n,) float, frame_id (n,) object)``.
        temperature: ``(stamp_ns (m,) int64, temp_c (m,) float, frame_id (m,) object)``.
        messages: total number of messages.
        last_log_ns: log time of the last message (for progress).

    """

    forces: list[tuple[np.ndarray, np.ndarray, np.ndarray]]
    temperature: tuple[np.ndarray, np.ndarray, np.ndarray]
    messages: int
    last_log_ns: int


def _arrival_codes(piece: MonitoringData) -> np.ndarray:
    """Topic index (0 frc_01, 1 frc_02, 2 temperature) of each message of ``piece`` in arrival order."""
    logs = [piece.forces[ch].log_ns for ch in CHANNELS] + [piece.temperature.log_ns]
    codes = np.concatenate([np.full(len(x), i, dtype=np.int8) for i, x in enumerate(logs)])
    return codes[np.argsort(np.concatenate(logs), kind="stable")]


def _columns(piece: MonitoringData) -> list[tuple[np.ndarray, ...]]:
    cols: list[tuple[np.ndarray, ...]] = [
        (s.stamp_ns, s.force_n, s.frame_id, s.log_ns) for s in (piece.forces[ch] for ch in CHANNELS)
    ]
    t = piece.temperature
    cols.append((t.stamp_ns, t.temp_c, t.frame_id, t.log_ns))
    return cols


def arrival_chunks(pieces: Iterable[MonitoringData], chunk: int = DEFAULT_CHUNK) -> Iterator[FeedChunk]:
    """Re-cut pieces (each wholly before the next in arrival order) into chunks of ``chunk`` messages.

    The first ``chunk`` messages in arrival order form the first chunk, and so on; the last may
    be shorter. Holds at most one piece and one chunk.
    """
    chunk = max(int(chunk), 1)
    parts: list[list[tuple[np.ndarray, ...]]] = [[], [], []]
    have = 0
    last = 0
    for piece in pieces:
        codes = _arrival_codes(piece)
        cols = _columns(piece)
        at = 0  # position in codes
        cursor = [0, 0, 0]  # position in each topic
        while at < len(codes):
            take = min(chunk - have, len(codes) - at)
            counts = np.bincount(codes[at : at + take], minlength=3)
            for k in range(3):
                n = int(counts[k])
                if n:
                    c = cursor[k]
                    parts[k].append(tuple(a[c : c + n] for a in cols[k]))
                    last = max(last, int(cols[k][3][c + n - 1]))
                    cursor[k] += n
            at += take
            have += take
            if have == chunk:
                yield _chunk(parts, have, last)
                parts, have = [[], [], []], 0
    if have:
        yield _chunk(parts, have, last)


def _chunk(parts: list[list[tuple[np.ndarray, ...]]], n: int, last: int) -> FeedChunk:
    joined = []
    for items in parts:
        if not items:
            empty = (np.empty(0, np.int64), np.empty(0), np.empty(0, dtype=object))
            joined.append(empty)
        elif len(items) == 1:
            joined.append(items[0][:3])
        else:
            stamp, value = (np.concatenate([it[j] for it in items]) for j in range(2))
            joined.append((stamp, value, concat_frames([it[2] for it in items])))
    return FeedChunk([joined[0], joined[1]], joined[2], n, last)


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

    """

    messages: int = 0
    pipeline_s: float = 0.0
    read_s: float = 0.0
    reader_s: float = 0.0
    write_s: float = 0.0
    windows_out: int = 0
    backend: str = ""


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
) -> StreamReplay:
    """Feed chunks through ``shadow`` (ingest per topic, then poll; flush at the end).

    Args:
        shadow: an ``estimate.Shadow`` (only its public methods are used).
        chunks: from ``arrival_chunks``.
        on_outputs: called with each non-empty list of closed-window outputs, in order.
        progress: called with the log time (ns) of the last message fed, after each chunk.
        flush: close the open windows at the end (end of a replay).

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


class WindowHistory:
    """Window outputs for plots, evenly decimated to at most ``capacity``.

    Keeps every ``stride``-th window (``stride`` starts at 1); when more than ``capacity`` are
    kept, every second one is dropped and ``stride`` doubles. So memory is bounded whatever the
    bag's length, and the kept windows stay evenly spaced over the whole record (a year of 60 s
    windows keeps every 64th: one per hour).
    """

    def __init__(self, capacity: int = HISTORY_CAPACITY) -> None:
        self.capacity = max(int(capacity), 2)
        self.stride = 1
        self.seen = 0
        self.kept: list[Any] = []

    def extend(self, outputs: Iterable[Any]) -> None:
        """Offer closed-window outputs in order."""
        for out in outputs:
            if self.seen % self.stride == 0:
                self.kept.append(out)
                if len(self.kept) > self.capacity:
                    self.kept = self.kept[::2]
                    self.stride *= 2
            self.seen += 1


class OutputBag:
    """Write window outputs to a bag as they close: mean, covariance, compensated forces, diagnostics.

    Topic names are the shadow's ``topic_*`` parameters (the contract's by default). ``finish``
    adds the final diagnostics (rejections, spline) at the last window's stamp. A context manager.
    """

    def __init__(self, path: str | Path, shadow: Any) -> None:
        from bridge_shadow.bagio import BagOutputWriter

        self.path = Path(path)
        self.shadow = shadow
        self.names = shadow.config.output_topics()
        self.writer = BagOutputWriter(self.path)
        self.last_end_ns: int | None = None

    def __enter__(self) -> OutputBag:
        self.writer.__enter__()
        return self

    def __exit__(self, *exc: object) -> None:
        self.writer.close()

    def write(self, outputs: Iterable[Any]) -> None:
        """Write the messages of each window output (stamp and log time = window end).

        The float arrays and compensated forces of a batch of windows are serialized at once
        (``float64_array_raws``, ``encode_stamped_floats``); messages are written window by
        window: mean, covariance, compensated frc_01 and frc_02 (when finite), diagnostics.
        """
        from bridge_shadow.bagio.cdr import encode_stamped_floats
        from bridge_shadow.contract import (
            COMPENSATED_TOPICS,
            COVARIANCE_LAYOUT_LABELS,
            COVARIANCE_TOPIC,
            DIAGNOSTICS_TOPIC,
            FLOAT_ARRAY_TYPE,
            FORCE_FRAMES,
            FORCE_TYPE,
            MEAN_LAYOUT_LABEL,
            MEAN_TOPIC,
            NODE_NAME,
        )

        outs = list(outputs)
        if not outs:
            return
        names, writer = self.names, self.writer
        end = np.array([int(o.end_ns) for o in outs], dtype=np.int64)
        means = writer.float64_array_raws(np.array([o.mean_m for o in outs]), [MEAN_LAYOUT_LABEL])
        covs = writer.float64_array_raws(
            np.array([o.covariance_m2 for o in outs]), list(COVARIANCE_LAYOUT_LABELS)
        )
        comp = np.array([o.compensated_n for o in outs], dtype=float).reshape(-1, 2)
        finite = np.flatnonzero(np.all(np.isfinite(comp), axis=1))
        wrench = np.zeros((len(finite), 6))
        forces: list[dict[int, bytes]] = []
        for c, ch in enumerate(CHANNELS):
            wrench[:, 2] = comp[finite, c]
            raws = encode_stamped_floats(end[finite], FORCE_FRAMES[ch], wrench)
            forces.append(dict(zip(finite.tolist(), raws, strict=True)))
        for i, out in enumerate(outs):
            t = int(end[i])
            writer.write_raw(names[MEAN_TOPIC], FLOAT_ARRAY_TYPE, t, means[i])
            writer.write_raw(names[COVARIANCE_TOPIC], FLOAT_ARRAY_TYPE, t, covs[i])
            if i in forces[0]:
                for c, ch in enumerate(CHANNELS):
                    writer.write_raw(names[COMPENSATED_TOPICS[ch]], FORCE_TYPE, t, forces[c][i])
            values = {
                "window_end_ns": t,
                "updated": out.updated,
                "reason": out.reason,
                "mean_m": list(out.mean_m),
                "sigma_m": list(np.sqrt(np.diag(out.covariance_m2))),
                "force_n": list(out.force_n),
                "temp_c": list(out.temp_c),
            }
            status = {
                "name": f"{NODE_NAME}: window",
                "level": 0 if out.updated else 1,
                "message": out.reason or "updated",
                "values": values,
            }
            writer.write_diagnostics(names[DIAGNOSTICS_TOPIC], t, t, [status])
            self.last_end_ns = t

    def finish(self) -> Path:
        """Write the final diagnostics (after the last window) and return the bag path."""
        from bridge_shadow.contract import DIAGNOSTICS_TOPIC, NODE_NAME

        if self.last_end_ns is not None:
            diag = self.shadow.diagnostics()
            levels = {"OK": 0, "WARN": 1, "ERROR": 2}
            t = self.last_end_ns
            status = {
                "name": f"{NODE_NAME}: final",
                "level": levels[diag["level"]],
                "message": diag["summary"],
                "values": {"rejected": diag["rejected"], "spline": diag["spline"]},
            }
            self.writer.write_diagnostics(self.names[DIAGNOSTICS_TOPIC], t, t, [status])
        return self.path


def _result(shadow: Any, stats: StreamReplay, outputs: list[Any]) -> Any:
    """Build the shadow's ``ReplayResult`` after a streamed replay (``seconds``: time in the shadow).

    Everything comes from the shadow's public ``posterior`` and ``diagnostics()``, the values
    ``Shadow.run`` puts in its result.
    """
    from bridge_shadow.estimate import ReplayResult

    mean, cov = shadow.posterior
    diag = shadow.diagnostics()
    return ReplayResult(
        mean_m=mean,
        covariance_m2=cov,
        messages=stats.messages,
        used=dict(diag["used"]),
        rejected=dict(diag["rejected"]),
        windows=int(diag["windows"]["closed"]),
        updates=int(diag["windows"]["updates"]),
        spline=diag["spline"],
        noise=diag["noise"],
        outputs=outputs,
        seconds=stats.pipeline_s,
    )


class Prefetch:
    """Iterate ``items`` in a background thread, at most ``depth`` items ahead (a context manager).

    Reading and decoding a slice spends most of its time in SQLite, zstd and numpy, which release
    the GIL, so a reader thread overlaps them with the shadow's work in the main thread. Memory
    stays bounded: ``depth`` items wait at most. An exception of the reader is raised in the
    consumer; leaving the block stops the reader and waits for it.

    Attributes:
        busy_s: wall seconds the reader spent producing items.

    """

    _END = object()

    def __init__(self, items: Iterable[Any], depth: int = 2) -> None:
        self._items = items
        self._queue: queue.Queue[tuple[Any, BaseException | None]] = queue.Queue(maxsize=max(int(depth), 1))
        self._stop = threading.Event()
        self.busy_s = 0.0
        self._thread = threading.Thread(target=self._work, name="bridge_shadow-reader", daemon=True)

    def _put(self, item: Any, err: BaseException | None = None) -> bool:
        while not self._stop.is_set():
            try:
                self._queue.put((item, err), timeout=0.05)
                return True
            except queue.Full:
                continue
        return False

    def _work(self) -> None:
        it = iter(self._items)
        try:
            while True:
                t0 = time.perf_counter()
                item = next(it, self._END)
                self.busy_s += time.perf_counter() - t0
                if not self._put(item) or item is self._END:
                    return
        except BaseException as err:  # handed to the consumer, raised there
            self._put(None, err)

    def __enter__(self) -> Prefetch:
        self._thread.start()
        return self

    def __iter__(self) -> Iterator[Any]:
        while True:
            item, err = self._queue.get()
            if err is not None:
                raise err
            if item is self._END:
                return
            yield item

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()


def replay_bag(
    bag: str | Path,
    shadow: Any,
    *,
    out: str | Path | None = None,
    history: int | None = None,
    keep_all: bool = False,
    chunk: int = DEFAULT_CHUNK,
    batch: int | None = None,
    progress: Callable[[float], None] | None = None,
    prefetch: bool = True,
) -> tuple[Any, StreamReplay]:
    """Replay a bag through ``shadow`` in bounded memory; return its ``ReplayResult`` and timings.

    Args:
        bag: rosbag2 bag with the input topics (names from the shadow's ``topic_*`` parameters).
        shadow: a fresh (or resumed) ``estimate.Shadow``.
        out: write the window outputs to this new bag as they close.
        history: keep at most this many window outputs, evenly decimated (for plots); None keeps
            none, unless ``keep_all``.
        keep_all: keep every window output (memory grows with the bag: tests and short bags).
        chunk: messages per shadow call.
        batch: messages per bag read (default ``bagio.stream.DEFAULT_BATCH``).
        progress: called with the fraction of the bag's log-time span fed so far.
        prefetch: read and decode in a background thread (``Prefetch``), two chunks ahead, while
            the shadow works; the calls into the shadow and their order are the same either way.
            With a free core the replay takes about max(read, shadow) instead of their sum (10 Hz
            forces: 4.6 s -> 3.0 s); on a machine whose cores are all busy it gains nothing.

    Returns:
        ``(result, stats)``: ``result.outputs`` holds the kept window outputs and
        ``result.seconds`` the time inside the shadow; ``stats`` has the read time too (with
        ``prefetch``, ``read_s`` is the time the shadow waited for data and ``reader_s`` the
        reader thread's own time).

    Raises:
        BagError: the bag cannot be read (before anything is fed or written).

    """
    from bridge_shadow.bagio.stream import DEFAULT_BATCH, MonitoringStream

    t0 = time.perf_counter()
    config = shadow.config
    stream = MonitoringStream(bag, topics=config.input_topics(), batch=batch or DEFAULT_BATCH)
    with stream:
        kept = WindowHistory(history) if history else None
        every: list[Any] = []
        report = None
        if progress is not None and stream.first_ns is not None and stream.last_ns is not None:
            first, span = stream.first_ns, max(stream.last_ns - stream.first_ns, 1)
            report = lambda log_ns: progress(min(max((log_ns - first) / span, 0.0), 1.0))  # noqa: E731
        sink = OutputBag(out, shadow) if out is not None else None

        def take(outs: list[Any]) -> None:
            if sink is not None:
                sink.write(outs)
            if kept is not None:
                kept.extend(outs)
            if keep_all:
                every.extend(outs)

        open_s = time.perf_counter() - t0
        with ExitStack() as stack:
            chunks: Iterable[FeedChunk] = arrival_chunks(stream, chunk)
            reader = stack.enter_context(Prefetch(chunks)) if prefetch else None
            if sink is not None:
                stack.enter_context(sink)
            stats = feed_shadow(shadow, reader if reader is not None else chunks, take, report)
            if sink is not None:
                t1 = time.perf_counter()
                sink.finish()
                stats.write_s += time.perf_counter() - t1
        stats.reader_s = reader.busy_s if reader is not None else stats.read_s
        stats.read_s += open_s
        stats.reader_s += open_s
        stats.backend = stream.backend
    if progress is not None:
        progress(1.0)
    if config.checkpoint_path:  # as Shadow.run does at the end of a replay
        shadow.save_checkpoint()
    outputs = every if keep_all else (kept.kept if kept is not None else [])
    return _result(shadow, stats, outputs), stats
