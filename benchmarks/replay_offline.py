"""Offline replay speed and memory: ``bridge-shadow replay`` (direct) against rosbags on one bag.

Writes a monitoring bag (two 100 Hz force channels and a 1 Hz temperature, a few hundred
thousand messages) to a temporary folder, then times on the same bag in the same run:

- baseline ``rosbags raw read``: iterate ``Reader.messages()`` (bytes only);
- ``rosbags deserialize``: the same plus ``deserialize_cdr`` of every message;
- ``replay direct``: ``read_monitoring`` + ``Shadow.run`` (gate, 60 s windows, REML P-spline,
  adaptive noise, Kalman), i.e. what ``bridge-shadow replay BAG`` does without printing;
- ``Shadow.run`` alone on the decoded data.

Prints msg/s and the ratio to the raw read (goal: replay >= 0.5x raw read). Then the memory of a
long replay: a day of 20 Hz forces fed in one-minute chunks (``ingest_*`` + ``poll``, as the
node does), with tracemalloc's current size every 4 hours of data (goal: flat). Usage::

    .venv/bin/python benchmarks/replay_offline.py [--messages N] [--repeat R] [--hours H]
"""

from __future__ import annotations

import argparse
import tempfile
import tracemalloc
from pathlib import Path

import numpy as np
from _common import best_of, rosbags_raw

from bridge_shadow.bagio import get_typestore, read_monitoring, write_monitoring
from bridge_shadow.estimate import Shadow, ShadowConfig
from bridge_shadow.model.surrogate_file import load_surrogate
from bridge_shadow.series import MonitoringData

T0 = 1_646_667_300 * 10**9


def make_data(n_messages: int, seed: int = 0) -> MonitoringData:
    """Two 100 Hz force channels and a 1 Hz temperature with a daily swing, about n_messages."""
    n = int(n_messages / 2.01)
    rng = np.random.default_rng(seed)
    stamp = T0 + np.arange(n, dtype=np.int64) * 10_000_000
    t_stamp = stamp[::100]
    temp = 8.0 + 6.0 * np.sin(2 * np.pi * (t_stamp - T0) / 86400e9) + rng.normal(0, 0.05, len(t_stamp))
    t_at = np.interp(stamp, t_stamp, temp)
    sur = load_surrogate()
    force = sur.reactions(np.array([7e-4, -7e-4])) + np.c_[300 * t_at, 80 * t_at] + rng.normal(0, 60, (n, 2))
    return MonitoringData.from_arrays(stamp, force, t_stamp, temp)


def rosbags_deserialize(path: Path) -> int:
    from rosbags.rosbag2 import Reader

    deserialize = get_typestore().deserialize_cdr
    n = 0
    with Reader(path) as reader:
        for conn, _t, raw in reader.messages():
            deserialize(raw, conn.msgtype)
            n += 1
    return n


def replay(path: Path) -> object:
    return Shadow(ShadowConfig(), load_surrogate()).run(read_monitoring(path))


def memory_profile(hours: float, rate: int = 20) -> list[tuple[float, float]]:
    """Feed ``hours`` of data minute by minute; tracemalloc current MB every 4 h of data."""
    rng = np.random.default_rng(1)
    sur = load_surrogate()
    # the kept-window log for refiltering is the only thing that grows; it is capped at
    # noise_refilter_max_windows (default 20000, about 14 days); 480 here shows the plateau
    shadow = Shadow(ShadowConfig(noise_refilter_max_windows=480), sur)
    base = sur.reactions(np.zeros(2))
    marks: list[tuple[float, float]] = []
    tracemalloc.start()
    for minute in range(int(hours * 60)):
        s0 = T0 + minute * 60 * 10**9
        stamps = s0 + np.arange(60 * rate, dtype=np.int64) * (10**9 // rate)
        temp = 8.0 + 6.0 * np.sin(2 * np.pi * minute / 1440.0)
        for c in range(2):
            shadow.ingest_forces(
                c, stamps, base[c] + 300 * temp + rng.normal(0, 60, len(stamps)), f"frc_0{c + 1}"
            )
        shadow.ingest_temperature(
            s0 + np.arange(60, dtype=np.int64) * 10**9, np.full(60, temp), "air_temperature"
        )
        shadow.poll()
        if minute % 240 == 239:
            marks.append(((minute + 1) / 60, tracemalloc.get_traced_memory()[0] / 1e6))
    tracemalloc.stop()
    return marks


def main() -> None:
    """Run the benchmark and print the tables."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--messages", type=int, default=400_000)
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--hours", type=float, default=24.0)
    args = parser.parse_args()
    data = make_data(args.messages)
    n = data.n_messages
    with tempfile.TemporaryDirectory(prefix="replay_offline_") as tmp:
        for storage in ("sqlite3", "mcap"):
            path = Path(tmp) / storage
            write_monitoring(path, data, storage)
            t_raw, n_raw = best_of(args.repeat, lambda p=path: rosbags_raw(p))
            t_des, n_des = best_of(1, lambda p=path: rosbags_deserialize(p))
            t_rep, res = best_of(args.repeat, lambda p=path: replay(p))
            t_run, _ = best_of(args.repeat, lambda: Shadow(ShadowConfig(), load_surrogate()).run(data))
            assert n_raw == n_des == n == res.messages
            print(f"{storage}: {n} messages, {res.windows} windows of 60 s")
            for name, t in (
                ("rosbags raw read", t_raw),
                ("rosbags deserialize_cdr", t_des),
                ("replay direct (read+shadow)", t_rep),
                ("Shadow.run on decoded data", t_run),
            ):
                print(f"  {name:28s} {n / t:12,.0f} msg/s   x{t_raw / t:6.2f} of raw read")
    print(
        f"memory over a long replay ({args.hours:g} h of 2 x 20 Hz forces, 1-minute chunks, "
        "refilter log capped at 480 windows):"
    )
    for hour, mb in memory_profile(args.hours):
        print(f"  after {hour:5.1f} h of data: {mb:7.2f} MB traced")


if __name__ == "__main__":
    main()
