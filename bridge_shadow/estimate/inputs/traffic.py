"""The traffic screen of a short record: cut the excursions of a vehicle that come back.

On a load-test day every record holds car-free minutes at its start and end and a test car
parked for minutes in between (+3 to +11 kN per bearing on the 2022-04-11 records). Taken as
data, those plateaus are read as strongly correlated noise (an AR(1) of phi ~0.99), the
provisional segment after a gap gets an sd of ~3.5 mm instead of ~0.24 mm, and a real
settlement stays an unconfirmed change (issue 19). The window buffer therefore holds a record
until it ends (a silence of ``gap_s`` in both force channels, or the end of the data) and, when
it is at most ``traffic_hold_s`` long, screens it here before its windows close:

1. 1 s bins from the record's first stamp, the mean force of each channel per bin; the bins
   holding both channels carry the sum (a record sampled every few seconds leaves the rest empty);
2. the calibration's car rule (``bridge_shadow.traffic.flag_car``) on that sum, its first
   baseline from the lowest fifth of each half of the record (a drift of ~1 kN through a record
   must not put the whole start at one end);
3. a flagged run is *traffic* when it lies above the baseline (a vehicle only adds load) and
   comes back inside the record: it touches neither the first nor the last bin with data. A run
   that does not come back is a change of state and stays data; so does one below the baseline.

The samples of the traffic bins are cut; the windows are built from the rest (a window left
with fewer than ``window_min_samples`` is rejected as ``traffic``). A record longer than the hold
limit is released unscreened (continuous monitoring: the detector's transients handle it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bridge_shadow.traffic import flag_car, runs

__all__ = ["BIN_NS", "TrafficCut", "screen_record"]

#: Bin width of the screen, ns: the calibration's 1 s bins (a car crossing takes seconds).
BIN_NS = 1_000_000_000


@dataclass(frozen=True)
class TrafficCut:
    """What the screen cut from one record.

    Attributes:
        keep: per channel, (n_c,) bool over the record's samples (True: kept).
        intervals_ns: ``(start, end)`` stamps (UTC ns) of the cut stretches.

    """

    keep: list[np.ndarray]
    intervals_ns: list[tuple[int, int]]


def screen_record(
    stamps: list[np.ndarray],
    values: list[np.ndarray],
    threshold_n: float,
    margin_s: float,
) -> TrafficCut:
    """Screen the samples of one record (per channel, sorted stamps in ns and forces in N)."""
    firsts = [int(s[0]) for s in stamps if len(s)]
    if not firsts or any(not len(s) for s in stamps):
        return TrafficCut([np.ones(len(s), bool) for s in stamps], [])
    t0 = min(firsts)
    n = (max(int(s[-1]) for s in stamps) - t0) // BIN_NS + 1
    idx = [(s - t0) // BIN_NS for s in stamps]
    mean = np.zeros(n)
    for i, v in zip(idx, values, strict=True):
        count = np.bincount(i, minlength=n)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean += np.where(count > 0, np.bincount(i, weights=v, minlength=n) / count, np.nan)
    t_s = np.arange(n) + 0.5
    flags = flag_car(t_s, mean, threshold_n, round(margin_s * 1e9 / BIN_NS), empty_is_car=False, parts=2)
    valid = np.flatnonzero(np.isfinite(mean))  # bins with both channels (sparse data leaves gaps)
    cut = np.zeros(n, bool)
    intervals: list[tuple[int, int]] = []
    for a, b in runs(flags.car[valid]):
        if a == 0 or b == len(valid):
            continue  # it does not come back within the record: a change of state
        first, last = valid[a], valid[b - 1]
        if np.mean(flags.residual_n[valid[a:b]]) <= 0:
            continue  # below the baseline: not a vehicle
        cut[first : last + 1] = True
        intervals.append((t0 + first * BIN_NS, t0 + (last + 1) * BIN_NS))
    return TrafficCut([~cut[i] for i in idx], intervals)
