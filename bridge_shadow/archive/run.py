"""Run an archive on Dask: a local cluster by default, a running scheduler when given its address.

The graph, per bridge: one ``bag_span_task`` per bag (its first and last log times: the order,
which bags overlap in time and which go on from the one before within ``gap_s``), one
``reduce_task`` per unit (a bag, or bags that overlap in time, read merged by log time; parallel,
across units and bridges) and one ``join_task`` that takes the
reductions in time order as they finish (parallel across bridges, overlapping the reductions).
Dask schedules it all; nothing here waits on a worker except through Dask's own futures and
progress bar.

``engine.dask_client`` gives the client (a local cluster on loopback, or ``--scheduler``);
``run_archive`` submits, waits with Dask's text progress bar (on stderr), and ``write_outputs``
writes the outputs, each atomically.
"""

from __future__ import annotations

import contextlib
import json
import sys
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bridge_shadow.archive.sources import BridgeSource
from bridge_shadow.archive.summary import DEFAULT_PERIOD_S
from bridge_shadow.archive.tasks import (
    BagOutcome,
    BridgeOutcome,
    bag_span_task,
    join_task,
    overlap_units,
    overlapping_bags,
    reduce_task,
)

__all__ = ["ArchiveRun", "plan_bridges", "run_archive", "write_outputs"]


@dataclass
class BridgePlan:
    """One bridge ready to submit: its source, parameters and surrogate (loaded and checked)."""

    source: BridgeSource
    config: Any
    surrogate: Any
    surrogate_path: str


@dataclass
class ArchiveRun:
    """What an archive run produced.

    Attributes:
        bridges: per bridge, its outcome (the replay JSON and its summary rows).
        bags: every bag's outcome, per bridge.
        seconds: wall time from submission to the last result; workers: Dask workers used.
        scheduler: the scheduler's address.

    """

    bridges: list[BridgeOutcome] = field(default_factory=list)
    bags: dict[str, list[BagOutcome]] = field(default_factory=dict)
    seconds: float = 0.0
    workers: int = 0
    scheduler: str = ""


def _start_key(item: tuple[tuple[int | None, int | None], Path]) -> tuple[bool, int, str]:
    (first, _), bag = item
    return (first is None, first or 0, str(bag))


def continuing_flags(spans: list[tuple[int | None, int | None]], gap_s: float) -> list[bool]:
    """For bags in time order: whether each starts within ``gap_s`` of the one before's end.

    A hint for the reduction (``reduce_bag(continuing=...)``), checked exactly by the join.
    """
    flags = [False] * len(spans)
    gap_ns = round(gap_s * 1e9)
    for i in range(1, len(spans)):
        (first, _), (_, last_before) = spans[i], spans[i - 1]
        flags[i] = first is not None and last_before is not None and 0 <= first - last_before < gap_ns
    return flags


def plan_bridges(sources: list[BridgeSource]) -> list[BridgePlan]:
    """Load and check each bridge's parameters and surrogate before anything runs.

    Raises:
        ConfigError, InputError: a parameter or surrogate file is unusable (one line naming it).

    """
    from bridge_shadow.estimate import load_config
    from bridge_shadow.model.surrogate_file import load_surrogate

    plans = []
    for src in sources:
        over = {"surrogate_path": str(src.surrogate.resolve())} if src.surrogate else None
        config = load_config(src.params, over).replace(checkpoint_path="")
        surrogate = load_surrogate(config.surrogate_path or None)
        plans.append(BridgePlan(src, config, surrogate, config.surrogate_path or "config/surrogate.yaml"))
    return plans


def run_archive(
    client: Any,
    plans: list[BridgePlan],
    cache: Path,
    *,
    summary_period_s: float = DEFAULT_PERIOD_S,
    show_progress: bool = False,
) -> ArchiveRun:
    """Submit every bag's reduction and every bridge's join; wait for them; return the outcomes."""
    from distributed import Queue, progress

    from bridge_shadow.bagio.merged import joined_span

    t0 = time.perf_counter()
    run = ArchiveRun(
        workers=len(client.scheduler_info().get("workers", {})), scheduler=client.scheduler.address
    )
    token = uuid.uuid4().hex[:8]  # keys of this run only (a shared scheduler may hold older ones)
    # the order of each bridge's bags (their first message) is known before they are reduced, so
    # its join takes them as they come, while later bags are still being reduced
    spans = client.gather(
        [
            client.map(bag_span_task, [str(b) for b in p.source.bags], config=p.config, pure=False)
            for p in plans
        ]
    )
    reduces: dict[str, list[Any]] = {}
    joins = []
    for plan, span in zip(plans, spans, strict=True):
        name = plan.source.name
        ordered = sorted(zip(span, plan.source.bags, strict=True), key=_start_key)
        # bags that overlap in time are reduced as one unit, merged by log time (nothing late)
        units = overlap_units([sp for sp, _ in ordered])
        bags = [[str(ordered[i][1]) for i in u] for u in units]
        unit_spans = [joined_span([ordered[i][0] for i in u]) for u in units]
        continuing = continuing_flags(unit_spans, plan.config.gap_s)
        merged = overlapping_bags(
            [BagOutcome(str(b), first_log_ns=f, last_log_ns=la) for (f, la), b in ordered]
        )
        queue = Queue(f"archive-{token}-{name}", client=client)
        # the join first (it waits outside the thread pool), then the bags in time order, whose
        # futures go into its queue as they are submitted
        joins.append(
            client.submit(
                join_task,
                name,
                plan.config,
                plan.surrogate,
                queue.name,
                len(bags),
                summary_period_s,
                merged,
                key=f"join-{token}-{name}",
                priority=1,
            )
        )
        futures = []
        for i, bag in enumerate(bags):
            futures.append(
                client.submit(
                    reduce_task,
                    bag[0] if len(bag) == 1 else bag,
                    plan.config,
                    plan.surrogate,
                    str(cache),
                    continuing[i],
                    key=f"reduce-{token}-{name}-{i}",
                )
            )
            queue.put(futures[-1])
        reduces[name] = futures
    everything = [f for fs in reduces.values() for f in fs] + joins
    if show_progress:
        with contextlib.redirect_stdout(sys.stderr):  # stdout is for --json alone
            progress(everything)
    run.bridges = client.gather(joins)
    run.bags = {name: client.gather(fs) for name, fs in reduces.items()}
    run.seconds = time.perf_counter() - t0
    return run


def write_outputs(out: Path, run: ArchiveRun, plans: list[BridgePlan], cache: Path) -> dict[str, Any]:
    """Write each bridge's JSON, the summary table and plot, and the index; return the index.

    ``out/bridges/NAME.json`` (the replay JSON of the bridge), ``out/summary.csv``,
    ``out/summary.png`` and ``out/index.json``, each written atomically.
    """
    from bridge_shadow.archive.summary import plot_summary, write_csv
    from bridge_shadow.fileio import atomic_write_text
    from bridge_shadow.jsonvalues import jsonable

    rows = [r for b in run.bridges for r in b.rows]
    files = {"summary_csv": str(write_csv(out / "summary.csv", rows))}
    if rows:
        files["summary_png"] = str(plot_summary(out / "summary.png", rows))
    bridges = []
    for b, plan in zip(run.bridges, plans, strict=True):
        path = out / "bridges" / f"{b.name}.json"
        atomic_write_text(path, json.dumps(jsonable(b.result), indent=2) + "\n", "bridge result")
        bags = run.bags[b.name]
        bridges.append(
            {
                "name": b.name,
                "result": str(path),
                "params": str(plan.source.params) if plan.source.params else "config/shadow.yaml",
                "surrogate": plan.surrogate_path,
                "posterior": b.result["posterior"],
                "events": len(b.result.get("events", [])),
                "updates": b.result["windows"]["updates"],
                "messages": b.result["messages"]["total"],
                "bags": [
                    {
                        "bag": o.bag,
                        "status": o.status,
                        "digest": o.digest,
                        "messages": o.messages,
                        "first_log_ns": o.first_log_ns,
                        "last_log_ns": o.last_log_ns,
                        "seconds": o.seconds,
                        **({"merged": o.merged} if o.merged else {}),
                        **({"dropped": [{"bag": d, "error": e} for d, e in o.dropped]} if o.dropped else {}),
                        **({"error": o.error} if o.error else {}),
                    }
                    for o in bags
                ],
                "failed_bags": [{"bag": p, "error": e} for p, e in b.failed],
                "fed_whole": b.fed_whole,
                "join_seconds": b.seconds,
            }
        )
    # per bag, not per unit: a unit of bags read merged counts each of them, and its dropped members
    statuses = [
        status
        for bags in run.bags.values()
        for o in bags
        for status in [o.status] * len(o.members) + ["failed"] * len(o.dropped)
    ]
    index = {
        "bridges": bridges,
        "bags": {s: statuses.count(s) for s in ("reduced", "cached", "failed")},
        "failed_bags": [{"bridge": b.name, "bag": p, "error": e} for b in run.bridges for p, e in b.failed],
        "files": files,
        "cache": str(cache),
        "workers": run.workers,
        "scheduler": run.scheduler,
        "seconds": run.seconds,
    }
    atomic_write_text(out / "index.json", json.dumps(jsonable(index), indent=2) + "\n", "archive index")
    files["index"] = str(out / "index.json")
    return index
