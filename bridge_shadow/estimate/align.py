"""Match air temperature to force stamps and aggregate a window (vectorized, no state).

Temperature arrives at about 1 Hz, forces at 100 Hz to 1 kHz. Each force sample gets a
temperature by ``hold`` (last reading at or before its stamp) or ``linear`` interpolation between
the bracketing readings (held flat beyond the ends). A sample is *stale* when the reading it
relies on is more than ``stale_s`` away: for ``hold`` the age of the last reading, for ``linear``
the distance to the nearer bracketing reading. A window is stale when any of its samples is.
"""

from __future__ import annotations

import numpy as np

__all__ = ["WindowMeans", "match_temperature", "window_means"]


def match_temperature(
    force_stamp_ns: np.ndarray,
    temp_stamp_ns: np.ndarray,
    temp_c: np.ndarray,
    mode: str = "linear",
    stale_ns: int = 120 * 10**9,
) -> tuple[np.ndarray, np.ndarray]:
    """Temperature at each force stamp and a stale flag per sample: ((n,) C, (n,) bool)."""
    t = np.asarray(force_stamp_ns, dtype=np.int64)
    ts = np.asarray(temp_stamp_ns, dtype=np.int64)
    tv = np.asarray(temp_c, dtype=float)
    if len(ts) == 0:
        return np.full(len(t), np.nan), np.ones(len(t), dtype=bool)
    right = np.searchsorted(ts, t, side="right")
    left = right - 1
    if mode == "hold":
        held = left >= 0
        temp = np.where(held, tv[np.clip(left, 0, None)], tv[0])
        age = np.where(held, t - ts[np.clip(left, 0, None)], np.iinfo(np.int64).max)
        return temp, age > stale_ns
    base = ts[0]
    temp = np.interp((t - base).astype(float), (ts - base).astype(float), tv)
    d_left = np.where(left >= 0, t - ts[np.clip(left, 0, None)], np.iinfo(np.int64).max)
    d_right = np.where(right < len(ts), ts[np.clip(right, None, len(ts) - 1)] - t, np.iinfo(np.int64).max)
    return temp, np.minimum(d_left, d_right) > stale_ns


class WindowMeans:
    """Aggregates of one window for both channels.

    Attributes:
        samples: (2,) int, accepted force samples per channel.
        force_n: (2,) N, mean force per channel (NaN when empty).
        temp_c: (2,) C, mean matched temperature per channel (NaN when empty).
        stale: True when any sample had no temperature reading within the stale limit.

    """

    def __init__(self, samples: np.ndarray, force_n: np.ndarray, temp_c: np.ndarray, stale: bool) -> None:
        self.samples = samples
        self.force_n = force_n
        self.temp_c = temp_c
        self.stale = stale


def window_means(
    stamps: list[np.ndarray],
    forces: list[np.ndarray],
    temp_stamp_ns: np.ndarray,
    temp_c: np.ndarray,
    mode: str,
    stale_ns: int,
) -> WindowMeans:
    """Means of force and matched temperature of one window, per channel."""
    samples = np.array([len(s) for s in stamps], dtype=np.int64)
    force = np.full(2, np.nan)
    temp = np.full(2, np.nan)
    stale = False
    for c in range(2):
        if samples[c] == 0:
            continue
        matched, flag = match_temperature(stamps[c], temp_stamp_ns, temp_c, mode, stale_ns)
        force[c] = float(np.mean(forces[c]))
        temp[c] = float(np.mean(matched))
        stale = stale or bool(flag.any())
    return WindowMeans(samples, force, temp, stale)
