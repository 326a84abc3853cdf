"""A live window's ingest and close: the short paths against the general ones, in one process.

The stream of ``live_latency.py`` (two force channels at 1 kHz, the air at 100 Hz, 0.1 s windows)
is fed to two shadows window by window, alternately (which goes first alternates too), as a node
feeds them: the air, then each force channel, then ``poll``; the refit a window schedules runs
after, outside the timing (the node publishes first). One shadow takes the short paths of a live
window (``TopicGate._regular`` for a batch of regular messages, ``WindowBuffer._one_window`` for
samples that all fall in one window, the temperature matched once where both load cells are
stamped alike, the curve and its variance for both channels at once where every window has a
temperature, the B-spline basis on plain floats at a few points, the clear sky from blocks of
windows computed ahead, ``SunCovariate.values`` with ``window_ns``, the basis, the curve and its
variance of one window in floats: ``Compensation.basis_one``, ``curve_one``, the sun covariate's
``SunCovariate.value_one``; a regular gate batch in floats, ``TopicGate._regular_few``, taken whole
by ``Shadow._gate``; the temperature match between two readings, ``WindowBuffer._match_one``); the
other, the baseline, goes the general way (those disabled). Both must give the same window
outputs (checked every window). Printed: each one's p50 / p99 per window and the ratio, paired
window by window, so that the machine's speed, which drifts within minutes, cancels.

Run: ``.venv/bin/python benchmarks/live_window_paths.py [SECONDS]`` (default 60 s of stream).
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import numpy as np
from live_latency import TICK_NS, stream

from bridge_shadow.estimate import Shadow
from bridge_shadow.estimate.compensation import spline
from bridge_shadow.estimate.parameters.config import load_config
from bridge_shadow.model.surrogate_file import load_surrogate

FEW = spline._SCALAR_PATH_MAX


def feed(
    shadow: Shadow, data: tuple[np.ndarray, ...], a: int, b: int, general: bool
) -> tuple[float, list[Any]]:
    """Feed ticks ``a:b`` and poll; return the seconds it took and the outputs."""
    stamps, f1, f2, air = data
    spline._SCALAR_PATH_MAX = 0 if general else FEW
    ticks = np.arange(a, b)
    t_air = ticks[ticks % 10 == 0]
    t0 = time.perf_counter()
    shadow.ingest_temperature(stamps[t_air], air[t_air], "air_temperature")
    shadow.ingest_forces(0, stamps[a:b], f1[a:b], "frc_01")
    shadow.ingest_forces(1, stamps[a:b], f2[a:b], "frc_02")
    out = shadow.poll()
    dt = time.perf_counter() - t0
    shadow.settle()
    spline._SCALAR_PATH_MAX = FEW
    return dt, out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("seconds", nargs="?", type=float, default=60.0)
    seconds = ap.parse_args().seconds
    cfg = load_config().replace(
        window_s=0.1, window_min_samples=10, topic_timeout_s=0.05, warmup_windows=5, traffic_hold_s=0.0
    )
    surrogate = load_surrogate()
    short, general = Shadow(cfg, surrogate), Shadow(cfg, surrogate)
    for gate in general.gates:
        gate._regular = lambda *args: False  # type: ignore[method-assign]
    general.buffer._one_window = lambda taken: None  # type: ignore[method-assign]
    if general.sun is not None:  # the clear sky of each call's windows at once, not from blocks
        sun_values = general.sun.values
        general.sun.values = lambda t, temp, window_ns=None: sun_values(t, temp)  # type: ignore[method-assign]
        general.sun.value_one = lambda t, temp, window_ns: tuple(  # type: ignore[method-assign]
            float(x[0]) for x in sun_values(np.array([t]), np.array([temp]))
        )
    comp = general.compensation
    comp._curve_rows_known = comp._curve_rows_by_channel  # type: ignore[method-assign]
    comp._curve_variance_known = comp._curve_variance_by_channel  # type: ignore[method-assign]
    comp.curve_one = lambda *args: None  # type: ignore[method-assign]
    rows = comp.basis_rows  # one window's basis through the rows (the lists it returns: two calls more)
    comp.basis_one = lambda temp, sun=0.0: tuple(  # type: ignore[method-assign]
        x[0].tolist() for x in rows(np.array([temp]), np.array([sun]))
    )
    data = stream(int(seconds * 1e9 / TICK_NS), seed=1)
    per_window = int(cfg.window_s * 1e9) // TICK_NS
    times: dict[bool, list[float]] = {False: [], True: []}
    for w in range(len(data[0]) // per_window):
        a, b = w * per_window + (w > 0), (w + 1) * per_window + 1  # up to and with the closing tick
        outs = {}
        for is_general in (w % 2 == 0, w % 2 == 1):
            dt, outs[is_general] = feed(general if is_general else short, data, a, b, is_general)
            times[is_general].append(dt)
        same = len(outs[True]) == len(outs[False]) and all(
            np.allclose(x.mean_m, y.mean_m, rtol=1e-12, atol=0.0)
            for x, y in zip(outs[True], outs[False], strict=True)
        )
        if not same:
            raise SystemExit(f"window {w}: the two paths disagree")
    skip = 2 * cfg.warmup_windows
    t_short, t_general = (np.array(times[g][skip:]) * 1e3 for g in (False, True))
    print(
        f"{seconds:g} s of the live_latency stream, {len(t_short)} windows of 0.1 s; ingest + poll a window:"
    )
    for label, t in (("general paths (baseline)", t_general), ("short paths", t_short)):
        print(f"  {label:26s} p50 {np.percentile(t, 50):6.3f} ms  p99 {np.percentile(t, 99):6.3f} ms")
    print(f"  ratio, paired by window: median {np.median(t_short / t_general):.2f}")


if __name__ == "__main__":
    main()
