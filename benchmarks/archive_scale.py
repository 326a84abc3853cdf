"""``bridge-shadow archive`` at scale: against serial replay and rosbags' raw read of the same bags.

Archives come from ``bridge-shadow synth --archive`` (one bridge, daily bags, sqlite3) into
``/tmp/bridge_shadow_bench/archive-<case>/`` and are reused by later runs (the generation time is
printed when made). For each case, in one run:

- ``rosbags raw read``: ``Reader.messages()`` over every bag, bytes only (the baseline);
- ``serial replay``: one ``Shadow`` fed every bag in time order by ``replay``'s own streaming
  reader and feeder, in this process (what ``replay`` of the bags concatenated does);
- ``archive, 1 worker`` and ``archive, 2 workers``: the archive's reduce and join tasks on a local
  process cluster, each with an empty cache, then ``archive, cached``: the 2-worker run again
  (only the sequential part runs);

printing wall times, the ratios to the raw read and to the serial replay, the 1 -> 2 worker
speed-up and efficiency (goal >= 0.8), the peak RSS of every worker (``VmHWM``), the measured
cost per bag (reduce) and per window (join), and from those the plan for 16 to 64 workers.

Cases: ``1hz-30d`` (30 daily bags at 1 Hz, 5.2 M messages) and ``100hz-1d`` (24 hourly bags at
100 Hz, 17 M messages) by default; the issue's ``1hz-365d`` (365 daily bags, 63 M messages, a
7 GB archive) and ``100hz-30d`` (30 daily bags, 518 M messages, about 58 GB in sqlite3) run only
when named: their generation (``synth --archive --workers 2``: the bags written on two worker
processes, sqlite3 rows inserted in bulk) took 583 s for the year (serially, before the bulk
insert) and 925 s for the 30 days at 100 Hz (58 GB) here. ``100hz-4d`` (4 daily bags
at 100 Hz, 69 M messages) is the daily 100 Hz bag at a size this machine's disk and a session
hold: two rounds of bags on two workers. Usage::

    .venv/bin/python benchmarks/archive_scale.py [--cases 1hz-30d,100hz-1d] [--workers 2]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

from _common import rosbags_raw

BENCH_DIR = Path("/tmp/bridge_shadow_bench")
BIN = Path(sys.executable).parent / "bridge-shadow"
#: name -> (days, force rate Hz, days per bag)
CASES: dict[str, tuple[float, float, float]] = {
    "1hz-30d": (30.0, 1.0, 1.0),
    "100hz-1d": (1.0, 100.0, 1.0 / 24.0),
    "1hz-365d": (365.0, 1.0, 1.0),
    "100hz-30d": (30.0, 100.0, 1.0),
    "100hz-4d": (4.0, 100.0, 1.0),
}
DEFAULT_CASES = "1hz-30d,100hz-1d"


def make_archive(name: str, workers: int) -> tuple[Path, float]:
    """Write (or reuse) the case's archive; return its bridge folder and the seconds it took (0: reused).

    ``synth --archive --workers N``: the bags are written on a local Dask cluster of N processes.
    """
    days, rate, bag_days = CASES[name]
    root = BENCH_DIR / f"archive-{name}"
    bridge = root / "bridge_00"
    if (bridge / "truth.yaml").is_file():
        return bridge, 0.0
    BENCH_DIR.mkdir(parents=True, exist_ok=True)
    cmd = [str(BIN), "synth", "--archive", str(root), "--days", str(days), "--rate", str(rate)]
    t0 = time.perf_counter()
    more = ["--bag-days", str(bag_days), "--seed", "7", "--overwrite", "--workers", str(workers)]
    subprocess.run([*cmd, *more], check=True)
    return bridge, time.perf_counter() - t0


def serial_replay(bags: list[Path]) -> tuple[float, dict]:
    """One shadow over every bag in order, as ``replay`` streams and feeds one bag; (seconds, JSON)."""
    from bridge_shadow.bagio.stream import MonitoringStream
    from bridge_shadow.estimate import load_config
    from bridge_shadow.estimate.shadow import Shadow
    from bridge_shadow.model.surrogate_file import load_surrogate
    from bridge_shadow.replay import arrival_chunks, feed_shadow

    t0 = time.perf_counter()
    config = load_config()
    shadow = Shadow(config, load_surrogate())

    def pieces():
        for bag in bags:
            with MonitoringStream(bag, topics=config.input_topics(), required=False) as stream:
                yield from stream

    stats = feed_shadow(shadow, arrival_chunks(pieces()))
    seconds = time.perf_counter() - t0
    return seconds, shadow.result([], stats.messages, seconds).to_json()


def _worker_hwm_mb() -> float:
    with open("/proc/self/status") as f:
        kb = next(line.split()[1] for line in f if line.startswith("VmHWM:"))
    return int(kb) / 1024.0


def archive_run(bridge: Path, workers: int, cache: Path) -> dict:
    """Run the archive on a fresh local process cluster: seconds, peak RSS per worker, the run's index."""
    from bridge_shadow.archive.run import plan_bridges, run_archive
    from bridge_shadow.archive.sources import archive_sources
    from bridge_shadow.engine import dask_client

    t0 = time.perf_counter()
    plans = plan_bridges(archive_sources(str(bridge)))
    with dask_client(workers=workers) as client:
        t1 = time.perf_counter()
        run = run_archive(client, plans, cache)
        hwm = sorted(client.run(_worker_hwm_mb).values())
    total = time.perf_counter() - t0
    (b,) = run.bridges
    bags = run.bags[b.name]
    return {
        "seconds": total,
        "run_s": run.seconds,
        "cluster_s": t1 - t0,
        "hwm_mb": hwm,
        "result": b.result,
        "join_s": b.seconds,
        "reduce_s": [o.seconds for o in bags if o.status == "reduced"],
        "fed_whole": b.fed_whole,
    }


def plan_text(per_bag_s: float, per_window_s: float, bags_per_year: int, windows_per_year: int) -> str:
    """Return the wall time of a year of B bridges on W workers, from the measured costs.

    Each bridge's join is one sequential chain of ``windows x per_window`` (it overlaps the
    reductions: it takes each bag as it is reduced); the reductions and the joins share the W
    cores. So wall = max(the longest chain of joins on a worker, all the work / W).
    """
    lines = []
    join_s = windows_per_year * per_window_s
    for w in (16, 32, 64):
        for bridges in (1, 10, 64):
            work_s = bridges * (bags_per_year * per_bag_s + join_s)
            chain_s = join_s * -(-bridges // w)
            wall_s = max(chain_s, work_s / w)
            bound = "the join chain" if chain_s >= work_s / w else "the cores"
            lines.append(
                f"  {w:2d} workers, {bridges:2d} bridges x 1 year: work {work_s / 3600:6.2f} core-h, "
                f"join chain {chain_s / 60:5.1f} min -> wall {wall_s / 60:6.1f} min (bound by {bound})"
            )
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", default=DEFAULT_CASES)
    parser.add_argument("--workers", type=int, default=2, help="the larger local cluster (default 2)")
    args = parser.parse_args()
    import numpy as np

    for name in args.cases.split(","):
        bridge, made_s = make_archive(name, args.workers)
        bags = sorted(p for p in bridge.iterdir() if p.is_dir())
        made = f" (written in {made_s:.0f} s)" if made_s else ""
        print(f"== {name}: {len(bags)} bags in {bridge}{made}")
        t0 = time.perf_counter()
        n_raw = sum(rosbags_raw(b) for b in bags)
        raw_s = time.perf_counter() - t0
        serial_s, ref = serial_replay(bags)
        assert ref["messages"]["total"] == n_raw
        runs = {}
        for w in (1, args.workers):
            cache = BENCH_DIR / f"cache-{name}-{w}-{time.time_ns()}"
            runs[w] = archive_run(bridge, w, cache)
        runs["cached"] = archive_run(bridge, args.workers, cache)
        for key, r in runs.items():
            got, want = np.array(r["result"]["posterior"]["mean_m"]), np.array(ref["posterior"]["mean_m"])
            assert np.allclose(got, want, rtol=1e-9, atol=0), (key, got, want)
        windows = ref["windows"]["closed"]
        print(f"  messages {n_raw:,}, windows {windows:,}; posterior equal to the serial replay in every run")
        print(f"  rosbags raw read        {raw_s:8.1f} s   1.00x raw   {n_raw / raw_s / 1e6:5.2f} M msg/s")
        print(f"  serial replay           {serial_s:8.1f} s   {raw_s / serial_s:4.2f}x raw   1.00x serial")
        for key, r in runs.items():
            label = (
                "archive, cached" if key == "cached" else f"archive, {key} worker{'s' if key != 1 else ''}"
            )
            print(
                f"  {label:<22}  {r['seconds']:8.1f} s   {raw_s / r['seconds']:4.2f}x raw   "
                f"{serial_s / r['seconds']:4.2f}x serial   (cluster start {r['cluster_s']:.1f} s, join "
                f"{r['join_s']:.1f} s, peak RSS per worker {', '.join(f'{m:.0f}' for m in r['hwm_mb'])} MB)"
            )
        t1, t2 = runs[1]["run_s"], runs[args.workers]["run_s"]
        print(
            f"  speed-up 1 -> {args.workers} workers (submission to result): {t1 / t2:.2f}, efficiency "
            f"{t1 / t2 / args.workers:.2f} (goal >= 0.8)"
        )
        per_bag = float(np.median(runs[1]["reduce_s"]))
        per_window = runs["cached"]["join_s"] / max(windows, 1)
        msgs_per_bag = n_raw / len(bags)
        print(
            f"  cost: reduce {per_bag:.2f} s per bag ({msgs_per_bag / per_bag / 1e6:.2f} M msg/s a worker), "
            f"join {1e6 * per_window:.0f} us per window"
        )
        bag_days = CASES[name][2]
        bags_per_year = round(365 / bag_days)
        print(f"  plan (from these costs; a year is {bags_per_year} bags of this size, 525,600 windows):")
        print(plan_text(per_bag, per_window, bags_per_year, 525_600))
        out = BENCH_DIR / f"archive-{name}.json"
        out.write_text(
            json.dumps(
                {
                    "raw_s": raw_s,
                    "serial_s": serial_s,
                    "runs": {str(k): {x: v for x, v in r.items() if x != "result"} for k, r in runs.items()},
                    "per_bag_s": per_bag,
                    "per_window_s": per_window,
                    "messages": n_raw,
                    "windows": windows,
                },
                indent=1,
            )
        )


if __name__ == "__main__":
    main()
