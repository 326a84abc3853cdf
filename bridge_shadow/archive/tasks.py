"""The two kinds of Dask task of an archive: reduce one bag, join one bridge (plain functions).

Both run on a worker and talk through the reduction cache (``archive.cache``): ``reduce_task``
writes a bag's reduction there and returns a small ``BagOutcome``; ``join_task`` takes the
outcomes of its bridge in time order as they come (it waits outside the worker's thread pool, so
the sequential part overlaps the reduction of later bags) and reads each reduction back from the
cache, so a worker holds one bag's reduction at a time however long the archive is.
``bag_span_task`` finds a bag's first and last log times, which fix the order (and which bags go on
from the one before) before anything is reduced.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bridge_shadow.archive.cache import ReductionCache, front_key
from bridge_shadow.archive.reduce import BagReduction, reduce_bag

__all__ = ["BagOutcome", "BridgeOutcome", "bag_span_task", "join_task", "reduce_task", "time_order"]


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


def reduce_task(
    bag: str, config: Any, surrogate: Any, cache_root: str, continuing: bool = False
) -> BagOutcome:
    """Reduce one bag into the cache (or find it there); a bag that cannot be read is ``failed``.

    ``continuing``: the bag goes on from the one before (``archive.reduce.reduce_bag``).
    """
    from bridge_shadow.bagio import BagError

    t0 = time.perf_counter()
    cache = ReductionCache(cache_root)
    out = BagOutcome(bag)
    path = Path(bag)
    try:
        if not path.exists():
            raise FileNotFoundError(f"{bag}: no such bag")
        out.digest = cache.digest(path)
        entry = cache.path(out.digest, front_key(config, continuing))
        red = cache.load(entry)
        if isinstance(red, BagReduction):
            out.status = "cached"
        else:
            red = reduce_bag(path, config, surrogate, continuing=continuing)
            cache.store(entry, red)
            out.status = "reduced"
    except (BagError, OSError) as err:
        out.error = " ".join(str(err).split()) or type(err).__name__
        out.seconds = time.perf_counter() - t0
        return out
    out.entry = str(entry)
    out.messages, out.first_log_ns, out.last_log_ns = red.messages, red.first_log_ns, red.last_log_ns
    out.seconds = time.perf_counter() - t0
    return out


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
    end of one joined earlier are rejected (``late``, ``out_of_order``). A day whose load records
    and air temperature came as separate bags lost most of its forces that way, with no bag
    named (a helper session's real-record archives).
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
    name: str, config: Any, surrogate: Any, queue: str, n_bags: int, summary_period_s: float
) -> BridgeOutcome:
    """Run the bridge's shadow over its bags in time order, each as soon as it is reduced.

    ``queue`` names the Dask queue that gets the bridge's ``n_bags`` reduce futures in the
    expected time order (by ``bag_span_task``); the join checks each bag's actual first message
    against it, and if a bag turns out earlier than one already joined, it starts over in the
    actual order (exact either way).
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
                red = reduce_bag(Path(o.bag), config, surrogate)
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
    failed = [(o.bag, o.error) for o in seen if o.status == "failed"]
    result["bridge"] = name
    result["bags"] = [o.bag for o in time_order(seen)]
    overlaps = overlapping_bags(time_order(seen))
    result["overlapping_bags"] = overlaps
    result["warnings"] = [*result.get("warnings", []), *(_overlap_line(o) for o in overlaps)]
    result["failed_bags"] = [{"bag": b, "error": e} for b, e in failed]
    result["surrogate"] = surrogate.summary()  # as replay's (its condition number was missing)
    return BridgeOutcome(name, result, rows.finish(shadow), failed, stats.fed_whole, seconds)


class _OutOfOrder(Exception):
    """A bag began before one already joined (its metadata said otherwise): join again in order."""
