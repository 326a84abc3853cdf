"""Live latency: force message -> posterior, through bridge_shadow_node over loopback DDS.

The player publishes at 1 kHz per force channel (and temperature at 100 Hz) in real time, with
0.1 s windows so that a posterior leaves every 100 ms. The latency of window k is the time from
publishing the frc_02 message whose stamp is the window's end (the message that closes it: the
temperature and frc_01 messages of that stamp go out just before) to the arrival of window k's
posterior mean at the player. Both clocks are the player's. The warm-up windows (held, then
released together) are left out. Baseline in the same run: a bare EventsExecutor node that publishes
each frc_02 message straight back (``bridge_shadow.ros.bare --echo``): the same closing messages,
publish -> echo arrival, i.e. the transport round trip the node cannot beat.

``--parts`` also times the node's window-closing drains by part (``_node_parts``: the drain, its
decode-and-ingest, its start to the window's first posterior message) through DDS, against the same
node code fed the same messages in one process (its subscription callbacks called directly, no
DDS), once as fast as it goes (the warm baseline: one window's close after the other) and once
paced at the stream's 1 kHz in wall-clock time (each tick sleeps until its time, as the player's
do; no DDS, no player). The first ratio is what the node's setting does to the same work; the
paced run says how much of it is the pace alone (the close running once a window, 0.1 s apart,
instead of back to back).

Run: ``.venv/bin/python benchmarks/live_latency.py [SECONDS] [--parts]`` (default 20 s).
"""

from __future__ import annotations

import argparse
import json
import os
import struct
import tempfile
import time
from pathlib import Path

import numpy as np
from geometry_msgs.msg import WrenchStamped

from bridge_shadow.bagio import encode_stamped_floats
from bridge_shadow.contract import MEAN_TOPIC
from bridge_shadow.ros.bare import ECHO_TOPIC
from bridge_shadow.ros.launcher import NodeProcess, wait_until
from bridge_shadow.ros.live_replay import Player
from bridge_shadow.ros.netenv import confine_to_loopback

W_NS = 100_000_000  # window 0.1 s
TICK_NS = 1_000_000  # 1 kHz
T0_NS = 1_647_212_400 * 1_000_000_000
WARMUP = 5
PARAMS = [
    "window_s:=0.1",
    "window_min_samples:=10",
    "topic_timeout_s:=0.05",
    f"warmup_windows:={WARMUP}",
    # seconds of data are one short record, which the traffic screen would hold to its end: the
    # latency measured here is the per-window path, so the screen is off
    "traffic_hold_s:=0.0",
]


def stream(n_ticks: int, seed: int, tick_ns: int = TICK_NS) -> tuple[np.ndarray, ...]:
    """Return ``n_ticks + 1`` ticks: stamps (ns), the two force channels (N, 60 N noise), the air (C)."""
    stamps = T0_NS + np.arange(n_ticks + 1, dtype=np.int64) * tick_ns
    rng = np.random.default_rng(seed)
    f1 = 2.60e5 + 60.0 * rng.standard_normal(n_ticks + 1)
    f2 = 2.21e5 + 60.0 * rng.standard_normal(n_ticks + 1)
    return stamps, f1, f2, 8.0 + 0.5 * np.sin(np.arange(n_ticks + 1) / 3000.0)


def messages(n_ticks: int, seed: int, tick_ns: int = TICK_NS) -> tuple[list[bytes], list[bytes], list[bytes]]:
    """Return ``stream`` serialized: frc_01, frc_02 (``WrenchStamped``), the air (``Temperature``)."""
    stamps, f1, f2, temp = stream(n_ticks, seed, tick_ns)
    out = []
    for force, frame in ((f1, "frc_01"), (f2, "frc_02")):
        values = np.zeros((n_ticks + 1, 6))
        values[:, 2] = force
        out.append(encode_stamped_floats(stamps, frame, values))
    out.append(
        encode_stamped_floats(stamps, "air_temperature", np.column_stack([temp, np.zeros(n_ticks + 1)]))
    )
    return out[0], out[1], out[2]


def run(
    module: str, args: list[str], seconds: float, echo: bool, env: dict[str, str] | None = None
) -> np.ndarray:
    """Play ``seconds`` at 1 kHz to one receiver; return the latency (ms) of each window after warm-up."""
    n = int(seconds * 1e9 / TICK_NS)
    f1, f2, temps = messages(n, seed=1)
    forces = [f1, f2]
    closing: dict[int, int] = {}  # window index -> time.time_ns() when its closing message left
    extra = {ECHO_TOPIC: WrenchStamped} if echo else None
    with (
        Player(record_diagnostics=False, extra=extra) as player,
        NodeProcess(args, module=module, env=env) as node,
    ):
        player.wait_for_node(node, 30.0, outputs=not echo)
        pub_f1, pub_f2, pub_t = (p.publish for p in player.publishers)
        t_start = time.perf_counter()
        for j in range(n + 1):
            lag = t_start + j * 1e-3 - time.perf_counter()
            if lag > 0:
                time.sleep(lag)
            if j % 10 == 0:
                pub_t(temps[j])
            pub_f1(forces[0][j])
            pub_f2(forces[1][j])
            if j % 100 == 0 and j > 0:
                closing[j // 100 - 1] = time.time_ns()
        behind_ms = 1e3 * (time.perf_counter() - t_start - n * 1e-3)
        n_windows = len(closing)
        if echo:
            wait_until(lambda: player.received(ECHO_TOPIC) >= n + 1, 30.0, "every echo", node.check_alive)
            arrivals = {}
            for t, raw in player.records[ECHO_TOPIC]:
                sec, nsec = struct.unpack_from("<iI", raw, 4)
                j = (sec * 1_000_000_000 + nsec - T0_NS) // TICK_NS
                if j % 100 == 0 and j > 0:
                    arrivals[j // 100 - 1] = t
        else:
            wait_until(
                lambda: player.received(MEAN_TOPIC) >= n_windows, 30.0, "the posteriors", node.check_alive
            )
            arrivals = dict(enumerate(t for t, _ in player.records[MEAN_TOPIC]))
    print(f"  {module}: {n_windows} windows, player {behind_ms:.0f} ms behind 1 kHz pacing at the end")
    return np.array([(arrivals[k] - closing[k]) / 1e6 for k in range(2 * WARMUP, n_windows)])


def parts(args: list[str], seconds: float) -> None:
    """Time the closing drains by part through DDS and in one process; print both and their ratio."""
    from _node_parts import PARTS, closing_parts_in_process

    n = int(seconds * 1e9 / TICK_NS)
    here = str(Path(__file__).resolve().parent)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "parts.json"
        env = dict(os.environ, BRIDGE_SHADOW_PARTS_OUT=str(out))
        env["PYTHONPATH"] = os.pathsep.join(x for x in (here, env.get("PYTHONPATH")) if x)
        lat = run("_node_parts", args, seconds, echo=False, env=env)
        dds = np.array(json.loads(out.read_text())["rows"])[2 * WARMUP :]
    streams = messages(n, seed=1)
    local = np.array(closing_parts_in_process(args, streams, 10, 50))[2 * WARMUP :]
    paced = np.array(closing_parts_in_process(args, streams, 10, 50, tick_s=TICK_NS / 1e9))[2 * WARMUP :]
    print(
        f"window-closing drains, ms (latency of the timed run: p50 {np.percentile(lat, 50):.2f}, p99 "
        f"{np.percentile(lat, 99):.2f}):"
    )
    print(
        f"  {'part':18s} {'in-process p50 / p99 (baseline)':>32s} {'in-process paced':>18s} "
        f"{'node via DDS':>16s}  ratio p50 paced, DDS"
    )
    for k, name in enumerate(PARTS):
        a50, a99 = np.percentile(local[:, k], [50, 99])
        c50, c99 = np.percentile(paced[:, k], [50, 99])
        b50, b99 = np.percentile(dds[:, k], [50, 99])
        print(
            f"  {name:18s} {a50:21.3f} / {a99:6.3f}   {c50:7.3f} / {c99:6.3f}  {b50:6.3f} / {b99:6.3f}"
            f"  x{c50 / a50:.2f}, x{b50 / a50:.2f}"
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("seconds", nargs="?", type=float, default=20.0)
    ap.add_argument("--parts", action="store_true", help="also time the node's closing drains by part")
    opts = ap.parse_args()
    confine_to_loopback()
    seconds = opts.seconds
    args = ["--ros-args", *[x for p in PARAMS for x in ("-p", p)]]
    print(f"{seconds:g} s at 1 kHz per force channel (temperature 100 Hz), 0.1 s windows, loopback DDS")
    bare = run("bridge_shadow.ros.bare", ["--echo"], seconds, echo=True)
    node = run("bridge_shadow.ros.main", args, seconds, echo=False)
    b50, b99 = np.percentile(bare, [50, 99])
    n50, n99 = np.percentile(node, [50, 99])
    print(f"bare echo (frc_02 -> echo)       : p50 {b50:6.2f} ms  p99 {b99:6.2f} ms  (baseline)")
    print(
        f"bridge_shadow_node (-> posterior): p50 {n50:6.2f} ms  p99 {n99:6.2f} ms  "
        f"({n50 / b50:.1f}x, {n99 / b99:.1f}x baseline; {len(node)} windows)"
    )
    if opts.parts:
        parts(args, seconds)


if __name__ == "__main__":
    main()
