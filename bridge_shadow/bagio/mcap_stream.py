"""Stream MCAP files chunk by chunk, locating messages through the chunks' message indexes.

Opening walks the top-level record headers only (seek and read a few bytes per record: a few
records per megabyte), collecting channels, schemas, the Statistics count and, per Chunk, its
declared log-time range and its MessageIndex records. Iterating then reads one chunk at a time
(decompressed if zstd/lz4), places each message of the wanted channels with ``np.frombuffer``
on its index, with the record layout of ``mcap_format`` for the whole file, and yields the chunk's blocks
with a *horizon*: every later chunk declares a start time at or after it, so a message before
the horizon can be handed on in log-time order. Memory is one chunk plus the messages of
overlapping chunks (none for a bag written in time order).

Anything unexpected at opening raises ``McapLayoutError`` (the caller falls back to rosbags).
"""

from __future__ import annotations

import struct
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO

import numpy as np

from bridge_shadow.bagio.cdr import RawBlock
from bridge_shadow.bagio.mcap_format import (
    _MAGIC,
    _OP_CHANNEL,
    _OP_CHUNK,
    _OP_FOOTER,
    _OP_INDEX,
    _OP_MESSAGE,
    _OP_SCHEMA,
    _OP_STATISTICS,
    _REC,
    McapLayoutError,
    _decompress,
    _string,
    payload_spans,
)

__all__ = ["McapChunks"]


@dataclass
class _Chunk:
    """Where one Chunk record lies, its declared log-time range and its message indexes."""

    file: int
    body: int  # offset of the chunk body in the file
    length: int
    start_ns: int
    end_ns: int
    indexes: list[tuple[int, int, int]] = field(default_factory=list)  # (entries offset, bytes, channel)


class McapChunks:
    """Read the given topics of MCAP files chunk by chunk.

    Args:
        files: the bag's ``.mcap`` files, in order.
        topics: topic names to read; each chunk gives one ``RawBlock`` (or None) per name.

    Iterating yields ``(blocks, horizon_ns)``: the chunk's messages per topic in log-time order,
    and the earliest start time of any later chunk (None after the last).

    Raises:
        McapLayoutError: at opening, a layout this reader does not handle (or a damaged file);
            while iterating, a chunk that does not hold what its records declare.

    """

    def __init__(self, files: Sequence[Path], topics: Sequence[str]) -> None:
        self.topics = list(topics)
        self._handles: list[BinaryIO] = []
        self._chunks: list[_Chunk] = []
        self._channels: dict[int, tuple[str, int]] = {}
        self._schemas: dict[int, str] = {}
        try:
            expected = 0
            for k, file in enumerate(files):
                fh = open(file, "rb")  # kept open while iterating; close() closes it
                self._handles.append(fh)
                expected += self._walk(k, fh)
            indexed = sum(nbytes // 16 for c in self._chunks for _, nbytes, _ in c.indexes)
            if indexed != expected:
                raise McapLayoutError("message indexes do not cover every message")
            if any(cid not in self._channels for c in self._chunks for _, _, cid in c.indexes):
                raise McapLayoutError("message index of an unknown channel")
        except (struct.error, UnicodeDecodeError, ValueError, OSError) as err:
            self.close()
            if isinstance(err, McapLayoutError):
                raise
            raise McapLayoutError(str(err)) from err
        self.first_ns = min((c.start_ns for c in self._chunks), default=None)
        self.last_ns = max((c.end_ns for c in self._chunks), default=None)

    @property
    def types(self) -> dict[str, str]:
        """``{topic: type}`` of every channel."""
        return {topic: self._schemas.get(sid, "") for topic, sid in self._channels.values()}

    def _walk(self, k: int, fh: BinaryIO) -> int:
        """Collect the records of file ``k``; return its Statistics message count."""
        if fh.read(len(_MAGIC)) != _MAGIC:
            raise McapLayoutError("bad magic")
        size = fh.seek(0, 2)
        fh.seek(size - len(_MAGIC))
        if fh.read(len(_MAGIC)) != _MAGIC:
            raise McapLayoutError("bad magic (truncated file?)")
        pos, end = len(_MAGIC), size - len(_MAGIC)
        current: _Chunk | None = None
        count = -1
        while pos < end:
            fh.seek(pos)
            op, length = _REC.unpack(fh.read(_REC.size))
            body = pos + _REC.size
            pos = body + length
            if pos > end:
                raise McapLayoutError("record runs past the end of the file")
            if op == _OP_CHUNK:
                start, stop = struct.unpack("<QQ", fh.read(16))
                current = _Chunk(k, body, length, start, stop)
                self._chunks.append(current)
            elif op == _OP_INDEX:
                if current is None:
                    raise McapLayoutError("message index before any chunk")
                cid, nbytes = struct.unpack("<HI", fh.read(6))
                if 6 + nbytes > length or nbytes % 16:
                    raise McapLayoutError("message index of a wrong size")
                current.indexes.append((body + 6, nbytes, cid))
            elif op == _OP_CHANNEL:
                data = fh.read(length)
                cid, sid = struct.unpack_from("<HH", data, 0)
                topic, _ = _string(data, 4)
                self._channels[cid] = (topic, sid)
            elif op == _OP_SCHEMA:
                data = fh.read(length)
                (sid,) = struct.unpack_from("<H", data, 0)
                self._schemas[sid], _ = _string(data, 2)
            elif op == _OP_STATISTICS:
                (count,) = struct.unpack("<Q", fh.read(8))
            elif op == _OP_MESSAGE:
                raise McapLayoutError("message outside a chunk")
            elif op == _OP_FOOTER:
                break
        if count < 0:
            raise McapLayoutError("no statistics record")
        return count

    def _read_chunk(self, chunk: _Chunk) -> list[RawBlock | None]:
        fh = self._handles[chunk.file]
        fh.seek(chunk.body)
        body = fh.read(chunk.length)
        usize, crc = struct.unpack_from("<QI", body, 16)
        compression, p = _string(body, 28)
        (clen,) = struct.unpack_from("<Q", body, p)
        buf = np.frombuffer(_decompress(body[p + 8 : p + 8 + clen], compression, usize, crc), dtype=np.uint8)
        out: list[RawBlock | None] = [None] * len(self.topics)
        for offset, nbytes, cid in chunk.indexes:
            topic, _ = self._channels[cid]
            if topic not in self.topics or not nbytes:
                continue
            fh.seek(offset)
            entries = np.frombuffer(fh.read(nbytes), dtype="<u8").reshape(-1, 2)
            block = _locate(buf, entries, cid)
            k = self.topics.index(topic)
            prev = out[k]
            if prev is not None:  # two channels of one topic: merge in log-time order
                log = np.concatenate([prev.log_ns, block.log_ns])
                order = np.argsort(log, kind="stable")
                starts = np.concatenate([prev.starts, block.starts])
                lengths = np.concatenate([prev.lengths, block.lengths])
                block = RawBlock(log[order], buf, starts[order], lengths[order])
            out[k] = block
        for block in out:
            if block is not None and len(block.log_ns) and int(block.log_ns[0]) < chunk.start_ns:
                raise McapLayoutError("a message lies before its chunk's declared start time")
        return out

    def __iter__(self) -> Iterator[tuple[list[RawBlock | None], int | None]]:
        """Yield each chunk's blocks and the horizon (earliest start of the chunks after it)."""
        horizons: list[int | None] = [None] * len(self._chunks)
        later: int | None = None
        for i in range(len(self._chunks) - 1, -1, -1):
            horizons[i] = later
            start = self._chunks[i].start_ns
            later = start if later is None else min(later, start)
        for chunk, horizon in zip(self._chunks, horizons, strict=True):
            yield self._read_chunk(chunk), horizon

    def close(self) -> None:
        """Close the files (idempotent)."""
        for fh in self._handles:
            fh.close()
        self._handles = []

    def __enter__(self) -> McapChunks:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _locate(buf: np.ndarray, entries: np.ndarray, cid: int) -> RawBlock:
    """Turn ``(log_time, offset)`` index entries into a block of CDR payloads in ``buf``."""
    log = entries[:, 0].astype(np.int64)
    rec = entries[:, 1].astype(np.int64)
    starts, lengths = payload_spans(buf, rec, cid)
    if len(log) > 1 and np.any(np.diff(log) < 0):
        order = np.argsort(log, kind="stable")
        return RawBlock(log[order], buf, starts[order], lengths[order])
    return RawBlock(log, buf, starts, lengths)
