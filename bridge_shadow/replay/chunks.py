"""Feed chunks: bag pieces re-cut into exactly ``chunk`` messages in arrival order.

Arrival order is log time, then topic (frc_01, frc_02, air temperature), then storage order:
the order ``Shadow.run`` feeds in-memory data. A chunk holds, per topic, that topic's messages
among the chunk's arrival positions, so feeding chunk by chunk makes the calls ``Shadow.run``
makes on the same data with the same ``chunk``.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass

import numpy as np

from bridge_shadow.bagio.cdr import concat_frames
from bridge_shadow.contract import CHANNELS
from bridge_shadow.series import MonitoringData

__all__ = ["DEFAULT_CHUNK", "FeedChunk", "arrival_chunks"]

#: Messages per shadow call (``Shadow.run``'s default, so both feed alike).
DEFAULT_CHUNK = 200_000


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
