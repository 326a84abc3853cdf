"""The one window aggregator: samples in stamp time -> per-window statistics (60 s by default).

Windows are ``[k W, (k + 1) W)`` since the epoch, so the same sample always falls into the same
window. ``window_index`` places samples; ``window_stats`` groups values by window row with
``np.bincount`` (count and mean; with ``spread`` also the within-window standard deviation,
maximum and median). The online shadow closes windows with it (``estimate.inputs.windows``), and the gap
diagnosis aggregates a whole record with it (``gap.windows``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["WindowStats", "sorted_union", "window_index", "window_stats"]


def window_index(stamps_ns: np.ndarray, width_ns: int) -> np.ndarray:
    """Return the window index ``k`` of each stamp (window ``[k W, (k + 1) W)``)."""
    return stamps_ns // width_ns


def sorted_union(parts: list[np.ndarray]) -> np.ndarray:
    """Return ``np.unique(np.concatenate(parts))`` of integer parts (stamps, window indices), merged.

    The set of values is the same whatever the order; parts that are sorted collapse to their
    distinct values in one pass (a record's 100 Hz samples fall in tens of windows, where
    ``np.unique`` of every sample's index took 6 ms), and a stable sort (Timsort for 64-bit
    integers) merges sorted parts in linear time. ``np.unique`` hashes every value first (numpy
    2.3 on): on the two channels' 100 Hz stamps of a 12-minute record, 144,000 distinct values,
    16.6 ms where the merge takes 1.2 ms, and a stream of the two real records replays in 0.66 of
    the time (``benchmarks/record_union.py``).
    """
    both = np.concatenate([_run_starts(p) for p in parts])
    both.sort(kind="stable")
    return _run_starts(both)


def _run_starts(a: np.ndarray) -> np.ndarray:
    """Return ``a`` without the values equal to the one before them (each run of equals once)."""
    first = np.ones(len(a), bool)
    np.not_equal(a[1:], a[:-1], out=first[1:])
    return a[first]


@dataclass
class WindowStats:
    """Statistics of the values of each of ``n`` windows (NaN where a window cannot have one).

    Attributes:
        count: (n,) int64, samples per window.
        mean: (n,) mean (NaN when empty).
        std: (n,) sample standard deviation (NaN with < 2 samples); None without ``spread``.
        max, median: (n,) (NaN when empty); None without ``spread``.

    """

    count: np.ndarray
    mean: np.ndarray
    std: np.ndarray | None = None
    max: np.ndarray | None = None
    median: np.ndarray | None = None


def window_stats(rows: np.ndarray, values: np.ndarray, n: int, spread: bool = False) -> WindowStats:
    """Group ``values`` by window row ``rows`` (ints in ``[0, n)``) and return their statistics.

    Without ``spread`` the sums run in the given sample order; with it the samples are sorted by
    (row, value) first, which gives the maximum and median directly.
    """
    if spread:
        order = np.lexsort((values, rows))
        rows, values = rows[order], values[order]
    count = np.bincount(rows, minlength=n)
    total = np.bincount(rows, values, minlength=n)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = total / count
    if not spread:
        return WindowStats(count, mean)
    with np.errstate(invalid="ignore", divide="ignore"):
        dev = values - mean[rows]
        var = np.bincount(rows, dev * dev, minlength=n) / (count - 1)
    starts = np.concatenate(([0], np.cumsum(count)[:-1]))
    full = count > 0
    vmax = np.full(n, np.nan)
    vmax[full] = values[starts[full] + count[full] - 1]
    # Values are sorted within each window, so the median is the middle element(s).
    lo = starts + (count - 1) // 2
    hi = starts + count // 2
    median = np.full(n, np.nan)
    median[full] = 0.5 * (values[lo[full]] + values[hi[full]])
    std = np.where(count > 1, np.sqrt(np.maximum(var, 0.0)), np.nan)
    return WindowStats(count, mean, std, vmax, median)
