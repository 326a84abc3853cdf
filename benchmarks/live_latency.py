"""Live latency: force message -> posterior, through bridge_shadow_node over loopback DDS.

The player publishes at 1 kHz per force channel (and temperature at 100 Hz) in real time, with
0.1 s windows so that a posterior leaves every 100 ms. The latency of window k is the time from
publishing the frc_02 message whose stamp is the window's end (the message that closes it: the
temperature and frc_01 messages of that stamp go out just before) to the arrival of window k's
posterior mean at the player. Both clocks are the player's. The warm-up windows (held, then
released together) are left out. Baseline in the same run: a bare EventsExecutor subscriber's
round trip is not measured here; compare with DESIGN 7 (0.3 ms p50, 0.5-1 ms p99 at 1 kHz).

Run: ``.venv/bin/python benchmarks/live_latency.py [SECONDS]`` (default 20).
"""

from __future__ import annotations

import sys
import time

import numpy as np

from bridge_shadow.bagio import encode_stamped_floats
from bridge_shadow.contract import MEAN_TOPIC
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
    f"spline_warmup_windows:={WARMUP}",
    f"noise_warmup_windows:={WARMUP}",
]


def main() -> None:
    confine_to_loopback()
    seconds = float(sys.argv[1]) if len(sys.argv) > 1 else 20.0
    n = int(seconds * 1e9 / TICK_NS)
    stamps = T0_NS + np.arange(n + 1, dtype=np.int64) * TICK_NS
    rng = np.random.default_rng(1)
    forces = []
    for base, frame in ((2.60e5, "frc_01"), (2.21e5, "frc_02")):
        values = np.zeros((n + 1, 6))
        values[:, 2] = base + 60.0 * rng.standard_normal(n + 1)
        forces.append(encode_stamped_floats(stamps, frame, values))
    temp_c = 8.0 + 0.5 * np.sin(np.arange(n + 1) / 3000.0)
    temps = encode_stamped_floats(stamps, "air_temperature", np.column_stack([temp_c, np.zeros(n + 1)]))
    args = ["--ros-args", *[x for p in PARAMS for x in ("-p", p)]]
    closing: dict[int, int] = {}  # window index -> time.time_ns() when its closing message left
    with Player(record_diagnostics=False) as player, NodeProcess(args) as node:
        player.wait_for_node(node, 30.0)
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
        n_windows = len(closing)
        wait_until(lambda: player.received(MEAN_TOPIC) >= n_windows, 30.0, "the posteriors", node.check_alive)
        arrivals = [t for t, _ in player.records[MEAN_TOPIC]]
    lat_ms = np.array([(arrivals[k] - closing[k]) / 1e6 for k in range(2 * WARMUP, n_windows)])
    p50, p99 = np.percentile(lat_ms, [50, 99])
    print(f"{n} ticks at 1 kHz (2 force + 0.1 temperature messages each), {n_windows} windows of 0.1 s")
    print(
        f"force -> posterior latency over {len(lat_ms)} windows: p50 {p50:.2f} ms, p99 {p99:.2f} ms, "
        f"max {lat_ms.max():.2f} ms"
    )
    print(
        f"pacing: the player kept 1 kHz to within {1e3 * (time.perf_counter() - t_start - seconds):.0f} ms "
        "over the run (wall minus nominal)"
    )


if __name__ == "__main__":
    main()
