"""Fast path for MCAP bags: locate messages through the chunks' message indexes, with numpy.

Reading the message indexes with ``np.frombuffer`` places every message without a Python step per
message; the CDR payload is then decoded in place (``cdr.decode_buffer``). Only top-level records
(a few per megabyte) are walked in Python, by ``mcap_stream.McapChunks``; ``read_mcap_topics``
reads its chunks whole. The record layout both share is ``mcap_format``.

Anything unexpected raises ``mcap_format.McapLayoutError``; the caller then falls back to rosbags,
which reports a damaged file as such.
"""

from __future__ import annotations

import struct
from collections.abc import Collection
from pathlib import Path

import numpy as np

from bridge_shadow.bagio.cdr import RawBlock
from bridge_shadow.bagio.mcap_format import McapLayoutError
from bridge_shadow.bagio.mcap_stream import McapChunks

__all__ = ["read_mcap_topics"]


def read_mcap_topics(
    files: list[Path], topics: Collection[str]
) -> tuple[dict[str, RawBlock], dict[str, str]]:
    """Locate every message of the given topics; returns ``{topic: RawBlock}`` and ``{topic: type}``.

    The whole-bag form of ``mcap_stream.McapChunks`` (one walker of the records for both): every
    chunk is read, and the topics' blocks share one buffer.

    Raises:
        McapLayoutError: layout not handled here or damaged file (fall back to rosbags).

    """
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
