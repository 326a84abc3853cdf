"""The two kinds of Dask task of an archive: reduce one bag, join one bridge (plain functions).

Both run on a worker and talk through the reduction cache (``archive.cache``): ``reduce_task``
writes a bag's reduction there and returns a small ``BagOutcome``; ``join_task`` takes the
outcomes of its bridge in time order as they come (it waits outside the worker's thread pool, so
the sequential part overlaps the reduction of later bags) and reads each reduction back from the
cache, so a worker holds one bag's reduction at a time however long the archive is.
``bag_span_task`` finds a bag's first and last log times, which fix the order (and which bags go on
from the one before) before anything is reduced. Bags whose spans overlap (``overlap_units``: a
day's load records and its air temperature as separate bags) are one *unit*: one ``reduce_task``
reads them as one stream merged by log time (``bagio.merged``), so the join loses none of them.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bridge_shadow.archive.cache import ReductionCache, front_key
from bridge_shadow.archive.reduce import BagReduction, reduce_bag

__all__ = [
    "BagOutcome",
    "BridgeOutcome",
    "bag_span_task",
    "join_task",
    "merged_line",
    "overlap_units",
    "overlapping_bags",
    "reduce_task",
    "time_order",
    "unit_digest",
]


@dataclass
class BagOutcome:
    """What became of one bag.

    Attributes:
        bag: its path; digest: its content hash ("" when it could not be read at all).
        status: ``reduced`` (now), ``cached`` (by an earlier run) or ``failed``.
        error: why it failed (one line; empty otherwise).
        entry: the cache entry holding its reduction.
        messages: input messages; first_log_ns, last_log_ns: its log-time span (None: empty).
        seconds: wall time of this task.
        merged: the bags of a unit that overlap in time, reduced as one merged stream (``bag`` is the
            first of them; empty for a bag on its own).
        dropped: members of such a unit that could not be read, each with its error: the unit was
            reduced again without them (one corrupt record must not cost the day's other bags).

    """

    bag: str
    digest: str = ""
    status: str = "failed"
    error: str = ""
    entry: str = ""
    messages: int = 0
    first_log_ns: int | None = None
    last_log_ns: int | None = None
    seconds: float = 0.0
    merged: list[str] = field(default_factory=list)
    dropped: list[tuple[str, str]] = field(default_factory=list)

    @property
    def members(self) -> list[str]:
        """The bags of this outcome: the merged unit's, or the one bag."""
        return list(self.merged) or [self.bag]


def unit_digest(digests: list[str]) -> str:
    """Return the content digest of bags reduced as one merged unit: over their digests, in order.

    The order counts (it breaks ties of log time), so the same bags in another order are another unit.
    """
    import hashlib

    h = hashlib.blake2b(digest_size=20)
    h.update(("merged:" + ",".join(digests)).encode())
    return h.hexdigest()


def reduce_task(
    bag: str | list[str], config: Any, surrogate: Any, cache_root: str, continuing: bool = False
) -> BagOutcome:
    """Reduce one bag into the cache (or find it there); a bag that cannot be read is ``failed``.

    ``bag``: one bag, or the bags of a unit that overlap in time (in time order), reduced as one
    stream merged by log time; its cache entry is keyed by every bag's content (``unit_digest``).
    ``continuing``: the bag goes on from the one before (``archive.reduce.reduce_bag``). A member
    of a unit that cannot be read (it opened, but a chunk is corrupt) is dropped and the unit
    reduced again without it (``BagOutcome.dropped``): a day's air bag joins every record of the
    day into one unit, and one corrupt record lost them all, a good bag named as the failed one.
    """
    t0 = time.perf_counter()
    bags = [bag] if isinstance(bag, str) else list(bag)
    dropped: list[tuple[str, str]] = []
    while True:
        out, culprit = _reduce_unit(bags, config, surrogate, ReductionCache(cache_root), continuing)
        if out.status != "failed" or len(bags) < 2 or culprit not in bags:
            break
        dropped.append((culprit, out.error))
        bags = [b for b in bags if b != culprit]
    out.dropped = dropped
    out.seconds = time.perf_counter() - t0
    return out


def _reduce_unit(
    bags: list[str], config: Any, surrogate: Any, cache: ReductionCache, continuing: bool
) -> tuple[BagOutcome, str | None]:
    """Reduce one unit (``reduce_task``); return its outcome and the member that failed (None: none known)."""
    from bridge_shadow.bagio import BagError

    out = BagOutcome(bags[0], merged=bags if len(bags) > 1 else [])
    paths = [Path(b) for b in bags]
    culprit: str | None = None
    try:
        digests = []
        for b, path in zip(bags, paths, strict=True):
            culprit = b
            if not path.exists():
                raise FileNotFoundError(f"{b}: no such bag")
            digests.append(cache.digest(path))
        culprit = None
        out.digest = digests[0] if len(digests) == 1 else unit_digest(digests)
        entry = cache.path(out.digest, front_key(config, continuing))
        red = cache.load(entry)
        if isinstance(red, BagReduction):
            out.status = "cached"
        else:
            red = reduce_bag(paths if len(paths) > 1 else paths[0], config, surrogate, continuing=continuing)
            cache.store(entry, red)
            out.status = "reduced"
    except (BagError, OSError) as err:
        out.error = " ".join(str(err).split()) or type(err).__name__
        return out, culprit if culprit is not None else getattr(err, "bag", None)
    out.entry = str(entry)
    out.messages, out.first_log_ns, out.last_log_ns = red.messages, red.first_log_ns, red.last_log_ns
    return out, None


@dataclass
class BridgeOutcome:
    """The result of one bridge: its replay JSON, its posterior over time, the bags skipped.

    Attributes:
        name: the bridge; result: ``ReplayResult.to_json()`` plus archive keys.
        rows: the summary table's rows of this bridge (``archive.summary``).
        failed: the bags that could not be read, ``(path, reason)``.
        fed_whole: bags whose seam did not settle in their head (fed from their file).
        seconds: wall time of the join.

    """

    name: str
    result: dict[str, Any]
    rows: list[dict[str, Any]] = field(default_factory=list)
    failed: list[tuple[str, str]] = field(default_factory=list)
    fed_whole: list[str] = field(default_factory=list)
    seconds: float = 0.0


def bag_span_task(bag: str, config: Any) -> tuple[int | None, int | None]:
    """Return the log times of a bag's first and last messages (None: unreadable or empty).

    As the reduction reads them.
    """
    from bridge_shadow.bagio import BagError
    from bridge_shadow.bagio.stream import MonitoringStream

    try:
        with MonitoringStream(bag, topics=config.input_topics(), required=False) as stream:
            if stream.first_ns is None or stream.last_ns is None:
                return None, None
            return int(stream.first_ns), int(stream.last_ns)
    except (BagError, OSError):
        return None, None


def overlapping_bags(ordered: list[BagOutcome]) -> list[dict[str, Any]]:
    """Return each bag (in time order) that begins before an earlier one has ended, with that one.

    The join takes a bridge's bags one after the other; the messages of a bag that lie before the
    end of one joined earlier would be rejected (``late``, ``out_of_order``). A day whose load
    records and air temperature came as separate bags lost most of its forces that way. So
    ``archive.run`` reduces bags that overlap as one unit merged by log time (``overlap_units``)
    and names them here; an overlap left between the join's units (their spans not known before)
    still loses messages.
    """
    out = []
    latest: tuple[str, int] | None = None  # the bag that ends last so far, and its end
    for o in ordered:
        if o.first_log_ns is None or o.last_log_ns is None:
            continue
        if latest is not None and o.first_log_ns < latest[1]:
            out.append(
                {"bag": o.bag, "first_log_ns": o.first_log_ns, "before": latest[0], "ends_ns": latest[1]}
            )
        if latest is None or o.last_log_ns > latest[1]:
            latest = (o.bag, o.last_log_ns)
    return out


def overlap_units(spans: list[tuple[int | None, int | None]]) -> list[list[int]]:
    """Group bags in time order into units: runs of bags whose [first, last] log-time spans overlap.

    A bag that begins before an earlier bag of its unit has ended joins that unit (connected
    components of overlapping spans; a bag beginning at the very log time another ends does not
    overlap it, as ``overlapping_bags`` says). A bag with no span (unreadable, empty) is a unit
    of its own.
    """
    units: list[list[int]] = []
    end: int | None = None  # the latest end of the last unit
    for i, (first, last) in enumerate(spans):
        if first is None or last is None:
            units.append([i])
            end = None
            continue
        if end is not None and first < end:
            units[-1].append(i)
            end = max(end, last)
        else:
            units.append([i])
            end = last
    return units


def merged_line(o: dict[str, Any]) -> str:
    """Return the information line of an overlap read merged (nothing lost)."""
    from bridge_shadow.timefmt import iso_utc

    return (
        f"bags overlap in time: {o['bag']} begins at {iso_utc(o['first_log_ns'])}, before {o['before']} "
        f"ends at {iso_utc(o['ends_ns'])}: read together as one stream merged by log time, nothing lost"
    )


def _overlap_line(o: dict[str, Any]) -> str:
    from bridge_shadow.timefmt import iso_utc

    return (
        f"bags overlap in time: {o['bag']} begins at {iso_utc(o['first_log_ns'])}, before {o['before']} "
        f"ends at {iso_utc(o['ends_ns'])}: a bridge's bags are taken one after the other, so its "
        "messages before that were rejected (late, out of order); import records that overlap into "
        "one bag (import-csv of their files together)"
    )


def time_order(outcomes: list[BagOutcome]) -> list[BagOutcome]:
    """Return the bags that were read, by their first message (log time), then path; empty ones last."""
    ok = [o for o in outcomes if o.status != "failed"]
    return sorted(ok, key=lambda o: (o.first_log_ns is None, o.first_log_ns or 0, o.bag))


def _outcomes(queue: str, n: int) -> Iterator[BagOutcome]:
    """Yield the outcomes of the bridge's ``n`` reduce tasks in time order, each as soon as it is there.

    The client puts the reduce futures, in time order, into the Dask ``Queue`` named ``queue``:
    handing futures between clients is what it is for. The join task leaves the worker's thread
    pool while it waits (``worker_client``), so that worker goes on reducing bags meanwhile.
    """
    from distributed import Queue, worker_client

    with worker_client() as client:
        futures = Queue(queue, client=client)
        for _ in range(n):
            future = futures.get()
            yield future.result()
            future.release()


def join_task(
    name: str,
    config: Any,
    surrogate: Any,
    queue: str,
    n_bags: int,
    summary_period_s: float,
    merged: list[dict[str, Any]] | None = None,
) -> BridgeOutcome:
    """Run the bridge's shadow over its bags in time order, each as soon as it is reduced.

    ``queue`` names the Dask queue that gets the bridge's ``n_bags`` reduce futures in the
    expected time order (by ``bag_span_task``); the join checks each bag's actual first message
    against it, and if a bag turns out earlier than one already joined, it starts over in the
    actual order (exact either way). ``n_bags`` counts the units (a merged unit is one);
    ``merged``: the overlaps within the units (``overlapping_bags`` of their bags), named in
    the result as information.
    """
    from bridge_shadow.archive.join import join_bags
    from bridge_shadow.archive.summary import PeriodicRows
    from bridge_shadow.estimate.shadow import Shadow

    t0 = time.perf_counter()
    seen: list[BagOutcome] = []

    def reductions(source: Iterator[BagOutcome], check: bool) -> Iterator[BagReduction]:
        last: tuple[bool, int, str] | None = None
        for o in source:
            seen.append(o)
            if o.status == "failed":
                continue
            order = (o.first_log_ns is None, o.first_log_ns or 0, o.bag)
            if check and last is not None and order < last:
                raise _OutOfOrder
            last = order
            red = ReductionCache(Path(o.entry).parent).load(Path(o.entry))
            if not isinstance(red, BagReduction):  # removed while we ran: reduce it again
                red = reduce_bag([Path(b) for b in o.members], config, surrogate)
            yield red

    def run(source: Iterator[BagOutcome], check: bool) -> tuple[Any, Any, PeriodicRows]:
        shadow = Shadow(config.replace(checkpoint_path=""), surrogate)
        rows = PeriodicRows(name, summary_period_s)
        return shadow, join_bags(shadow, reductions(source, check), rows.add), rows

    try:
        outcomes = _outcomes(queue, n_bags)
        shadow, stats, rows = run(outcomes, check=True)
    except _OutOfOrder:
        rest = list(outcomes)
        everything = time_order(seen + rest)
        seen.clear()
        shadow, stats, rows = run(iter(everything), check=False)
    seconds = time.perf_counter() - t0
    result = shadow.result([], stats.messages, seconds).to_json()
    failed = [(o.bag, o.error) for o in seen if o.status == "failed"] + [d for o in seen for d in o.dropped]
    result["bridge"] = name
    result["bags"] = [b for o in time_order(seen) for b in o.members]
    # overlaps within a unit were read merged (information); one left between units lost messages
    lost = [{**o, "merged": False} for o in overlapping_bags(time_order(seen))]
    gone = {b for o in seen for b, _ in o.dropped}  # unreadable members: not read with the others
    read = [o for o in merged or [] if o["bag"] not in gone and o["before"] not in gone]
    result["overlapping_bags"] = [{**o, "merged": True} for o in read] + lost
    result["merged_bags"] = [o.members for o in time_order(seen) if o.merged]
    result["warnings"] = [*result.get("warnings", []), *(_overlap_line(o) for o in lost)]
    result["failed_bags"] = [{"bag": b, "error": e} for b, e in failed]
    result["surrogate"] = surrogate.summary()  # as replay's (its condition number was missing)
    return BridgeOutcome(name, result, rows.finish(shadow), failed, stats.fed_whole, seconds)


class _OutOfOrder(Exception):
    """A bag began before one already joined (its metadata said otherwise): join again in order."""
