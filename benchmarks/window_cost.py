"""Per-window cost of the shadow: ``Shadow.run`` on decoded data against rosbags' raw read of the same bag.

For forces at 1 Hz and at 100 Hz (two channels, a 1 Hz air temperature), writes a bag of the same
messages and times in the same run, rounds interleaved, best of ``--repeat``:

- baseline ``rosbags raw read``: iterate ``Reader.messages()`` of the bag (bytes only);
- ``Shadow.run``: gate, 60 s windows, event detector, joint compensation with its scheduled refits,
  noise model and the settlement posterior, on the decoded arrays (what replay adds to reading).

Prints microseconds of shadow work per 60 s window and per message, and the ratio of the shadow's
time to the raw read's: the streaming replay reaches 0.5x the raw read end to end only if the
shadow (plus decoding) costs less than the raw read itself. At 1 Hz a window is 122 messages, so
the per-window work dominates; at 100 Hz (12 061 messages a window) the per-message work does.
Usage::

    .venv/bin/python benchmarks/window_cost.py [--days D] [--repeat R]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
from _common import rosbags_raw

from bridge_shadow.bagio import write_monitoring
from bridge_shadow.estimate import Shadow, ShadowConfig
from bridge_shadow.model.surrogate_file import load_surrogate
from bridge_shadow.series import MonitoringData

T0 = 1_646_667_300 * 10**9


def make_data(hours: float, force_hz: float, seed: int = 0) -> MonitoringData:
    """Make forces at ``force_hz`` following a daily temperature swing, AR(1) noise, one 1 mm step."""
    rng = np.random.default_rng(seed)
    n = int(hours * 3600 * force_hz)
    dt = round(1e9 / force_hz)
    stamp = T0 + np.arange(n, dtype=np.int64) * dt
    t_stamp = T0 + np.arange(int(hours * 3600), dtype=np.int64) * 10**9
    temp = 8.0 + 6.0 * np.sin(2 * np.pi * (t_stamp - T0) / 86400e9) + rng.normal(0, 0.05, len(t_stamp))
    t_at = np.interp((stamp - T0).astype(float), (t_stamp - T0).astype(float), temp)
    sur = load_surrogate()
    x = np.where((np.arange(n) > n // 2)[:, None], [-1e-3, -1e-3], [0.0, 0.0])
    e = rng.normal(0, 60, (n, 2))
    phi = 0.999 if force_hz > 10 else 0.9
    noise = np.zeros_like(e)
    noise[0] = e[0]
    for i in range(1, n):  # AR(1) per sample
        noise[i] = phi * noise[i - 1] + np.sqrt(1 - phi**2) * e[i]
    force = x @ sur.A.T + sur.u0 + np.c_[300 * (t_at - 8), 80 * (t_at - 8)] + noise
    return MonitoringData.from_arrays(stamp, force, t_stamp, temp)


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--days", type=float, default=2.0, help="record length at 1 Hz (100 Hz: 1/24 of it)")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    sur = load_surrogate()
    cases = [("1 Hz", 1.0, 24.0 * args.days), ("100 Hz", 100.0, args.days)]
    print(
        f"{'forces':>7} {'windows':>8} {'messages':>10} {'raw read':>12} {'Shadow.run':>12} "
        f"{'us/window':>10} {'us/msg':>8} {'shadow/raw':>11} {'events':>7}"
    )
    with tempfile.TemporaryDirectory() as tmp:
        for label, hz, hours in cases:
            data = make_data(hours, hz)
            bag = Path(tmp) / label.replace(" ", "")
            write_monitoring(bag, data)
            n_msg = sum(len(f) for f in data.forces.values()) + len(data.temperature)
            raw, run = [], []
            result = None
            for _ in range(args.repeat):  # interleaved rounds: the same load on both
                t0 = time.perf_counter()
                assert rosbags_raw(bag) == n_msg
                raw.append(time.perf_counter() - t0)
                t0 = time.perf_counter()
                result = Shadow(ShadowConfig(), sur).run(data)
                run.append(time.perf_counter() - t0)
            t_raw, t_run = min(raw), min(run)
            print(
                f"{label:>7} {result.windows:8d} {n_msg:10d} {n_msg / t_raw:10.0f}/s {n_msg / t_run:10.0f}/s "
                f"{1e6 * t_run / result.windows:10.1f} {1e6 * t_run / n_msg:8.2f} {t_run / t_raw:11.3f} "
                f"{len(result.events):7d}"
            )


if __name__ == "__main__":
    main()
