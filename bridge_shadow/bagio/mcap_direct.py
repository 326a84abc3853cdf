"""Fast path for MCAP bags: locate messages through the chunks' message indexes, with numpy.

An MCAP data section is a sequence of records ``opcode u8 | length u64 | body``. Messages live in
Chunk records (optionally zstd/lz4 compressed), and each chunk is followed by one MessageIndex
record per channel: an array of ``(log_time u64, offset u64)`` into the uncompressed chunk. Reading
those arrays with ``np.frombuffer`` places every message without a Python step per message; the
CDR payload is then decoded in place (``cdr.decode_buffer``). Only top-level records (a few per
megabyte) are walked in Python, by ``mcap_stream.McapChunks``; ``read_mcap_topics`` reads its
chunks whole. This module holds the record layout both share.

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


def read_mcap_topics(
    files: list[Path], topics: Collection[str]
) -> tuple[dict[str, RawBlock], dict[str, str]]:
    """Locate every message of the given topics; returns ``{topic: RawBlock}`` and ``{topic: type}``.

    The whole-bag form of ``mcap_stream.McapChunks`` (one walker of the records for both): every
    chunk is read, and the topics' blocks share one buffer.

    Raises:
        McapLayoutError: layout not handled here or damaged file (fall back to rosbags).

    """
    from bridge_shadow.bagio.mcap_stream import McapChunks  # it builds on this module

    names = list(topics)
    bufs: list[np.ndarray] = []
    parts: list[list[RawBlock]] = [[] for _ in names]
    offset = 0
    try:
        with McapChunks(files, names) as source:
            types = source.types
            for blocks, _ in source:
                held = [b for b in blocks if b is not None]
                if not held:
                    continue
                for k, b in enumerate(blocks):
                    if b is not None:
                        parts[k].append(RawBlock(b.log_ns, b.buf, b.starts + offset, b.lengths))
                bufs.append(held[0].buf)  # one chunk: its topics' blocks share its buffer
                offset += len(held[0].buf)
    except (struct.error, UnicodeDecodeError, ValueError, OSError) as err:
        if isinstance(err, McapLayoutError):
            raise
        raise McapLayoutError(str(err)) from err
    buf = np.concatenate(bufs) if bufs else np.empty(0, np.uint8)
    out: dict[str, RawBlock] = {}
    for name, blocks in zip(names, parts, strict=True):
        if name not in types:
            continue
        none = np.empty(0, np.int64)
        joined = RawBlock.concat([RawBlock(b.log_ns, buf, b.starts, b.lengths) for b in blocks])
        out[name] = joined if joined is not None else RawBlock(none, buf, none, none)
    return out, types
