"""Stream plain sqlite3 rosbag2 files in log-time slices, a few SQL aggregates per slice.

A slice is ``[lo, hi)`` in log time, with ``hi`` the timestamp of the ``batch``-th message at or
after ``lo`` (found on the ``timestamp`` index), so no slice holds more than ``batch`` messages
per file unless one log time alone carries more. For each slice one query returns, per topic,
the concatenated CDR blobs (``group_concat(data, '')``), the log times as text (offsets from
``lo``, parsed by ``np.fromstring`` as exact int64) and the longest message: SQLite does the
per-row work in C, and Python touches each slice a handful of times, never each message.

The rows come in ``timestamp_idx`` order, i.e. (log time, rowid): the same order as one query
per topic sorted stably by log time (``sqlite_direct``), so slices concatenated give exactly the
whole read. A file without a timestamp index or not in UTF-8 is refused here (the caller then
streams it through rosbags).
"""

from __future__ import annotations

import sqlite3
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np

from bridge_shadow.bagio.cdr import RawBlock

__all__ = ["SqliteSlices", "SqliteStreamUnsupported"]


class SqliteStreamUnsupported(ValueError):
    """The file cannot be streamed by slices (no timestamp index, not UTF-8): use rosbags."""


def _connect(file: Path) -> sqlite3.Connection:
    # opened by the caller, possibly read by its prefetching thread (one thread at a time)
    db = sqlite3.connect(f"file:{file}?immutable=1", uri=True, check_same_thread=False)
    db.text_factory = bytes  # group_concat of blobs comes back byte for byte
    return db


def _text(value: bytes | str) -> str:
    return value.decode() if isinstance(value, bytes) else value


def _timestamp_index(db: sqlite3.Connection) -> str | None:
    """Name of an index of ``messages`` whose first column is ``timestamp`` (None if there is none)."""
    for row in db.execute("PRAGMA index_list(messages)").fetchall():
        name = _text(row[1])
        cols = db.execute(f"PRAGMA index_info('{name}')").fetchall()
        if cols and _text(cols[0][2]) == "timestamp":
            return name
    return None


class _File:
    """One ``.db3`` file: its topic ids and the prepared slice query."""

    def __init__(self, file: Path, topics: Sequence[str]) -> None:
        self.path = file
        self.db = _connect(file)
        enc = _text(self.db.execute("PRAGMA encoding").fetchone()[0])
        if enc.upper() != "UTF-8":
            raise SqliteStreamUnsupported(f"{file}: database encoding {enc!r}")
        rows = self.db.execute("SELECT id, name, type FROM topics").fetchall()
        self.types = {_text(name): _text(msgtype) for _, name, msgtype in rows}
        ids = {_text(name): int(tid) for tid, name, _ in rows}
        self.ids = [ids.get(t) for t in topics]
        index = _timestamp_index(self.db)
        if index is None:
            raise SqliteStreamUnsupported(f"{file}: no index on messages.timestamp")
        first, last = self.db.execute("SELECT min(timestamp), max(timestamp) FROM messages").fetchone()
        self.first_ns = None if first is None else int(first)
        self.last_ns = None if last is None else int(last)
        parts = []
        for tid in self.ids:
            if tid is None:
                parts.append("NULL, NULL, NULL")
                continue
            where = f"FILTER (WHERE topic_id = {tid})"
            parts.append(
                f"group_concat(data, '') {where}, group_concat(timestamp - :lo, ',') {where}, "
                f"max(length(data)) {where}"
            )
        present = ", ".join(str(t) for t in self.ids if t is not None) or "NULL"
        self.query = (
            f"SELECT {', '.join(parts)} FROM messages "
            f"WHERE timestamp >= :lo AND timestamp < :hi AND topic_id IN ({present})"
        )
        plan = " ".join(
            _text(r[-1]) for r in self.db.execute("EXPLAIN QUERY PLAN " + self.query, {"lo": 0, "hi": 1})
        )
        if f"INDEX {index} " not in plan + " ":  # rows must come in (timestamp, rowid) order
            raise SqliteStreamUnsupported(f"{file}: the slice query does not use the timestamp index")

    def boundary(self, lo: int, batch: int) -> int | None:
        """Log time of the ``batch``-th message at or after ``lo`` (None: fewer remain)."""
        row = self.db.execute(
            "SELECT timestamp FROM messages WHERE timestamp >= ? ORDER BY timestamp LIMIT 1 OFFSET ?",
            (lo, batch),
        ).fetchone()
        if row is None:
            return None
        hi = int(row[0])
        if hi == lo:  # one log time holds more than a batch: take it whole
            row = self.db.execute("SELECT min(timestamp) FROM messages WHERE timestamp > ?", (lo,)).fetchone()
            return None if row[0] is None else int(row[0])
        return hi

    def read(self, lo: int, hi: int) -> list[RawBlock | None]:
        """Messages of each topic with ``lo <= log < hi``, in (log time, rowid) order."""
        if all(tid is None for tid in self.ids):  # none of the topics (one of several bags): no
            return [None] * len(self.ids)  # aggregate in the query, so no row to read
        row = self.db.execute(self.query, {"lo": lo, "hi": hi}).fetchone()
        out: list[RawBlock | None] = []
        for k, tid in enumerate(self.ids):
            blob, text, longest = row[3 * k : 3 * k + 3]
            if tid is None or text is None:
                out.append(None)
                continue
            log = np.fromstring(text, dtype=np.int64, sep=",") + lo  # exact int64 parse
            n = len(log)
            buf = np.frombuffer(blob, dtype=np.uint8)
            if int(longest) * n == len(blob):  # every message of the topic has the longest length
                lengths = np.full(n, int(longest), dtype=np.int64)
            else:
                lengths = self._lengths(tid, lo, hi)
            if len(lengths) != n or int(lengths.sum()) != len(blob):
                raise sqlite3.DatabaseError(f"{self.path}: slice read back inconsistent")
            starts = np.cumsum(lengths) - lengths
            block = RawBlock(log, buf, starts, lengths)
            if n > 1 and np.any(np.diff(log) < 0):  # not expected on the index; keep rowid order on ties
                order = np.argsort(log, kind="stable")
                block = RawBlock(log[order], buf, starts[order], lengths[order])
            out.append(block)
        return out

    def _lengths(self, tid: int, lo: int, hi: int) -> np.ndarray:
        (text,) = self.db.execute(
            "SELECT group_concat(length(data), ',') FROM messages "
            "WHERE timestamp >= ? AND timestamp < ? AND topic_id = ?",
            (lo, hi, tid),
        ).fetchone()
        return np.fromstring(text, dtype=np.int64, sep=",")

    def close(self) -> None:
        self.db.close()


class SqliteSlices:
    """Read the given topics of sqlite3 files slice by slice, in log-time order.

    Args:
        files: the bag's ``.db3`` files (uncompressed).
        topics: topic names to read; each slice gives one ``RawBlock`` (or None) per name.
        batch: at most this many messages (all topics of a file) per slice and file, unless a
            single log time holds more.

    Raises:
        SqliteStreamUnsupported: a file cannot be streamed this way (caller falls back).
        sqlite3.Error: unreadable or corrupt database.

    """

    def __init__(self, files: Sequence[Path], topics: Sequence[str], batch: int = 100_000) -> None:
        self.topics = list(topics)
        self.batch = max(int(batch), 1)
        self._files: list[_File] = []
        try:
            for file in files:
                self._files.append(_File(file, self.topics))
        except BaseException:
            self.close()
            raise
        firsts = [f.first_ns for f in self._files if f.first_ns is not None]
        lasts = [f.last_ns for f in self._files if f.last_ns is not None]
        self.first_ns: int | None = min(firsts) if firsts else None
        self.last_ns: int | None = max(lasts) if lasts else None

    @property
    def types(self) -> dict[str, str]:
        """``{topic: type}`` of every topic in the files."""
        out: dict[str, str] = {}
        for f in self._files:
            out.update(f.types)
        return out

    def __iter__(self) -> Iterator[list[RawBlock | None]]:
        """Yield, slice by slice, one block per topic (None when the slice has none of it)."""
        lo = self.first_ns
        while lo is not None:
            live = [f for f in self._files if f.last_ns is not None and f.last_ns >= lo]
            bounds = [f.boundary(lo, self.batch) for f in live]
            ends = [b for b in bounds if b is not None]
            hi = min(ends) if ends else None
            stop = hi if hi is not None else (self.last_ns or lo) + 1
            per_file = [f.read(lo, stop) for f in live if f.first_ns is not None and f.first_ns < stop]
            yield [RawBlock.concat([blocks[k] for blocks in per_file]) for k in range(len(self.topics))]
            lo = hi

    def close(self) -> None:
        """Close every file (idempotent)."""
        for f in self._files:
            f.close()
        self._files = []

    def __enter__(self) -> SqliteSlices:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
