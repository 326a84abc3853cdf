"""``bridge-shadow archive``: replay a whole archive of bags, one bridge or many, on Dask."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

HELP = "replay an archive of bags (one bridge or many) on Dask: the same answer as one serial replay"
DESCRIPTION = """\
Replay an archive of rosbag2 bags through the shadow on Dask: every bag is decoded, gated and cut
into 60 s windows in parallel, then the shadow's sequential part (event detector, compensation
refits, settlement chain) runs over each bridge's windows in time order. Per bridge the result
is the JSON of `bridge-shadow replay` on the bags concatenated (to rounding), plus a summary of
every bridge's posterior over time.

PATH is one of
  a folder of bags                 one bridge, named after the folder
  a folder of bridge folders       one bridge per sub-folder (each a folder of bags)
  a glob of bags (quoted)          one bridge per parent folder, e.g. '/data/*/2024-*'
  a manifest (.yaml)               bridges: {NAME: {bags: [paths or globs], params: YAML,
                                   surrogate: YAML}}, paths relative to the manifest
A bridge folder may hold shadow.yaml (parameters) and surrogate.yaml beside its bags (else
config/shadow.yaml and the default surrogate). A bridge's bags are taken in the order of their
first message; bags of one bridge that overlap in time (a day's load records and its air
temperature as separate bags) are read together as one stream merged by log time, so none of
their messages is lost, and named as information.

Engine: a local Dask cluster on this machine (one worker process per core, on loopback) unless
--scheduler tcp://HOST:PORT names a running scheduler (`dask scheduler`, `dask worker ADDR`);
then the bags, the cache folder and the output folder must be at the same paths on every worker.

Long runs: a progress bar (Dask's) on a terminal; a rerun skips every bag already reduced
(cache keyed by the bag's content hash and the parameters that shape its windows: a new
surrogate or event threshold reuses it); a bag that cannot be read is named, skipped, and listed
in the summary, and nothing else is lost; Ctrl-C leaves only whole files (every output and
cache entry is written atomically).

Outputs in --out DIR (default: ./NAME.shadow for an archive NAME): bridges/NAME.json (the replay
JSON of each bridge), summary.csv (every bridge's posterior once per --summary-period, SI),
summary.png, index.json (bags, status, digests, failures, timings) and cache/ (the reductions).
--json prints one object: {"bridges": {NAME: replay JSON}, "bags": counts by status,
"failed_bags", "files", "seconds", "messages_per_s"}. Exit 1 when a bridge got no window into
its estimate (the replay's rule), or when bags overlap in time and could not be read merged (each
named: the later one's messages before the earlier one's end were lost), 0 otherwise (skipped
bags are WARN lines on stderr; bags read merged are info lines).

Examples:
  bridge-shadow synth --archive /tmp/fleet --bridges 3 --days 7 --rate 1
  bridge-shadow archive /tmp/fleet
  bridge-shadow archive /tmp/fleet --scheduler tcp://10.0.0.5:8786 --out /shared/fleet.shadow
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add PATH, --scheduler, --workers, --out, --cache, --summary-period, --json."""
    parser.add_argument("path", metavar="PATH", help="folder, quoted glob or manifest (.yaml) of bags")
    parser.add_argument(
        "--scheduler", metavar="ADDR", help="address of a running Dask scheduler (default: a local cluster)"
    )
    parser.add_argument(
        "--workers", type=int, metavar="N", help="local cluster: worker processes (default: one per core)"
    )
    parser.add_argument("--out", metavar="DIR", help="output folder (default: ./NAME.shadow)")
    parser.add_argument("--cache", metavar="DIR", help="reduction cache (default: OUT/cache)")
    parser.add_argument(
        "--summary-period",
        type=float,
        default=3600.0,
        metavar="S",
        help="seconds of stamp time between rows of summary.csv (default 3600: one an hour)",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object (SI units)")


def _default_out(path: str) -> Path:
    p = Path(path)
    name = "archive" if any(c in path for c in "*?[") else (p.stem if p.is_file() else p.resolve().name)
    return Path.cwd() / f"{name}.shadow"


def _n(count: int, noun: str) -> str:
    return f"{count} {noun}{'' if count == 1 else 's'}"


def _summary(js: dict[str, Any]) -> str:
    lines = []
    for name, res in js["bridges"].items():
        mean = res["posterior"]["mean_m"]
        sd = res["posterior"]["sigma_m"]
        post = ", ".join(
            f"{side} {1e3 * m:+.3f} ± {1.96e3 * s:.3f} mm"
            for side, m, s in zip(("south", "north"), mean, sd, strict=True)
        )
        merged = res.get("merged_bags", [])
        joined = f" ({sum(map(len, merged))} of them overlapping in time, read merged)" if merged else ""
        lines.append(
            f"{name}: {post}; {_n(len(res['bags']), 'bag')}{joined}, {res['messages']['total']} messages, "
            f"{res['windows']['updates']} window updates, {_n(len(res.get('events', [])), 'event')}"
        )
    bags = js["bags"]
    lines.append(
        f"bags: {bags['reduced']} reduced, {bags['cached']} from the cache, {bags['failed']} failed; "
        f"{js['seconds']:.1f} s, {js['messages_per_s']:.0f} msg/s on {_n(js['workers'], 'worker')}"
    )
    lines.append(f"outputs: {js['out']}")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Run the archive and print the result; exit 0 (1 when a bridge got no window update)."""
    import sys
    import time

    from bridge_shadow.archive.run import plan_bridges, run_archive, write_outputs
    from bridge_shadow.archive.sources import archive_sources
    from bridge_shadow.archive.tasks import merged_line
    from bridge_shadow.commands.output import emit_json
    from bridge_shadow.engine import dask_client
    from bridge_shadow.errors import InputError
    from bridge_shadow.fileio import check_output_dir

    started = getattr(args, "started", None) or time.perf_counter()
    if not (args.summary_period > 0 and args.summary_period < float("inf")):
        raise InputError(f"--summary-period must be a positive number of seconds (got {args.summary_period})")
    if args.workers is not None and args.scheduler:
        raise InputError("--workers sizes the local cluster; a --scheduler has its own workers")
    sources = archive_sources(args.path)
    plans = plan_bridges(sources)  # a bad parameter or surrogate file stops us before any work
    out = check_output_dir(args.out or _default_out(args.path), "archive output folder")
    cache = check_output_dir(args.cache or out / "cache", "archive cache folder")
    show = not args.json and sys.stderr.isatty()
    with dask_client(args.scheduler, args.workers) as client:
        result = run_archive(
            client, plans, cache.resolve(), summary_period_s=args.summary_period, show_progress=show
        )
    index = write_outputs(out, result, plans, cache)
    seconds = time.perf_counter() - started
    total = sum(b.result["messages"]["total"] for b in result.bridges)
    js = {
        "bridges": {b.name: b.result for b in result.bridges},
        "bags": index["bags"],
        "failed_bags": index["failed_bags"],
        "files": index["files"],
        "out": str(out),
        "workers": index["workers"],
        "scheduler": index["scheduler"],
        "seconds": seconds,
        "messages_per_s": total / seconds if seconds > 0 else float("inf"),
    }
    for f in index["failed_bags"]:
        print(
            f"bridge-shadow archive: WARN: skipped bag {f['bag']} ({f['bridge']}): {f['error']}",
            file=sys.stderr,
        )
    code = 0
    for b in result.bridges:
        for line in b.result.get("warnings", []):
            print(f"bridge-shadow archive: WARN: {b.name}: {line}", file=sys.stderr)
        for o in b.result.get("overlapping_bags", []):
            if o.get("merged"):
                print(f"bridge-shadow archive: info: {b.name}: {merged_line(o)}", file=sys.stderr)
        if any(not o.get("merged") for o in b.result.get("overlapping_bags", [])):
            print(
                f"bridge-shadow archive: error: {b.name}: bags overlap in time (named above): its result "
                "is not the stream's, the later bags' messages before the earlier ones' end were rejected",
                file=sys.stderr,
            )
            code = 1
        if not b.result["windows"]["updates"]:
            print(
                f"bridge-shadow archive: error: {b.name}: no window updated the estimate (its posterior is "
                "the prior)",
                file=sys.stderr,
            )
            code = 1
    if args.json:
        emit_json(js)
    else:
        print(_summary(js))
    return code
