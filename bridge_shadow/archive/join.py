"""The sequential part of an archive: one shadow over the reduced bags of a bridge, in time order.

For each bag (``archive.reduce.BagReduction``) the archive's shadow

1. is fed the bag's head chunks by ``replay``'s own feeding code (ingest per topic, ``poll``),
   until its front end *behaves* as the bag's own front end did at the same point
   (``frontstate.same_behaviour``: the gates and the window buffer hold equal states);
2. takes the windows the bag's front end closed after that point (``Shadow.take_windows``),
   adds what its gates decided meanwhile (``frontstate.add_bookkeeping``), and takes over its
   front end at the bag's end (``frontstate.load_behaviour``).

From equal states, equal messages give equal decisions and equal windows (the front end holds
stamps and raw values, never a computed float), so the result is the serial ``replay`` of the
bags concatenated. One more input reaches a gate: a topic's *first* accepted message is checked
against the span of the data clock, whose start the bag's own front end does not know. So when
this shadow has accepted data before the bag, a snapshot where a gate has not accepted yet only
counts when that gate accepts nothing, and holds nothing back, to the bag's end.

The buffers are compared less what no window still to close reads (``WindowBuffer.behaviour_state``):
the archive's front end holds the previous record's last air reading across a gap, a bag's own
front end that closed no window yet (a record held for the traffic screen) still holds its air
readings from the bag's first; neither is read once the forces have started after them.

A bag whose seam does not settle within its head (a clock jump held over the seam, a topic that
starts late in the bag, forces that start before the bag's first air reading after a gap) is fed
whole from the bag file, as ``replay`` would feed it: exact, only not parallel
(``JoinStats.fed_whole`` counts those bags).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any

from bridge_shadow.archive.frontstate import (
    FrontState,
    add_bookkeeping,
    front_state,
    load_behaviour,
    same_behaviour,
)
from bridge_shadow.archive.reduce import BagReduction, split_log
from bridge_shadow.replay.chunks import DEFAULT_CHUNK, arrival_chunks
from bridge_shadow.replay.feed import feed_shadow
from bridge_shadow.series import MonitoringData

__all__ = ["JoinStats", "join_bags", "seam_synced"]


@dataclass
class JoinStats:
    """What the join did.

    Attributes:
        messages: input messages of the bags joined.
        bags: bags joined; fed_whole: bags fed from their file (their seam did not settle).
        head_chunks: head chunks fed again (seams).
        windows_taken: windows taken from the reductions; windows_out: window outputs.

    """

    messages: int = 0
    bags: int = 0
    fed_whole: list[str] = field(default_factory=list)
    head_chunks: int = 0
    windows_taken: int = 0
    windows_out: int = 0


def seam_synced(
    now: FrontState, snap: FrontState, end: FrontState, fresh: bool, window_buffer: Any = None
) -> bool:
    """Whether the archive's front end (``now``) continues exactly as the bag's own from ``snap``.

    ``fresh``: the archive's shadow had accepted nothing before this bag (then the data clock's
    start is the bag's own too). ``end`` is the bag's front end after its last message.
    ``window_buffer``: the archive's ``WindowBuffer``, whose parameters say what of a buffer's
    state no later window reads (``frontstate.same_behaviour``).
    """
    if not same_behaviour(now, snap, window_buffer):
        return False
    if fresh:
        return True
    for s, e in zip(snap.gates, end.gates, strict=True):
        if not bool(s["has_last"]) and (bool(e["has_last"]) or len(e["pending_ns"]) or bool(e["has_held"])):
            return False  # a first message after the snapshot: checked against a clock span we differ in
    return True


def _rest_of_bag(red: BagReduction, head_end_ns: int | None, config: Any) -> Iterator[MonitoringData]:
    """Yield the bag's messages from ``head_end_ns`` on (all when None), read as ``replay`` reads them.

    A merged unit (``red.bags``) is read merged again, as its reduction read it.
    """
    from bridge_shadow.bagio.merged import open_monitoring

    paths = list(red.bags) or [red.bag]
    with open_monitoring(paths, topics=config.input_topics(), required=False) as stream:
        for piece in stream:
            if head_end_ns is not None:
                piece = split_log(piece, head_end_ns)[1]
            if piece.n_messages:
                yield piece


def join_bags(
    shadow: Any,
    reductions: Iterable[BagReduction],
    on_outputs: Callable[[list[Any]], None] | None = None,
    flush: bool = True,
) -> JoinStats:
    """Run ``shadow`` over reduced bags in the order given (each wholly after the one before).

    Args:
        shadow: the bridge's ``estimate.Shadow`` (fresh, or resumed).
        reductions: the bags' reductions in time order (any iterable: one is held at a time).
        on_outputs: called with each non-empty list of window outputs, in window order.
        flush: close the open windows after the last bag (the end of a replay).

    Returns:
        the join's counts; the shadow holds the result (``shadow.result``).

    """
    stats = JoinStats()
    take = on_outputs if on_outputs is not None else (lambda outs: None)

    def emit(outs: list[Any]) -> None:
        if outs:
            stats.windows_out += len(outs)
            take(outs)

    fresh = front_state(shadow).never_accepted
    for red in reductions:
        stats.bags += 1
        stats.messages += red.messages
        if red.end is None or not red.head:
            continue  # no input message in the bag
        synced = None
        for j, chunk in enumerate(red.head):
            feed_shadow(shadow, [chunk], emit, flush=False)
            stats.head_chunks += 1
            now = front_state(shadow)
            if seam_synced(now, red.snapshots[j], red.end, fresh, shadow.buffer):
                synced = j
                break
        if synced is None:
            # the seam did not settle: feed the rest of the bag as replay would
            stats.fed_whole.append(red.bag)
            pieces = _rest_of_bag(red, red.head_end_ns, shadow.config)
            feed_shadow(shadow, arrival_chunks(pieces, DEFAULT_CHUNK), emit, flush=False)
        else:
            batch = red.windows_after(synced)
            stats.windows_taken += len(batch)
            add_bookkeeping(shadow, red.end, red.snapshots[synced])
            emit(shadow.take_windows(batch))
            load_behaviour(shadow, red.end)
        fresh = fresh and front_state(shadow).never_accepted
    if flush:
        emit(shadow.flush())
    return stats
