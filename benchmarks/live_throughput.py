"""Live throughput: bridge_shadow_node against bare EventsExecutor subscribers, measured in one run.

Synthetic contract messages (forces at 100 Hz on both channels by default, the low end of the rates
the shadow is built for; air temperature at 1 Hz; 60 s windows) are played over loopback DDS by the
same ``Player`` to three receivers, each in its own process: a bare subscriber taking raw CDR bytes,
a bare subscriber taking typed messages (what a plain rclpy node does), and the node (raw CDR,
decode, shadow pipeline, outputs). The rate is messages / (first publish -> the receiver has taken
everything and answered flush). The rounds are interleaved and their order rotated, and medians are
compared, because on 2 cores one run varies by about 10 %. Goal: the node >= 0.9x the bare
subscriber and >= 10k msg/s.

Run: ``.venv/bin/python benchmarks/live_throughput.py [N_MESSAGES] [--repeat R] [--force-hz HZ]``
(defaults 200000, 5, 100).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from bridge_shadow.bagio import encode_stamped_floats
from bridge_shadow.ros.launcher import NodeProcess, wait_until
from bridge_shadow.ros.live_replay import MAX_IN_FLIGHT, Player, merge_log_order
from bridge_shadow.ros.netenv import confine_to_loopback

T0_NS = 1_647_212_400 * 1_000_000_000  # 2022-03-13 23:00 UTC


def synthetic(n_total: int, force_hz: float = 10.0, temp_hz: float = 1.0, seed: int = 0):
    """Raw CDR per topic and their log times: forces about 260/221 kN, daily temperature swing."""
    rng = np.random.default_rng(seed)
    n_f = int(n_total * force_hz / (2 * force_hz + temp_hz))
    n_t = n_total - 2 * n_f
    t_f = T0_NS + np.arange(n_f, dtype=np.int64) * round(1e9 / force_hz)
    t_t = T0_NS + np.arange(n_t, dtype=np.int64) * round(1e9 / temp_hz)
    temp = 8.0 + 8.0 * np.sin(2 * np.pi * (t_t - T0_NS) / 86.4e12)
    raws, logs = [], []
    for ch, (base, frame) in enumerate(((2.60e5, "frc_01"), (2.21e5, "frc_02"))):
        values = np.zeros((n_f, 6))
        values[:, 2] = base + 60.0 * rng.standard_normal(n_f) + 300.0 * ch
        raws.append(encode_stamped_floats(t_f, frame, values))
        logs.append(t_f)
    raws.append(encode_stamped_floats(t_t, "air_temperature", np.column_stack([temp, np.zeros(n_t)])))
    logs.append(t_t)
    return raws, logs


def play(module: str, args: list[str], raws, topic, pos, outputs: bool) -> float:
    """Messages per second from first publish to the receiver's flush answer."""
    with Player() as player, NodeProcess(args, module=module) as node:
        player.wait_for_node(node, 30.0, outputs=outputs)
        t0 = time.perf_counter()
        player.publish(topic, pos, raws, in_flight=MAX_IN_FLIGHT, node=node)
        wait_until(lambda: player.taken(node) >= len(topic), 120.0, "all messages", node.check_alive)
        player.flush(node, 60.0)
        seconds = time.perf_counter() - t0
    return len(topic) / seconds


def main() -> None:
    confine_to_loopback()
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("messages", nargs="?", type=int, default=200_000, help="messages per run")
    parser.add_argument(
        "--force-hz", type=float, default=100.0, help="force rate per channel (10 stresses per-window work)"
    )
    parser.add_argument("--repeat", type=int, default=5, help="interleaved rounds (medians are reported)")
    args = parser.parse_args()
    raws, logs = synthetic(args.messages, force_hz=args.force_hz)
    topic, pos, _ = merge_log_order(logs)
    print(
        f"{len(topic)} messages (forces {args.force_hz:g} Hz x 2, temperature 1 Hz), loopback DDS, "
        f"2 processes, {args.repeat} interleaved rounds"
    )
    receivers = {
        "bare subscriber, raw CDR": ("bridge_shadow.ros.bare", [], False),
        "bare subscriber, typed msgs": ("bridge_shadow.ros.bare", ["--typed"], False),
        "bridge_shadow_node": ("bridge_shadow.ros.main", [], True),
    }
    rates: dict[str, list[float]] = {name: [] for name in receivers}
    names = list(receivers)
    for r in range(args.repeat):  # interleaved and rotated: a slow spell or an order effect hits all
        for name in names[r % 3 :] + names[: r % 3]:
            module, extra, outputs = receivers[name]
            rates[name].append(play(module, extra, raws, topic, pos, outputs))
    med = {name: float(np.median(r)) for name, r in rates.items()}
    base, typed = med["bare subscriber, raw CDR"], med["bare subscriber, typed msgs"]
    node = med["bridge_shadow_node"]
    for name, r in rates.items():
        runs = ", ".join(f"{x:.0f}" for x in r)
        print(f"{name:28s}: median {med[name]:8.0f} msg/s  ({med[name] / base:.2f}x raw)  runs: {runs}")
    ratios = np.array(rates["bridge_shadow_node"]) / np.array(rates["bare subscriber, raw CDR"])
    print(
        f"node / bare raw per round: {', '.join(f'{x:.2f}' for x in ratios)}; "
        f"node / typed median {node / typed:.2f}x"
    )
    met = node >= 0.9 * base and node >= 1e4
    print(f"goal >= 0.9x bare (raw CDR) and >= 10k msg/s (medians): {'met' if met else 'NOT met'}")


if __name__ == "__main__":
    main()
