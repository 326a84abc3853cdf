"""The air temperature past a bag's last force: held back for a checkpoint chain, fed with the next bag.

A bag of one record often carries the whole day's air temperature (``import-csv`` of a record
with the day's temperature file). Replayed with ``--checkpoint``, that air, hours past the
record's last force, moved the window clock on (a force channel silent while the air flows closes
its windows live), and the next bag's forces, earlier than the air's end, were all ``late``: a
chain of ``replay --checkpoint`` lost the later records that one ``replay BAG BAG`` of the same
bags, read merged by log time, keeps.

``AirTail`` passes a stream's pieces on in arrival order but holds the air messages after the last
force seen so far; they go on, as a piece of their own, just before the next piece with forces.
What is held when the stream ends (``tail``) is the run past the bag's last force. ``replay_bag``
takes the checkpoint's state before feeding it (the state after the last force, the tail beside
it), then feeds it and closes the windows for this bag's own result, and writes that state once
the run is complete (``--out`` in place). The next bag's replay merges the
checkpoint's tail with its own messages by log time (``bagio.merged.MergedStream``'s ``held``),
so the chain reads what one merged replay of both bags reads, in the same order.

Re-cutting into chunks happens after this (``arrival_chunks``), so holding air between pieces
changes no chunk but the last: the shadow's calls are those of a replay without it, up to where
the tail begins.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from typing import Any

import numpy as np

from bridge_shadow.series import ForceSeries, MonitoringData, TemperatureSeries

__all__ = ["HELD_AIR_LIMIT", "AirTail", "air_piece", "mark_air_held_whole", "new_air", "split_air"]

#: Most air messages held at once (23 days at 1 Hz). Past it the held air goes on to the shadow,
#: and a checkpoint can hold only what came after: a longer air-only run is no bag of a record.
HELD_AIR_LIMIT = 2_000_000


def split_air(t: TemperatureSeries, from_log_ns: int) -> tuple[TemperatureSeries, TemperatureSeries]:
    """Return (messages of ``t`` with log time < ``from_log_ns``, the others), each in its order."""
    keep = np.asarray(t.log_ns) < from_log_ns
    return t.take(keep), t.take(~keep)


def new_air(tail: TemperatureSeries | None, held: TemperatureSeries | None, clock_ns: int | None) -> bool:
    """Whether ``tail`` (a bag's air past its last force) holds air a checkpoint does not have.

    Its own: a reading stamped after the checkpoint's data clock ``clock_ns`` that is not in the
    air it holds (``held``). A bag of older data has none (a copy of the bag that wrote it: the
    same air it holds); the bag run again after a run stopped past a periodic write that took all
    its forces has its tail, which the next bag's replay merges in.
    """
    if tail is None or not len(tail):
        return False
    stamps = np.asarray(tail.stamp_ns)
    if held is not None and len(held):
        stamps = stamps[~np.isin(stamps, np.asarray(held.stamp_ns))]
    return bool(len(stamps)) and (clock_ns is None or bool((stamps > clock_ns).any()))


def mark_air_held_whole(js: dict[str, Any], forces: int, held_air: int) -> None:
    """Mark the replay JSON ``js`` of a chain's bag of the air alone, held whole for the next bag.

    The day's air as a bag of its own, replayed first with ``--checkpoint``: ``forces`` (load-cell
    messages played) is 0 and ``held_air`` (air readings the checkpoint holds unfed) is all of it,
    merged with the next bag's forces. Nothing of it is lost and no window could close, so the
    run is no failure: it exited 1 ("no window updated the estimate") and warned "no load cell
    message", and a chain's script stopped at its first bag. ``air_held_whole`` (the count) is set
    and that warning dropped; the replay says what is held instead.
    """
    if forces or not held_air:
        return
    js["air_held_whole"] = int(held_air)
    js["warnings"] = [w for w in js["warnings"] if not w.startswith("no load cell message:")]


def air_piece(t: TemperatureSeries, channels: Iterable[str]) -> MonitoringData:
    """Return a ``MonitoringData`` piece holding the air messages ``t`` and no forces."""
    none = np.empty(0, np.int64)
    forces = {ch: ForceSeries(none, np.empty(0), np.empty(0, dtype=object), none) for ch in channels}
    return MonitoringData(forces, t)


class AirTail:
    """Pieces of a stream in arrival order, the air after the last force held until forces follow.

    Args:
        pieces: ``MonitoringData`` pieces, each wholly before the next in arrival order (log time,
            then frc_01, frc_02, air temperature).
        limit: most air messages held at once (``HELD_AIR_LIMIT``).

    Attributes:
        tail: once iterated to the end, the air messages after the stream's last force, all of them
            when it has no force (a bag of the air alone: fed before the next bag's forces, it
            made them all ``late``); None when there are none.
        released: air messages that went on past ``limit`` with no force after them yet.

    """

    def __init__(self, pieces: Iterable[MonitoringData], limit: int = HELD_AIR_LIMIT) -> None:
        self._pieces = pieces
        self.limit = int(limit)
        self.tail: TemperatureSeries | None = None
        self.released = 0
        self._channels: list[str] = []

    def __iter__(self) -> Iterator[MonitoringData]:
        held: list[TemperatureSeries] = []
        n_held = 0
        for piece in self._pieces:
            self._channels = list(piece.forces)
            logs = [f.log_ns for f in piece.forces.values() if len(f)]
            if not logs:  # air only: held until forces follow (before the first force too)
                if not len(piece.temperature):
                    yield piece
                    continue
                held.append(piece.temperature)
                n_held += len(piece.temperature)
                if n_held > self.limit:
                    self.released += n_held
                    yield air_piece(TemperatureSeries.concat(held), self._channels)
                    held, n_held = [], 0
                continue
            if held:
                yield air_piece(TemperatureSeries.concat(held), self._channels)
                held, n_held = [], 0
            # at one log time the air comes after the forces: from the last force's time on, it is past them
            last = max(int(x[-1]) for x in logs)
            before, after = split_air(piece.temperature, last)
            yield MonitoringData(piece.forces, before)
            if len(after):
                held.append(after)
                n_held += len(after)
        self.tail = TemperatureSeries.concat(held) if held else None
