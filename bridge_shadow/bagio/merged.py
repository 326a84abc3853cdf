"""Read several bags as one: their input topics merged by log time, piece by piece, in bounded memory.

``MergedStream(paths)`` offers what ``MonitoringStream`` offers its consumers (``replay_bag``,
``archive.reduce``, ``replay.chunks.arrival_chunks``): ``MonitoringData`` pieces in arrival order
(log time, then topic, then storage order), ``first_ns``/``last_ns`` over all the bags,
``backend``, ``required`` topics and a context manager. ``required`` holds over the union of the
bags: a day whose air temperature came as a bag of its own has it.

Each bag is a sorted run (``MonitoringStream`` yields its messages in log-time order per topic);
the merge is a k-way merge of the runs: a bag is read a piece at a time, the one whose last read
log time is smallest first, and what is held is handed on up to (not including) the smallest of
those times over the bags not yet exhausted, since no bag can still yield anything earlier. So
at most about one piece per bag is held. Messages of one topic at the same log time keep the
order of the bags as given (stable), then their order within their bag.

``open_monitoring(paths)`` is a ``MonitoringStream`` for one bag and a ``MergedStream`` for several.
"""

from __future__ import annotations

from collections.abc import Collection, Iterator, Sequence
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import numpy as np

from bridge_shadow.bagio.cdr import concat_frames, frame_value
from bridge_shadow.bagio.errors import BagError, MissingTopicError
from bridge_shadow.bagio.reader import _required_topics
from bridge_shadow.bagio.stream import DEFAULT_BATCH, MonitoringStream
from bridge_shadow.contract import CHANNELS, INPUT_TOPICS
from bridge_shadow.series import ForceSeries, MonitoringData, TemperatureSeries

__all__ = ["HeldStream", "MergedStream", "joined_span", "open_monitoring"]

#: Per topic: (log_ns, stamp_ns, value columns ..., frame_id), all of one length.
_Cols = tuple[np.ndarray, ...]


def joined_span(spans: Sequence[tuple[int | None, int | None]]) -> tuple[int | None, int | None]:
    """Return the log-time span of several bags' ``(first, last)`` (None where none has one)."""
    firsts = [f for f, _ in spans if f is not None]
    lasts = [la for _, la in spans if la is not None]
    return (min(firsts) if firsts else None, max(lasts) if lasts else None)


def _columns(piece: MonitoringData) -> list[_Cols]:
    """Return the three topics of a piece as columns, log time first and frame ids last."""
    cols: list[_Cols] = [
        (s.log_ns, s.stamp_ns, s.force_n, s.frame_id) for s in (piece.forces[ch] for ch in CHANNELS)
    ]
    t = piece.temperature
    cols.append((t.log_ns, t.stamp_ns, t.temp_c, t.variance, t.frame_id))
    return cols


def _monitoring(cols: list[_Cols]) -> MonitoringData:
    forces = {ch: ForceSeries(c[1], c[2], c[3], c[0]) for ch, c in zip(CHANNELS, cols[:2], strict=True)}
    t = cols[2]
    return MonitoringData(forces, TemperatureSeries(t[1], t[2], t[3], t[4], t[0]))


def _concat(parts: list[_Cols]) -> _Cols:
    """Concatenate one topic's column blocks in the order given."""
    if len(parts) == 1:
        return parts[0]
    n = len(parts[0])
    out = [np.concatenate([p[j] for p in parts]) for j in range(n - 1)]
    return (*out, concat_frames([p[-1] for p in parts]))


def _merge(runs: list[_Cols]) -> _Cols:
    """Merge runs sorted by log time into one, stably (ties: the runs' order, then their own)."""
    joined = _concat(runs)
    if len(runs) == 1 or not len(joined[0]):
        return joined
    order = np.argsort(joined[0], kind="stable")
    frames = joined[-1] if frame_value(joined[-1]) is not None else joined[-1][order]
    return (*(c[order] for c in joined[:-1]), frames)


def _split(cols: _Cols, horizon: int | None) -> tuple[_Cols, _Cols]:
    """(messages with log time < ``horizon``, the others); all in the first when None."""
    i = len(cols[0]) if horizon is None else int(np.searchsorted(cols[0], horizon, side="left"))
    return tuple(c[:i] for c in cols), tuple(c[i:] for c in cols)


class HeldStream:
    """Messages held in memory (a checkpoint's air past its bag's last force), read as a bag is.

    Offers what ``MergedStream`` reads of a ``MonitoringStream``: one piece, its log-time span, the
    input topics it holds and a context manager.
    """

    backend = ""

    def __init__(self, piece: MonitoringData, names: Sequence[str]) -> None:
        self.piece = piece
        logs = [s.log_ns for s in piece.forces.values()] + [piece.temperature.log_ns]
        logs = [x for x in logs if x is not None and len(x)]
        self.first_ns = min(int(x[0]) for x in logs) if logs else None
        self.last_ns = max(int(x[-1]) for x in logs) if logs else None
        sizes = [len(piece.forces[ch]) for ch in CHANNELS] + [len(piece.temperature)]
        self.present = frozenset(name for name, n in zip(names, sizes, strict=True) if n)

    def __iter__(self) -> Iterator[MonitoringData]:
        if self.first_ns is not None:
            yield self.piece

    def __enter__(self) -> HeldStream:
        return self

    def __exit__(self, *exc: object) -> None:
        return None


class MergedStream:
    """Several bags' input topics as one stream of ``MonitoringData`` pieces in arrival order.

    Args:
        paths: the bags (each as ``MonitoringStream`` takes it); their order breaks ties of log time.
        topics: the names the bags use for frc_01, frc_02 and the air temperature.
        required: True (all three topics), False (none) or the contract names of those that must be
            in *some* bag.
        batch: messages per read of each bag.
        held: messages held in memory, merged before the bags at equal log times (the air a
            checkpoint kept past its bag's last force: ``replay.air_tail``); then ``paths`` may
            name one bag.

    Attributes:
        paths, streams: the bags and their open ``MonitoringStream`` s (``held`` first).
        first_ns, last_ns: log-time range over all the bags (None when all are empty).
        backend: the bags' back end, or theirs joined by ``+`` (in bag order) when they differ.
        present: the names of ``topics`` some bag holds.
        peak_pending: the most messages held at once by the merge (besides the bags' own).

    Raises:
        BagError: a bag cannot be opened or read (one line naming it; its ``bag`` attribute is that
            bag's path), or a required topic is in none.

    """

    def __init__(
        self,
        paths: Sequence[str | Path],
        *,
        topics: Sequence[str] | None = None,
        required: bool | Collection[str] = True,
        batch: int = DEFAULT_BATCH,
        held: MonitoringData | None = None,
    ) -> None:
        if not paths:
            raise ValueError("MergedStream needs at least one bag")
        self.paths = [Path(p) for p in paths]
        names = list(INPUT_TOPICS) if topics is None else list(topics)
        self.names = names
        self.peak_pending = 0
        self._stack = ExitStack()
        self.streams: list[MonitoringStream | HeldStream] = []
        self._labels = [str(p) for p in self.paths]
        if held is not None:
            self.streams.append(HeldStream(held, names))
            self._labels.insert(0, "the checkpoint's held air temperature")
        try:
            for p in self.paths:
                try:
                    stream = MonitoringStream(p, topics=names, required=False, batch=batch)
                except BagError as err:
                    err.bag = str(p)  # type: ignore[attr-defined]  # which of the bags failed
                    raise
                self.streams.append(self._stack.enter_context(stream))
            self.present = frozenset().union(*(s.present for s in self.streams))
            must = {names[list(INPUT_TOPICS).index(t)] for t in _required_topics(required)}
            missing = sorted(must - self.present)
            if missing:
                has = ", ".join(sorted(self.present)) or "none of the input topics"
                bags = ", ".join(map(str, self.paths))
                raise MissingTopicError(
                    f"{bags}: missing topic(s) {', '.join(missing)} (the bags have {has})"
                )
        except BaseException:
            self.close()
            raise
        self.first_ns, self.last_ns = joined_span([(s.first_ns, s.last_ns) for s in self.streams])
        backends = list(dict.fromkeys(s.backend for s in self.streams if s.backend))
        self.backend = "+".join(backends)

    def __iter__(self) -> Iterator[MonitoringData]:
        """Yield the merged pieces in arrival order (each holds at least one message)."""
        n = len(self.streams)
        its = [iter(s) for s in self.streams]
        held: list[list[list[_Cols]]] = [[[], [], []] for _ in range(n)]  # per bag, per topic
        # the last log time read of each bag; before its first read, its first message's (nothing
        # of it comes earlier), so a bag is read only once the merge has reached its start and
        # memory stays at about a piece per bag in progress, however many bags (a day's air and
        # forty records: 469 MB when every bag's first piece was read at once); None: unknown
        front: list[int | None] = [s.first_ns for s in self.streams]
        active = list(range(n))
        while active:
            # read on the bag that bounds the merge: one of unknown start, else the one furthest behind
            i = min(active, key=lambda k: (front[k] is not None, front[k] or 0, k))
            try:
                piece = next(its[i], None)
            except BagError as err:
                err.bag = self._labels[i]  # type: ignore[attr-defined]  # which of the bags failed
                raise
            if piece is None:
                active.remove(i)
            else:
                cols = _columns(piece)
                end = max(int(c[0][-1]) for c in cols if len(c[0]))
                front[i] = end if front[i] is None else max(end, int(front[i]))
                for k, c in enumerate(cols):
                    if len(c[0]):
                        held[i][k].append(c)
                size = sum(len(c[0]) for per in held for parts in per for c in parts)
                self.peak_pending = max(self.peak_pending, size)
            if any(front[k] is None for k in active):
                continue
            # nothing a bag still yields comes before its last read log time
            horizon = min(int(front[k]) for k in active) if active else None  # type: ignore[arg-type]
            out = self._take(held, horizon)
            if out is not None:
                yield out

    @staticmethod
    def _take(held: list[list[list[_Cols]]], horizon: int | None) -> MonitoringData | None:
        """Hand on per topic the held messages with log time < ``horizon`` (all when None), merged."""
        topics: list[_Cols] = []
        count = 0
        for k in range(3):
            runs = []
            for per in held:
                if not per[k]:
                    continue
                head, rest = _split(_concat(per[k]), horizon)
                per[k] = [rest] if len(rest[0]) else []
                if len(head[0]):
                    runs.append(head)
            if runs:
                topics.append(_merge(runs))
                count += len(topics[-1][0])
            else:
                topics.append(_empty(k))
        return _monitoring(topics) if count else None

    def close(self) -> None:
        """Close every bag (idempotent)."""
        self._stack.close()

    def __enter__(self) -> MergedStream:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _empty(k: int) -> _Cols:
    none = (np.empty(0, np.int64), np.empty(0, np.int64), np.empty(0))
    return (*none, np.empty(0, dtype=object)) if k < 2 else (*none, np.empty(0), np.empty(0, dtype=object))


def open_monitoring(
    paths: str | Path | Sequence[str | Path], held: MonitoringData | None = None, **kwargs: Any
) -> MonitoringStream | MergedStream:
    """Open a ``MonitoringStream`` of one bag (a path or a sequence of one), a ``MergedStream`` of several.

    ``held``: messages in memory merged with the bags (``MergedStream``), also with one bag.
    """
    if isinstance(paths, str | Path):
        paths = [paths]
    if len(paths) == 1 and held is None:
        return MonitoringStream(paths[0], **kwargs)
    return MergedStream(paths, held=held, **kwargs)
