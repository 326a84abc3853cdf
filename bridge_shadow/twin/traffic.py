"""Test-car crossings: Poisson arrivals in the daytime window, moving over the two-span influence line.

The ``traffic`` effect's magnitude is the car's weight ``W`` (N). A car drives over the 2 x 15 m
bridge at constant speed in about ``traffic_duration_s``; its weight splits between the girders by
its lane position (south share ``0.5 +- traffic_lateral_sd``), and each girder passes it to its
central bearing by the influence line of a continuous two-span beam. The peak is ``W / 2`` per
bearing, about 12.5 kN for the realistic 25 kN car (DESIGN 3: up to about +12 kN).
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass

import numpy as np

from bridge_shadow.twin.config import LOCAL_TZ, TwinConfig
from bridge_shadow.twin.response import two_span_mid_influence

__all__ = ["MIN_HEADWAY_S", "Crossings", "draw_crossings", "traffic_reactions"]

NS = 1_000_000_000
#: Shortest time between the starts of two crossings of the one test car, s.
MIN_HEADWAY_S = 60.0


@dataclass
class Crossings:
    """Drawn crossings.

    Attributes:
        start_ns: (k,) int64, time the car enters the bridge (UTC ns).
        duration_s: (k,) time on the bridge, s.
        south_share: (k,) share of the weight carried by the south girder.

    """

    start_ns: np.ndarray
    duration_s: np.ndarray
    south_share: np.ndarray

    def __len__(self) -> int:
        return len(self.start_ns)


def _local_ns(day: dt.date, hours: float) -> int:
    midnight = dt.datetime(day.year, day.month, day.day, tzinfo=LOCAL_TZ)
    return round((midnight.timestamp() + hours * 3600.0) * NS)


def draw_crossings(rng: np.random.Generator, t0_ns: int, t1_ns: int, config: TwinConfig) -> Crossings:
    """Crossings of one test car in the local daytime window of each day in the span.

    Arrivals are a Poisson stream of ``traffic_per_hour`` thinned to one car: each crossing starts
    at least ``MIN_HEADWAY_S`` after the previous one (the car must clear the bridge and turn), the
    rest of the headway is exponential, so the mean rate stays ``traffic_per_hour``.
    """
    first = dt.datetime.fromtimestamp(t0_ns / NS, LOCAL_TZ).date()
    last = dt.datetime.fromtimestamp(t1_ns / NS, LOCAL_TZ).date()
    hours = config.traffic_end_h - config.traffic_start_h
    mean_s = 3600.0 / config.traffic_per_hour
    extra_mean_s = max(mean_s - MIN_HEADWAY_S, 1.0)
    n_max = int(3 * hours * config.traffic_per_hour + 20)
    starts = []
    day = first
    while day <= last:
        a = _local_ns(day, config.traffic_start_h)
        headway = MIN_HEADWAY_S + rng.exponential(extra_mean_s, n_max)
        offset_s = np.cumsum(headway) - MIN_HEADWAY_S * rng.random()
        offset_s = offset_s[offset_s < hours * 3600.0]
        starts.append(a + (offset_s * NS).astype(np.int64))
        day += dt.timedelta(days=1)
    start = np.concatenate(starts) if starts else np.zeros(0, np.int64)
    start = start[(start >= t0_ns) & (start <= t1_ns)]
    k = len(start)
    duration = config.traffic_duration_s * (1.0 + 0.2 * (2.0 * rng.random(k) - 1.0))
    share = np.clip(0.5 + config.traffic_lateral_sd * rng.standard_normal(k), 0.0, 1.0)
    return Crossings(start.astype(np.int64), duration, share)


def traffic_reactions(t_ns: np.ndarray, crossings: Crossings, weight_n: float, span_m: float) -> np.ndarray:
    """Central reactions (n, 2) in N [south, north] at the stamps from cars of weight ``weight_n``."""
    t = np.asarray(t_ns, np.int64)
    out = np.zeros((len(t), 2))
    if not len(crossings) or weight_n == 0.0:
        return out
    end = crossings.start_ns + (crossings.duration_s * NS).astype(np.int64)
    lo = np.searchsorted(t, crossings.start_ns, side="left")
    hi = np.searchsorted(t, end, side="right")
    counts = hi - lo
    event = np.repeat(np.arange(len(crossings)), counts)
    idx = np.repeat(lo, counts) + (np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts))
    frac = (t[idx] - crossings.start_ns[event]) / (crossings.duration_s[event] * NS)
    load = weight_n * two_span_mid_influence(frac * 2.0 * span_m, span_m)
    share = crossings.south_share[event]
    np.add.at(out, (idx, 0), load * share)
    np.add.at(out, (idx, 1), load * (1.0 - share))
    return out
