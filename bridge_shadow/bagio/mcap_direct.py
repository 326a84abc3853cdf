"""Fast path for MCAP bags: locate messages through the chunks' message indexes, with numpy.

An MCAP data section is a sequence of records ``opcode u8 | length u64 | body``. Messages live in
Chunk records (optionally zstd/lz4 compressed), and each chunk is followed by one MessageIndex
record per channel: an array of ``(log_time u64, offset u64)`` into the uncompressed chunk. Reading
those arrays with ``np.frombuffer`` places every message without a Python step per message; the
CDR payload is then decoded in place (``cdr.decode_buffer``). Only top-level records (a few per
megabyte) are walked in Python.

Anything unexpected (no message index, an offset that does not point at a Message record of
its channel, an unknown compression, a bad magic) raises ``McapLayoutError``; the caller then
falls back to rosbags, which reports a damaged file as such.
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Collection
from pathlib import Path, PurePath

import numpy as np
import yaml

from bridge_shadow.bagio.cdr import RawBlock

__all__ = ["McapLayoutError", "mcap_files", "read_mcap_topics"]

_MAGIC = b"\x89MCAP0\r\n"
_REC = struct.Struct("<BQ")
_OP_FOOTER, _OP_SCHEMA, _OP_CHANNEL, _OP_MESSAGE, _OP_CHUNK, _OP_INDEX, _OP_STATISTICS = 2, 3, 4, 5, 6, 7, 11
_MSG_HEAD = 9 + 2 + 4 + 8 + 8  # record header, channel id, sequence, log time, publish time


class McapLayoutError(ValueError):
    """The MCAP file is not laid out as the fast path expects (or is damaged)."""



def payload_spans(buf: np.ndarray, rec: np.ndarray, cid: int) -> tuple[np.ndarray, np.ndarray]:
    """CDR payload starts and lengths (int64, bytes into ``buf``) of the message records at ``rec``.

    ``rec`` are the record offsets a message index gives (into the decompressed chunk data
    ``buf``); every record is checked to be a message of channel ``cid`` lying inside ``buf``.
    Raises McapLayoutError otherwise.
    """
    if not len(rec):
        return np.empty(0, np.int64), np.empty(0, np.int64)
    if int(rec.max()) + _MSG_HEAD > len(buf) or int(rec.min()) < 0:
        raise McapLayoutError("message index points outside its chunk")
    length = np.zeros(len(rec), dtype=np.int64)
    for j in range(8):  # u64 record length, little endian
        length |= buf[rec + 1 + j].astype(np.int64) << (8 * j)
    cid_at = buf[rec + 9].astype(np.int64) | (buf[rec + 10].astype(np.int64) << 8)
    if np.any(buf[rec] != _OP_MESSAGE) or np.any(cid_at != cid) or np.any(length < _MSG_HEAD - 9):
        raise McapLayoutError("message index does not point at messages of its channel")
    starts, lengths = rec + _MSG_HEAD, length - (_MSG_HEAD - 9)
    if int((starts + lengths).max()) > len(buf):
        raise McapLayoutError("message runs past its chunk")
    return starts, lengths

def mcap_files(path: Path) -> list[Path] | None:
    """Return the MCAP files of a bag (directory without rosbag2 compression, or a bare file)."""
    if path.is_file():
        return [path] if path.suffix == ".mcap" else None
    try:
        meta = yaml.safe_load((path / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
        if meta["storage_identifier"] != "mcap" or int(meta["version"]) > 9:
            return None
        if str(meta.get("compression_mode") or "").lower() not in ("", "none"):
            return None
        files = [path / PurePath(x).name for x in meta["relative_file_paths"]]
    except (OSError, yaml.YAMLError, KeyError, TypeError, ValueError, AttributeError):
        return None
    return files if files and all(f.is_file() for f in files) else None


def _string(body: bytes, pos: int) -> tuple[str, int]:
    (n,) = struct.unpack_from("<I", body, pos)
    return body[pos + 4 : pos + 4 + n].decode("utf-8"), pos + 4 + n


def _decompress(data: bytes, compression: str, size: int, crc: int) -> bytes:
    try:
        if compression == "":
            out = data
        elif compression == "zstd":
            try:
                from compression import zstd  # type: ignore[import-not-found]
            except ImportError:
                from backports import zstd
            out = zstd.decompress(data)
        elif compression == "lz4":
            from lz4.frame import decompress

            out = decompress(data)
        else:
            raise McapLayoutError(f"unknown chunk compression {compression!r}")
    except McapLayoutError:
        raise
    except Exception as err:  # ZstdError, lz4's RuntimeError: a damaged chunk
        raise McapLayoutError(f"{compression} chunk does not decompress ({err})") from err
    if len(out) != size:
        raise McapLayoutError("chunk size mismatch")
    if crc and zlib.crc32(out) != crc:
        raise McapLayoutError("chunk checksum mismatch")
    return out


def _read_file(
    file: Path,
    chunks: list[bytes],
    index: dict[int, list[tuple[int, np.ndarray]]],
    channels: dict[int, tuple[str, int]],
    schemas: dict[int, str],
) -> int:
    """Walk the top-level records of one file; collect chunks, message indexes, channels, schemas.

    Returns the message count of the file's Statistics record.
    """
    data = file.read_bytes()
    if not (data.startswith(_MAGIC) and data.endswith(_MAGIC)):
        raise McapLayoutError("bad magic (truncated file?)")
    pos, end = len(_MAGIC), len(data) - len(_MAGIC)
    current = -1
    count = -1
    while pos < end:
        op, length = _REC.unpack_from(data, pos)
        body_start = pos + 9
        pos = body_start + length
        if pos > end:
            raise McapLayoutError("record runs past the end of the file")
        if op == _OP_CHUNK:
            body = data[body_start:pos]
            usize, crc = struct.unpack_from("<QI", body, 16)
            compression, p = _string(body, 28)
            (clen,) = struct.unpack_from("<Q", body, p)
            chunks.append(_decompress(body[p + 8 : p + 8 + clen], compression, usize, crc))
            current = len(chunks) - 1
        elif op == _OP_INDEX:
            if current < 0:
                raise McapLayoutError("message index before any chunk")
            (cid, nbytes) = struct.unpack_from("<HI", data, body_start)
            entries = np.frombuffer(data, dtype="<u8", count=nbytes // 8, offset=body_start + 6).reshape(
                -1, 2
            )
            index.setdefault(cid, []).append((current, entries))
        elif op == _OP_CHANNEL:
            cid, sid = struct.unpack_from("<HH", data, body_start)
            topic, _ = _string(data, body_start + 4)
            channels[cid] = (topic, sid)
        elif op == _OP_SCHEMA:
            (sid,) = struct.unpack_from("<H", data, body_start)
            schemas[sid], _ = _string(data, body_start + 2)
        elif op == _OP_STATISTICS:
            (count,) = struct.unpack_from("<Q", data, body_start)
        elif op == _OP_MESSAGE:
            raise McapLayoutError("message outside a chunk")
        elif op == _OP_FOOTER:
            break
    if count < 0:
        raise McapLayoutError("no statistics record")
    return count


def read_mcap_topics(
    files: list[Path], topics: Collection[str]
) -> tuple[dict[str, RawBlock], dict[str, str]]:
    """Locate every message of the given topics; returns ``{topic: RawBlock}`` and ``{topic: type}``.

    Raises:
        McapLayoutError: layout not handled here or damaged file (fall back to rosbags).

    """
    chunks: list[bytes] = []
    index: dict[int, list[tuple[int, np.ndarray]]] = {}
    channels: dict[int, tuple[str, int]] = {}
    schemas: dict[int, str] = {}
    expected = 0
    try:
        for file in files:
            expected += _read_file(file, chunks, index, channels, schemas)
    except (struct.error, UnicodeDecodeError, ValueError, OSError) as err:
        if isinstance(err, McapLayoutError):
            raise
        raise McapLayoutError(str(err)) from err
    starts_of_chunk = np.cumsum([0] + [len(c) for c in chunks])
    buf = np.frombuffer(b"".join(chunks), dtype=np.uint8)
    types = {topic: schemas.get(sid, "") for topic, sid in channels.values()}
    if any(cid not in channels for cid in index):
        raise McapLayoutError("message index of an unknown channel")
    if sum(len(e) for items in index.values() for _, e in items) != expected:
        raise McapLayoutError("message indexes do not cover every message")
    out: dict[str, RawBlock] = {}
    for cid, (topic, _) in channels.items():
        if topic not in topics:
            continue
        items = index.get(cid, [])
        log = np.concatenate([e[:, 0] for _, e in items]).astype(np.int64) if items else np.empty(0, np.int64)
        rec = (
            np.concatenate([e[:, 1].astype(np.int64) + starts_of_chunk[k] for k, e in items])
            if items
            else np.empty(0, np.int64)
        )
        starts, lengths = payload_spans(buf, rec, cid)
        order = np.argsort(log, kind="stable") if len(log) > 1 and np.any(np.diff(log) < 0) else slice(None)
        prev = out.get(topic)
        block = RawBlock(log[order], buf, starts[order], lengths[order])
        if prev is not None:  # two channels of one topic: merge in log-time order
            log2 = np.concatenate([prev.log_ns, block.log_ns])
            merge = np.argsort(log2, kind="stable")
            block = RawBlock(
                log2[merge],
                buf,
                np.concatenate([prev.starts, block.starts])[merge],
                np.concatenate([prev.lengths, block.lengths])[merge],
            )
        out[topic] = block
    return out, types
