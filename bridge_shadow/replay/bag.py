"""``replay_bag``: a bag through a ``Shadow`` in bounded memory, what ``bridge-shadow replay BAG`` runs."""

from __future__ import annotations

import time
from collections.abc import Callable, Collection, Iterable, Iterator, Sequence
from contextlib import ExitStack
from pathlib import Path
from typing import Any

from bridge_shadow.contract import CHANNELS
from bridge_shadow.replay.air_tail import AirTail, air_piece, split_air
from bridge_shadow.replay.chunks import DEFAULT_CHUNK, FeedChunk, arrival_chunks
from bridge_shadow.replay.feed import StreamReplay, feed_shadow
from bridge_shadow.replay.outputs import OutputBag, WindowHistory
from bridge_shadow.replay.prefetch import Prefetch
from bridge_shadow.replay.taken import forces_used, older_data, recorded

__all__ = ["replay_bag"]


def _result(shadow: Any, stats: StreamReplay, outputs: list[Any]) -> Any:
    """Return the shadow's ``ReplayResult`` after a streamed replay (``seconds``: time in the shadow).

    The same ``Shadow.result`` that ``Shadow.run`` uses (posterior, counts, events, warnings).
    """
    return shadow.result(outputs, stats.messages, stats.pipeline_s)


def _add(stats: StreamReplay, more: StreamReplay) -> None:
    """Add the counts and times of a later feed (the held air and the close) to ``stats``."""
    for name in ("messages", "pipeline_s", "read_s", "write_s", "windows_out"):
        setattr(stats, name, getattr(stats, name) + getattr(more, name))


def _held_unfed(chunks: Iterable[FeedChunk], shadow: Any, held: Any) -> Iterator[FeedChunk]:
    """Yield ``chunks``; meanwhile ``shadow.held_air`` is ``held`` from the last yielded chunk's log time on.

    A periodic checkpoint written while they are fed then keeps the held air still to come (written
    without it, a run interrupted after it lost the rest of the day's air for the bags after). The
    held air at a chunk's last log time is kept: one fed already comes again as a duplicate.
    """
    for c in chunks:
        shadow.held_air = split_air(held, c.last_log_ns)[1]
        yield c


class _ForceCount:
    """Chunks passed on, counting the load-cell messages in them; the state they began from."""

    def __init__(self, chunks: Iterable[FeedChunk], shadow: Any) -> None:
        self._chunks = chunks
        self.used_before = forces_used(shadow.used)
        self.clock_before = shadow.clock_ns
        self.fed = 0

    def __iter__(self) -> Iterator[FeedChunk]:
        for c in self._chunks:
            self.fed += sum(len(f[0]) for f in c.forces)
            yield c


def replay_bag(
    bag: str | Path | Sequence[str | Path],
    shadow: Any,
    *,
    out: str | Path | None = None,
    overwrite: bool = False,
    storage: str = "sqlite3",
    history: int | None = None,
    keep_all: bool = False,
    chunk: int = DEFAULT_CHUNK,
    batch: int | None = None,
    progress: Callable[[float], None] | None = None,
    prefetch: bool = True,
    required: bool | Collection[str] = True,
    taken: Sequence[dict[str, Any]] = (),
) -> tuple[Any, StreamReplay]:
    """Replay a bag through ``shadow`` in bounded memory; return its ``ReplayResult`` and timings.

    Args:
        bag: rosbag2 bag with the input topics (names from the shadow's ``topic_*`` parameters), or
            several bags read as one stream merged by log time (``bagio.merged.MergedStream``: bags
            that overlap in time; ``required`` then holds over them all).
        shadow: a fresh (or resumed) ``estimate.Shadow``.
        out: write the window outputs to this new bag as they close.
        overwrite: replace an existing bag at ``out`` (``--force``), once the new one is complete.
        storage: ``out``'s storage, ``sqlite3`` or ``mcap``.
        history: keep at most this many window outputs, evenly decimated (for plots); None keeps
            none, unless ``keep_all``.
        keep_all: keep every window output (memory grows with the bag: tests and short bags).
        chunk: messages per shadow call.
        batch: messages per bag read (default ``bagio.stream.DEFAULT_BATCH``).
        progress: called with the fraction of the bag's log-time span fed so far.
        prefetch: read and decode in a background thread (``Prefetch``), two chunks ahead, while
            the shadow works; the calls into the shadow and their order are the same either way.
            With a free core the replay takes about max(read, shadow) instead of their sum (10 Hz
            forces: 4.6 s -> 3.0 s); on a machine whose cores are all busy it gains nothing.
        required: input topics that must be in the bag (``bagio.stream.MonitoringStream``): True
            for all three, or the contract names of those required (the air temperature may be
            left out: the shadow then runs uncompensated and says so).
        taken: the signatures of the bags (``replay.taken.bag_signature``), recorded in the
            checkpoint as taken (``Shadow.taken_bags``) once the bag's last force is fed.

    Returns:
        ``(result, stats)``: ``result.outputs`` holds the kept window outputs and
        ``result.seconds`` the time inside the shadow; ``stats`` has the read time too (with
        ``prefetch``, ``read_s`` is the time the shadow waited for data and ``reader_s`` the
        reader thread's own time).

    Raises:
        BagError: the bag cannot be read (before anything is fed or written).

    """
    from bridge_shadow.bagio.merged import open_monitoring
    from bridge_shadow.bagio.stream import DEFAULT_BATCH

    t0 = time.perf_counter()
    config = shadow.config
    # the air past the last force of the bag that wrote the checkpoint: merged with this bag's own
    # messages by log time, as one replay of both bags reads them (``air_tail``)
    held = shadow.held_air
    held_piece = air_piece(held, CHANNELS) if held is not None and len(held) else None
    stream = open_monitoring(
        bag, held=held_piece, topics=config.input_topics(), batch=batch or DEFAULT_BATCH, required=required
    )
    shadow.held_air = None
    with stream:
        kept = WindowHistory(history) if history else None
        every: list[Any] = []
        report = None
        if progress is not None and stream.first_ns is not None and stream.last_ns is not None:
            first, span = stream.first_ns, max(stream.last_ns - stream.first_ns, 1)
            report = lambda log_ns: progress(min(max((log_ns - first) / span, 0.0), 1.0))  # noqa: E731
        sink = OutputBag(out, shadow, overwrite=overwrite, storage=storage) if out is not None else None

        def take(outs: list[Any]) -> None:
            if sink is not None:
                sink.write(outs)
            if kept is not None:
                kept.extend(outs)
            if keep_all:
                every.extend(outs)

        open_s = time.perf_counter() - t0
        final: dict[str, Any] | None = None  # the chain's checkpoint, written once the run is complete
        with ExitStack() as stack:
            # a checkpoint chain holds the air past the bag's last force (``air_tail``)
            tail = AirTail(stream) if config.checkpoint_path else None
            chunks: Iterable[FeedChunk] = arrival_chunks(tail if tail is not None else stream, chunk)
            reader = stack.enter_context(Prefetch(chunks)) if prefetch else None
            if sink is not None:
                stack.enter_context(sink)
            # the checkpoint holds the state before the end-of-data close: a replay of the next bag
            # resumed from it goes on with the last record still open, as one replay of both bags
            # would (written after the close, a bag split inside a record lost the next bag's
            # first seconds of that window as `late`: 7022 messages of the real records split 0.1 h
            # into the first record); and before the air past the bag's last force, which it holds
            # unfed for the next bag (fed, it closed windows hours past the record, and the next
            # bag's forces before the air's end were `late`)
            at_close: list[int] = []

            def before_close() -> None:
                at_close.extend((shadow.n_windows, shadow.n_updates))

            fed: Iterable[FeedChunk] = reader if reader is not None else chunks
            if held_piece is not None:
                fed = _held_unfed(fed, shadow, held)
            forces = _ForceCount(fed, shadow)
            fed = forces
            stats = feed_shadow(
                shadow,
                fed,
                take,
                report,
                flush=tail is None,
                before_flush=before_close,
            )
            stats.forces = forces.fed
            if tail is not None:
                before_close()
                stats.held_air = len(tail.tail) if tail.tail is not None else 0
                shadow.held_air = None  # the checkpoint's held air is all fed now
                used = (forces.used_before, forces_used(shadow.used))
                if older_data(forces.fed, used, (forces.clock_before, shadow.clock_ns), tail.tail, held):
                    # a checkpoint resumed from is left as it was (written, it counted the rejects
                    # and held this bag's air, older than its own), the bag is not taken
                    stats.checkpoint_kept = Path(config.checkpoint_path).is_file()
                else:
                    shadow.taken_bags = recorded(shadow.taken_bags, taken)  # known if replayed again
                # the checkpoint's state, written once the run is complete (written here, a run
                # stopped after it, in the tail's feed or --out's finish, exited 130 with the bag taken
                # whole, and its rerun rejected every message: exit 1)
                final = None if stats.checkpoint_kept else shadow.checkpoint_state(tail.tail)
                # this bag's result goes on to the air's end; no periodic write replaces the checkpoint
                shadow.checkpoints_paused = True
                try:
                    rest = arrival_chunks([air_piece(tail.tail, CHANNELS)], chunk) if tail.tail else []
                    _add(stats, feed_shadow(shadow, rest, take, report))
                finally:
                    shadow.checkpoints_paused = False
            # the flush's refit, when no output carried it (the tail's flush too: written before the
            # tail alone, a chain's bag ended at the posterior before it, the node's topics did not)
            if sink is not None:
                sink.write_final_posterior(*shadow.posterior)
            if at_close:
                stats.closed_at_end = shadow.n_windows - at_close[0]
                stats.updates_at_end = shadow.n_updates - at_close[1]
            if sink is not None:
                t1 = time.perf_counter()
                sink.finish()
                stats.write_s += time.perf_counter() - t1
        if final is not None:  # after --out is in place (its context's exit renames it there)
            shadow.save_checkpoint(state=final)
        stats.reader_s = reader.busy_s if reader is not None else stats.read_s
        stats.read_s += open_s
        stats.reader_s += open_s
        stats.backend = stream.backend
    if progress is not None:
        progress(1.0)
    outputs = every if keep_all else (kept.kept if kept is not None else [])
    return _result(shadow, stats, outputs), stats
