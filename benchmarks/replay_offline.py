"""Offline replay speed and memory: ``bridge-shadow replay BAG`` against rosbags' raw read of the same bag.

Bags come from ``bridge-shadow synth`` (the truth twin, sqlite3 by default) into
``/tmp/bridge_shadow_bench/`` and are reused by later runs. Cases (days of data, so the 60 s
windows show their cost): forces at 1 Hz over 3 and 30 days, 10 Hz over 3 days, 100 Hz over 6 h
(4.3 M messages).
``--cases 1hz-365d`` replays a year of 1 Hz forces (63 M messages, a 7.5 GB bag; synth writes it
segment by segment in bounded memory).

For each bag, in one run:

- ``rosbags raw read``: iterate ``Reader.messages()`` (bytes only) in this process: the baseline;
- ``replay end to end``: the CLI ``bridge-shadow replay BAG --json`` in a fresh interpreter; its
  wall time from spawn to exit (interpreter start-up included), its JSON ``messages_per_s`` (from
  the command's start) and ``pipeline_messages_per_s`` (the shadow alone), and its peak RSS
  (``VmHWM`` of the child's own image, read at its exit);
- ``read + decode``: the streamed reader alone in this process (``MonitoringStream`` cut into
  feed chunks), so that read, decode and shadow add up.

Goal: end to end >= 0.5x the raw read at 1 Hz and at 100 Hz, and peak RSS flat in the bag's
length. ``--in-memory`` also runs the former path (``read_monitoring`` + ``Shadow.run``) in a
subprocess for its peak RSS. Usage::

    .venv/bin/python benchmarks/replay_offline.py [--cases 1hz-3d,1hz-30d,10hz-3d,100hz-6h]
        [--storage sqlite3|mcap] [--repeat R] [--in-memory]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _common import best_of, rosbags_raw

BENCH_DIR = Path("/tmp/bridge_shadow_bench")
#: name -> (days, force rate Hz)
CASES: dict[str, tuple[float, float]] = {
    "1hz-3d": (3.0, 1.0),
    "1hz-30d": (30.0, 1.0),
    "10hz-3d": (3.0, 10.0),
    "100hz-6h": (0.25, 100.0),
    "1hz-365d": (365.0, 1.0),  # not in the default run: a 7.5 GB bag and about 10 minutes
}
DEFAULT_CASES = "1hz-3d,1hz-30d,10hz-3d,100hz-6h"
BIN = Path(sys.executable).parent / "bridge-shadow"


def make_bag(name: str, storage: str) -> Path:
    """Write (or reuse) the synth bag of a case (synth streams long records segment by segment)."""
    days, rate = CASES[name]
    path = BENCH_DIR / f"{name}-{storage}"
    if not (path / "metadata.yaml").is_file():
        BENCH_DIR.mkdir(parents=True, exist_ok=True)
        cmd = [str(BIN), "synth", "--out", str(path), "--days", str(days), "--rate", str(rate), "--seed", "7"]
        subprocess.run([*cmd, "--storage", storage, "--overwrite"], check=True, stdout=subprocess.DEVNULL)
    return path


#: Run as ``python -c HWM_WRAP code args...``: the code runs as ``__main__`` and, at exit, the peak
#: RSS of this process image (``VmHWM``) goes to stderr. ``ru_maxrss`` of a child would not do: it
#: keeps the high-water mark of the forked copy of this (parent) process from before ``exec``.
HWM_WRAP = """
import atexit, sys
def _hwm():
    with open("/proc/self/status") as f:
        kb = [line.split()[1] for line in f if line.startswith("VmHWM:")][0]
    sys.stderr.write(f"\\nVmHWM_KB {kb}\\n")
atexit.register(_hwm)
code, sys.argv = sys.argv[1], sys.argv[2:]
exec(compile(code, "<benchmark child>", "exec"), {"__name__": "__main__"})
"""
CLI = "import sys\nfrom bridge_shadow.cli import main\nsys.exit(main())\n"


def run_child(code: str, args: list[str]) -> tuple[float, int, str]:
    """Run ``code`` with ``args`` in a fresh interpreter; return (wall s, peak RSS MB, stdout)."""
    with tempfile.TemporaryFile("w+") as err:
        t0 = time.perf_counter()
        proc = subprocess.run(
            [sys.executable, "-c", HWM_WRAP, code, *args], stdout=subprocess.PIPE, stderr=err, text=True
        )
        wall = time.perf_counter() - t0
        err.seek(0)
        text = err.read()
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(args)} failed ({proc.returncode}): {text.strip()[-500:]}")
    hwm = [line.split()[1] for line in text.splitlines() if line.startswith("VmHWM_KB ")]
    return wall, int(hwm[-1]) // 1024, proc.stdout


def read_only(path: Path) -> tuple[int, str]:
    """Stream the bag's input topics into feed chunks without the shadow; return (messages, backend)."""
    from bridge_shadow.bagio.stream import MonitoringStream
    from bridge_shadow.replay import arrival_chunks

    with MonitoringStream(path) as stream:
        n = sum(c.messages for c in arrival_chunks(stream))
        return n, stream.backend


IN_MEMORY = """
import sys
from bridge_shadow.bagio import read_monitoring
from bridge_shadow.estimate import Shadow, load_config
from bridge_shadow.model.surrogate_file import load_surrogate
res = Shadow(load_config(None), load_surrogate(None)).run(read_monitoring(sys.argv[1]))
print(res.windows)
"""


def main() -> None:
    """Run the cases and print one table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", default=DEFAULT_CASES, help=f"comma-separated, of {', '.join(CASES)}")
    parser.add_argument("--storage", choices=("sqlite3", "mcap"), default="sqlite3")
    parser.add_argument("--repeat", type=int, default=2, help="raw-read repetitions (best of)")
    parser.add_argument("--in-memory", action="store_true", help="also the former whole-bag path (RSS)")
    args = parser.parse_args()
    rows = []
    for name in args.cases.split(","):
        path = make_bag(name.strip(), args.storage)
        t_raw, n = best_of(args.repeat, lambda p=path: rosbags_raw(p))
        t_read, (n_read, backend) = best_of(args.repeat, lambda p=path: read_only(p))
        wall, rss, out = run_child(CLI, ["bridge-shadow", "replay", str(path), "--json"])
        js = json.loads(out)
        assert js["messages"]["total"] == n == n_read
        row = {
            "case": name,
            "messages": n,
            "windows": js["windows"]["closed"],
            "raw": n / t_raw,
            "read": n / t_read,
            "e2e_wall": n / wall,
            "e2e_json": js["messages_per_s"],
            "pipeline": js["pipeline_messages_per_s"],
            "shadow_ms_per_window": 1e3 * js["pipeline_seconds"] / max(js["windows"]["closed"], 1),
            "shadow_share": js["pipeline_seconds"] / wall,
            "read_share": t_read / wall,
            "rss_mb": rss,
            "backend": backend,
        }
        if args.in_memory:
            _, row["rss_in_memory_mb"], _ = run_child(IN_MEMORY, ["in-memory", str(path)])
        rows.append(row)
        print(json.dumps(row), file=sys.stderr)
    print(
        f"storage {args.storage}; rates in msg/s, x = ratio to rosbags' raw read of the same bag in this run"
    )
    cols = (
        f"{'case':9s} {'msgs':>8s} {'windows':>7s} {'raw read':>9s} {'read+decode':>16s} "
        f"{'end to end':>16s} {'json e2e':>9s} {'pipeline':>16s} {'shadow ms/win':>13s} "
        f"{'shadow %':>8s} {'RSS MB':>7s}"
    )
    print(cols)
    for r in rows:
        raw = r["raw"]
        line = (
            f"{r['case']:9s} {r['messages']:8d} {r['windows']:7d} {raw:9,.0f} "
            f"{r['read']:10,.0f} x{r['read'] / raw:4.2f} {r['e2e_wall']:10,.0f} x{r['e2e_wall'] / raw:4.2f} "
            f"{r['e2e_json']:9,.0f} {r['pipeline']:10,.0f} x{r['pipeline'] / raw:4.1f} "
            f"{r['shadow_ms_per_window']:13.3f} {100 * r['shadow_share']:8.0f} {r['rss_mb']:7d}"
        )
        if "rss_in_memory_mb" in r:
            line += f"  (whole-bag path: {r['rss_in_memory_mb']} MB)"
        print(line)


if __name__ == "__main__":
    main()
