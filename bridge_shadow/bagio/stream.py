"""Read the three input topics of a bag piece by piece, in arrival order, in bounded memory.

``MonitoringStream(path)`` yields ``MonitoringData`` pieces. Every message of a piece comes before
every message of the next one in *arrival order*: log time, then topic (frc_01, frc_02, air
temperature), then storage order; within a piece each topic is in log-time order. So the pieces
concatenated per topic equal ``read_monitoring(path)``, and feeding them in order is feeding
the whole bag in arrival order, which is what ``Shadow.run`` does.

Back ends (chosen as ``read_monitoring`` chooses its fast paths):

- plain sqlite3 directories (or a bare ``.db3``): log-time slices through SQL aggregates
  (``sqlite_stream``), at most ``batch`` messages per slice;
- MCAP (plain or zstd/lz4 chunks): chunk by chunk on the message indexes (``mcap_stream``);
- anything else (rosbag2 file or message compression, unusual files): rosbags'
  ``Reader.messages()`` taken ``batch`` messages at a time.

Each piece is decoded with the vectorized CDR decoder; what is held at any time is one slice,
chunk or batch (plus messages of overlapping MCAP chunks, none in a bag written in time order).
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Iterator, Sequence
from contextlib import ExitStack
from itertools import islice
from operator import attrgetter
from pathlib import Path
from typing import Any

import numpy as np

from bridge_shadow.bagio.cdr import (
    N_FLOATS,
    CdrFormatError,
    RawBlock,
    concat_frames,
    decode_buffer,
    frame_value,
)
from bridge_shadow.bagio.errors import CorruptBagError, MissingTopicError, UnexpectedTypeError
from bridge_shadow.bagio.mcap_format import McapLayoutError, mcap_files
from bridge_shadow.bagio.mcap_stream import McapChunks
from bridge_shadow.bagio.reader import _required_topics, _translated, not_a_bag, open_bag
from bridge_shadow.bagio.sqlite_direct import plain_sqlite_files
from bridge_shadow.bagio.sqlite_stream import SqliteSlices, SqliteStreamUnsupported
from bridge_shadow.contract import CHANNELS, INPUT_TOPICS
from bridge_shadow.series import ForceSeries, MonitoringData, TemperatureSeries

__all__ = ["DEFAULT_BATCH", "MonitoringStream", "iter_monitoring"]

#: Messages per read (SQL slice or rosbags batch); MCAP reads one chunk (about 1 MB) at a time.
DEFAULT_BATCH = 50_000

_TYPES: tuple[str, ...] = tuple(INPUT_TOPICS.values())  # frc_01, frc_02, air temperature
#: The float64 fields kept per topic: wrench.force.z; temperature and variance.
_FIELDS: tuple[tuple[int, ...], ...] = ((2,), (2,), (0, 1))


class _Decoded:
    """One topic's messages decoded: log times, stamps, float fields (n, k) and frame ids."""

    __slots__ = ("frames", "log", "stamp", "values")

    def __init__(self, log: np.ndarray, stamp: np.ndarray, values: np.ndarray, frames: np.ndarray) -> None:
        self.log, self.stamp, self.values, self.frames = log, stamp, values, frames

    @staticmethod
    def empty(n_floats: int) -> _Decoded:
        return _Decoded(
            np.empty(0, np.int64), np.empty(0, np.int64), np.empty((0, n_floats)), np.empty(0, dtype=object)
        )

    def __len__(self) -> int:
        return len(self.log)

    def split(self, i: int) -> tuple[_Decoded, _Decoded]:
        a = _Decoded(self.log[:i], self.stamp[:i], self.values[:i], self.frames[:i])
        b = _Decoded(self.log[i:], self.stamp[i:], self.values[i:], self.frames[i:])
        return a, b

    @staticmethod
    def join(parts: list[_Decoded]) -> _Decoded:
        """Concatenate parts (storage order) and sort stably by log time."""
        if len(parts) == 1:
            return parts[0]
        d = _Decoded(
            np.concatenate([p.log for p in parts]),
            np.concatenate([p.stamp for p in parts]),
            np.concatenate([p.values for p in parts]),
            concat_frames([p.frames for p in parts]),
        )
        if len(d) > 1 and np.any(np.diff(d.log) < 0):  # overlapping MCAP chunks
            order = np.argsort(d.log, kind="stable")
            frames = d.frames if frame_value(d.frames) is not None else d.frames[order]
            d = _Decoded(d.log[order], d.stamp[order], d.values[order], frames)
        return d


class _Pending:
    """Messages not yet handed on, per topic; ``take(horizon)`` returns those before it.

    Holds one kind of per-topic block (``_Decoded`` or ``RawBlock``): ``join`` concatenates a
    topic's blocks in log-time order, ``log`` gives a block's log times; blocks have ``split(i)``.
    """

    def __init__(self, join: Callable[[list[Any]], Any], log: Callable[[Any], np.ndarray]) -> None:
        self.parts: list[list[Any]] = [[] for _ in _TYPES]
        self._join, self._log = join, log

    def add(self, blocks: Sequence[Any]) -> None:
        for parts, b in zip(self.parts, blocks, strict=True):
            if b is not None and len(self._log(b)):
                parts.append(b)

    def take(self, horizon: int | None) -> list[Any] | None:
        """Return per topic the messages with log time < ``horizon`` (all when None), or None if none."""
        out: list[Any] = []
        for k, parts in enumerate(self.parts):
            if not parts:
                out.append(None)
                continue
            block = self._join(parts)
            log = self._log(block)
            i = len(log) if horizon is None else int(np.searchsorted(log, horizon, side="left"))
            head, rest = block.split(i)
            self.parts[k] = [rest] if i < len(log) else []
            out.append(head if i else None)
        return out if any(b is not None for b in out) else None

    @property
    def size(self) -> int:
        """Messages held."""
        return sum(len(self._log(b)) for parts in self.parts for b in parts)


def _monitoring(decoded: list[_Decoded | None]) -> MonitoringData:
    """One piece as ``MonitoringData`` (an absent topic: an empty series)."""
    out = [_Decoded.empty(len(f)) if d is None else d for d, f in zip(decoded, _FIELDS, strict=True)]
    forces = {}
    for ch, d in zip(CHANNELS, out[:2], strict=True):
        forces[ch] = ForceSeries(d.stamp, d.values[:, 0], d.frames, d.log)
    t = out[2]
    return MonitoringData(forces, TemperatureSeries(t.stamp, t.values[:, 0], t.values[:, 1], t.frames, t.log))


class MonitoringStream:
    """A bag's three input topics as ``MonitoringData`` pieces in arrival order (a context manager).

    Args:
        path: bag directory (sqlite3 or MCAP) or a bare ``.db3``/``.mcap`` file.
        topics: the names the bag uses for frc_01, frc_02 and the air temperature (default: the
            contract's); the message types stay the contract's.
        required: True (all three topics must be present), False (none), or the contract topic
            names that must be present.
        batch: messages per read (see ``DEFAULT_BATCH``).

    Attributes:
        first_ns, last_ns: log-time range of the bag (None when empty), for progress.
        backend: ``"sqlite3"``, ``"mcap"`` or ``"rosbags"``.
        present: the names of ``topics`` the bag holds (``bagio.merged`` checks ``required`` over
            several bags with it).
        peak_pending: the most decoded messages held at once (memory check in tests).

    Opening checks the bag, the topics and their types; errors are the ``BagError``s of
    ``read_monitoring``, one line naming the bag.
    """

    def __init__(
        self,
        path: str | Path,
        *,
        topics: Sequence[str] | None = None,
        required: bool | Collection[str] = True,
        batch: int = DEFAULT_BATCH,
    ) -> None:
        self.path = Path(path)
        self.batch = max(int(batch), 1)
        names = list(INPUT_TOPICS) if topics is None else list(topics)
        self.names = names
        must = {names[list(INPUT_TOPICS).index(t)] for t in _required_topics(required)}
        self.peak_pending = 0
        self._stack = ExitStack()
        self._source: Any = None
        self.backend = "rosbags"
        try:
            found = self._open()
            for name, msgtype in zip(names, _TYPES, strict=True):
                if name in found and found[name] != msgtype:
                    raise UnexpectedTypeError(
                        f"{self.path}: topic {name} has type {found[name]}, expected {msgtype}"
                    )
            self.present = frozenset(n for n in names if n in found)
            missing = sorted(must - set(found))
            if missing:
                has = ", ".join(sorted(n for n in names if n in found)) or "none of the input topics"
                raise MissingTopicError(f"{self.path}: missing topic(s) {', '.join(missing)} (bag has {has})")
        except BaseException:
            self.close()
            raise

    def _open(self) -> dict[str, str]:
        """Open the fastest back end that takes the bag; return ``{topic: type}`` of its topics."""
        path = self.path
        if path.exists():
            files = [path] if path.is_file() and path.suffix == ".db3" else plain_sqlite_files(path)
            if files is not None:
                with _translated(path, "opening"):
                    try:
                        source = SqliteSlices(files, self.names, self.batch)
                    except SqliteStreamUnsupported:
                        source = None  # rosbags streams it below
                if source is not None:
                    self._source = self._stack.enter_context(source)
                    self.backend = "sqlite3"
                    self.first_ns, self.last_ns = source.first_ns, source.last_ns
                    return source.types
            if (files := mcap_files(path)) is not None:
                try:
                    source = McapChunks(files, self.names)
                except McapLayoutError:
                    pass  # rosbags decides: a damaged file becomes a CorruptBagError below
                else:
                    self._source = self._stack.enter_context(source)
                    self.backend = "mcap"
                    self.first_ns, self.last_ns = source.first_ns, source.last_ns
                    return source.types
        if path.is_file() and path.suffix not in (".db3", ".mcap"):
            raise not_a_bag(path, "expected a directory, .db3 or .mcap")
        reader = self._stack.enter_context(open_bag(path))
        self._source = reader
        count = int(reader.message_count)
        self.first_ns = int(reader.start_time) if count else None
        self.last_ns = int(reader.end_time) - 1 if count else None
        return {c.topic: c.msgtype for c in reader.connections}

    def _decode(self, blocks: Sequence[RawBlock | None]) -> list[_Decoded | None]:
        out: list[_Decoded | None] = []
        for name, msgtype, fields, block in zip(self.names, _TYPES, _FIELDS, blocks, strict=True):
            if block is None or not len(block.log_ns):
                out.append(None)
                continue
            try:
                stamp, frames, values = decode_buffer(
                    block.buf,
                    block.starts,
                    block.lengths,
                    N_FLOATS[msgtype],
                    fields=fields,
                    compact_frames=True,
                )
            except CdrFormatError as err:
                raise CorruptBagError(
                    f"{self.path}: topic {name} does not decode as {msgtype}: {err}"
                ) from err
            out.append(_Decoded(block.log_ns, stamp, values, frames))
        return out

    def _pieces(self) -> Iterator[tuple[Sequence[RawBlock | None], int | None]]:
        """Raw blocks per topic and the horizon after them, from the open back end."""
        source = self._source
        if self.backend in ("sqlite3", "mcap"):
            it = iter(source)
            while True:
                with _translated(self.path, "reading messages"):
                    item = next(it, None)
                if item is None:
                    return
                # a sqlite3 slice is complete: nothing later comes before its end
                yield (item, None) if self.backend == "sqlite3" else item
            return
        conns = [c for c in source.connections if c.topic in self.names]
        if not conns:
            return
        messages = source.messages(connections=conns)
        while True:
            with _translated(self.path, "reading messages"):
                items = list(islice(messages, self.batch))
            if not items:
                return
            conn_of, logs, raws = zip(*items, strict=True)
            topic_of = np.array(list(map(attrgetter("topic"), conn_of)), dtype=object)
            blocks: list[RawBlock | None] = []
            for name in self.names:
                idx = np.flatnonzero(topic_of == name).tolist()
                blocks.append(
                    RawBlock.from_raws([logs[i] for i in idx], [raws[i] for i in idx]) if idx else None
                )
            # rosbags yields in log-time order: messages at the last log time may continue
            yield blocks, int(logs[-1])

    def _in_arrival_order(self, pending: _Pending, prepare: Callable[[Any], Any]) -> Iterator[list[Any]]:
        """Hand on what is held as soon as nothing later in the bag can come before it."""
        for blocks, horizon in self._pieces():
            pending.add(prepare(blocks))
            self.peak_pending = max(self.peak_pending, pending.size)
            if self.backend == "sqlite3" or horizon is not None:
                piece = pending.take(None if self.backend == "sqlite3" else horizon)
                if piece is not None:
                    yield piece
        piece = pending.take(None)
        if piece is not None:
            yield piece

    def __iter__(self) -> Iterator[MonitoringData]:
        """Yield the pieces in arrival order (each holds at least one message)."""
        pending = _Pending(_Decoded.join, attrgetter("log"))
        for piece in self._in_arrival_order(pending, self._decode):
            yield _monitoring(piece)

    def raw_pieces(self) -> Iterator[list[RawBlock | None]]:
        """Yield the messages undecoded, per topic (None: none in this piece), in arrival order.

        The same pieces as iterating, before decoding: what a player publishes as it reads.
        """
        yield from self._in_arrival_order(_Pending(RawBlock.concat, attrgetter("log_ns")), list)

    def close(self) -> None:
        """Close the bag (idempotent)."""
        self._stack.close()

    def __enter__(self) -> MonitoringStream:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def iter_monitoring(path: str | Path, **kwargs: Any) -> Iterator[MonitoringData]:
    """Yield the pieces of ``MonitoringStream(path, **kwargs)`` and close the bag at the end."""
    with MonitoringStream(path, **kwargs) as stream:
        yield from stream
