"""MCAP record layout shared by the fast MCAP readers (``mcap_stream`` and ``mcap_direct``).

An MCAP data section is a sequence of records ``opcode u8 | length u64 | body``. Messages live in
Chunk records (optionally zstd/lz4 compressed), and each chunk is followed by one MessageIndex
record per channel: an array of ``(log_time u64, offset u64)`` into the uncompressed chunk. This
module holds the opcodes, the message-record layout, chunk decompression and ``McapLayoutError``:
anything unexpected (no message index, an offset that does not point at a Message record of its
channel, an unknown compression, a bad magic) raises it, and the caller falls back to rosbags.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np

from bridge_shadow.bagio.metadata import plain_bag_files

__all__ = ["McapLayoutError", "mcap_files", "payload_spans"]

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
    found = plain_bag_files(path, "mcap")
    return None if found is None else found[0]


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
