"""A record's 60 s windows on a regular grid, for the gap diagnosis (aggregator: ``bridge_shadow.windowing``).

The paper aggregates to 60 s means; the gap diagnosis also needs the within-window spread and
maximum (traffic events). Windows are aligned to multiples of the window length since the epoch,
so the same sample always falls into the same window.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bridge_shadow.contract import CHANNELS
from bridge_shadow.gap.errors import GapError
from bridge_shadow.series import MonitoringData
from bridge_shadow.windowing import window_index, window_stats

__all__ = ["Windows", "aggregate"]

NS = 1_000_000_000


@dataclass
class Windows:
    """Per-window statistics on a regular grid (``n`` windows, channels ``[south, north]``).

    Attributes:
        t_ns: (n,) int64, window centre, ns since epoch (UTC).
        width_s: window length in s.
        mean_n: (n, 2) float, mean force in N (NaN where the window has no sample).
        std_n: (n, 2) float, within-window standard deviation in N (NaN if < 2 samples).
        max_n: (n, 2) float, within-window maximum in N (NaN if empty).
        median_n: (n, 2) float, within-window median in N (NaN if empty).
        count: (n, 2) int, samples per window.
        temp_c: (n,) float, air temperature in C (window mean, linearly interpolated over gaps; all
            NaN when the record holds no temperature).

    """

    t_ns: np.ndarray
    width_s: float
    mean_n: np.ndarray
    std_n: np.ndarray
    max_n: np.ndarray
    median_n: np.ndarray
    count: np.ndarray
    temp_c: np.ndarray

    def __len__(self) -> int:
        return len(self.t_ns)

    @property
    def valid(self) -> np.ndarray:
        """(n, 2) bool: windows with a finite mean force."""
        return np.isfinite(self.mean_n)

    def subtract(self, contribution_n: np.ndarray) -> Windows:
        """Return a copy with ``contribution_n`` (n, 2) N removed from the force statistics."""
        c = np.asarray(contribution_n, float)
        return Windows(
            self.t_ns,
            self.width_s,
            self.mean_n - c,
            self.std_n,
            self.max_n - c,
            self.median_n - c,
            self.count,
            self.temp_c,
        )


def aggregate(data: MonitoringData, width_s: float = 60.0) -> Windows:
    """Aggregate forces and air temperature to windows of ``width_s`` seconds.

    Non-finite samples are dropped. The grid spans the force records; the temperature is the
    window mean where a window holds temperature samples and is linearly interpolated elsewhere
    (all NaN when the record has no temperature). Raises ``GapError`` when a force channel has no
    finite sample.
    """
    width_ns = round(width_s * NS)
    stamps, values = [], []
    for ch in CHANNELS:
        s = data.forces[ch]
        ok = np.isfinite(s.force_n)
        stamps.append(s.stamp_ns[ok])
        values.append(s.force_n[ok])
    if not all(len(s) for s in stamps):
        raise GapError("no finite force samples on one of the load-cell channels")
    temp = data.temperature
    tok = np.isfinite(temp.temp_c)
    first = int(window_index(min(int(s.min()) for s in stamps), width_ns))
    last = int(window_index(max(int(s.max()) for s in stamps), width_ns))
    n = last - first + 1
    t_ns = (np.arange(first, last + 1, dtype=np.int64) * width_ns) + width_ns // 2
    stats = [
        window_stats((window_index(s, width_ns) - first).astype(np.int64), v, n, spread=True)
        for s, v in zip(stamps, values, strict=True)
    ]
    names = ("mean", "std", "max", "median", "count")
    mean, std, vmax, median, count = (np.stack([getattr(st, name) for st in stats], axis=1) for name in names)
    if not tok.any():
        return Windows(t_ns, width_s, mean, std, vmax, median, count.astype(np.int64), np.full(n, np.nan))
    ts, tv = temp.stamp_ns[tok], temp.temp_c[tok]
    widx = window_index(ts, width_ns) - first
    inside = (widx >= 0) & (widx < n)
    tstats = window_stats(widx[inside], tv[inside], n)
    tmean, have = tstats.mean, tstats.count > 0
    order = np.argsort(ts)
    temp_c = np.where(have, tmean, np.interp(t_ns, ts[order], tv[order]))
    return Windows(t_ns, width_s, mean, std, vmax, median, count.astype(np.int64), temp_c)
