"""Bag read speed: our read + vectorized decode against rosbags' raw read and full deserialization.

Writes a monitoring bag of a few hundred thousand messages to a temporary folder (sqlite3 and
MCAP), then times, on the same bag in the same run:

- baseline ``rosbags raw``: iterate ``Reader.messages()`` (bytes only, no decoding);
- ``rosbags deserialize``: the same plus ``typestore.deserialize_cdr`` of every message and
  extraction of stamp and value (what a per-message reader must do);
- ``bagio read_monitoring``: our read into ``MonitoringData``: blobs per topic (one SQL query per
  topic for sqlite3, the chunks' message indexes for MCAP) + vectorized CDR decode.

Prints msg/s and the ratio to the raw-read baseline. Usage::

    .venv/bin/python benchmarks/bag_read.py [--messages N] [--repeat R]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
from _common import best_of, rosbags_raw

from bridge_shadow.bagio import get_typestore, read_monitoring, write_monitoring
from bridge_shadow.series import MonitoringData


def make_data(n_messages: int, seed: int = 0) -> MonitoringData:
    """Two 100 Hz force channels and a 1 Hz temperature, about ``n_messages`` in total."""
    n = int(n_messages / (2 + 0.01))
    rng = np.random.default_rng(seed)
    stamp = 1_646_667_315_601_000_000 + np.arange(n, dtype=np.int64) * 10_000_000
    force = np.column_stack([rng.normal(2.6e5, 20, n), rng.normal(2.2e5, 20, n)])
    return MonitoringData.from_arrays(stamp, force, stamp[::100], rng.normal(5, 3, len(stamp[::100])))


def rosbags_deserialize(path: Path) -> int:
    from rosbags.rosbag2 import Reader

    ts = get_typestore()
    deserialize = ts.deserialize_cdr
    out: dict[str, list[tuple[int, float]]] = {}
    with Reader(path) as reader:
        for conn, _t, raw in reader.messages():
            msg = deserialize(raw, conn.msgtype)
            stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
            value = msg.wrench.force.z if conn.msgtype.endswith("WrenchStamped") else msg.temperature
            out.setdefault(conn.topic, []).append((stamp, value))
    return sum(len(v) for v in out.values())


def main() -> None:
    """Run the benchmark and print a table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--messages", type=int, default=300_000)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    data = make_data(args.messages)
    with tempfile.TemporaryDirectory(prefix="bag_read_") as tmp:
        for storage in ("sqlite3", "mcap"):
            path = Path(tmp) / storage
            t_write, _ = best_of(1, lambda p=path, s=storage: write_monitoring(p, data, s))
            n = data.n_messages
            t_raw, n_raw = best_of(args.repeat, lambda p=path: rosbags_raw(p))
            t_des, n_des = best_of(min(2, args.repeat), lambda p=path: rosbags_deserialize(p))
            t_our, got = best_of(args.repeat, lambda p=path: read_monitoring(p))
            assert n_raw == n_des == got.n_messages == n
            print(f"{storage}: {n} messages (write_monitoring {n / t_write:,.0f} msg/s)")
            for name, t in (
                ("rosbags raw read", t_raw),
                ("rosbags deserialize_cdr", t_des),
                ("bagio read_monitoring", t_our),
            ):
                print(f"  {name:26s} {n / t:12,.0f} msg/s   x{t_raw / t:6.2f} of raw read")
            print(f"  read_monitoring / deserialize_cdr speed-up: x{t_des / t_our:.1f}")


if __name__ == "__main__":
    main()
