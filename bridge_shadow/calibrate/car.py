"""Test-car detection in a short load-cell record: car-free baseline, crossings and parked plateaus.

The 2022-04-11 records hold a test car that crosses the bridge and parks for about two minutes at a
few positions: plateaus of +5 to +11 kN per bearing, plus short crossings. The car's weight and
positions are not documented. A live load only adds to the central reactions (the influence line
of a continuous beam's middle reaction is positive over both spans), so the car shows as
excursions above a slowly drifting baseline.

Method, on 1 s bin means of the reaction sum ``s(t)``: start from the lowest fifth of the bins
(car-free whatever the drift), fit a straight baseline, flag every bin further than ``threshold_n``
from it (either side), widen the flagged stretches by ``margin_s`` (a crossing's edges are small),
refit on the rest, repeat until the flags settle. Plateaus are runs of car bins where the sum
moves less than ``plateau_rate_n_per_s`` per second for at least ``plateau_min_s``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bridge_shadow.contract import CHANNELS
from bridge_shadow.series import MonitoringData
from bridge_shadow.traffic import flag_car, line_fit, runs
from bridge_shadow.windowing import window_stats

__all__ = ["Binned", "CarDetection", "Plateau", "bin_record", "detect_car"]

NS = 1_000_000_000


@dataclass(frozen=True)
class Binned:
    """Bin means of a record on a common grid.

    Attributes:
        start_ns: stamp of the first bin's left edge (UTC ns). bin_s: bin width, s.
        t_s: (n,) s, bin centres after ``start_ns``.
        force_n: (n, 2) N, mean force per bin [south, north] (NaN where a channel has no sample).
        samples: (n, 2) int, finite samples per bin.
        temp_c: (n,) C, mean air temperature per bin (NaN without a reading in the bin).

    """

    start_ns: int
    bin_s: float
    t_s: np.ndarray
    force_n: np.ndarray
    samples: np.ndarray
    temp_c: np.ndarray


def bin_record(data: MonitoringData, bin_s: float = 1.0) -> Binned:
    """Average both force channels (and the air temperature) into ``bin_s`` bins (NaN samples dropped)."""
    stamps = [data.forces[ch].stamp_ns for ch in CHANNELS]
    t0 = min(int(s.min()) for s in stamps if len(s))
    t1 = max(int(s.max()) for s in stamps if len(s))
    width = round(bin_s * NS)
    n = (t1 - t0) // width + 1
    force = np.full((n, 2), np.nan)
    count = np.zeros((n, 2), np.int64)
    for c, ch in enumerate(CHANNELS):
        s = data.forces[ch]
        ok = np.isfinite(s.force_n)
        stats = window_stats((s.stamp_ns[ok] - t0) // width, s.force_n[ok], n)
        count[:, c], force[:, c] = stats.count, stats.mean
    temp = np.full(n, np.nan)
    ts = data.temperature
    if len(ts):
        ok = np.isfinite(ts.temp_c) & (ts.stamp_ns >= t0) & (ts.stamp_ns < t0 + n * width)
        temp = window_stats((ts.stamp_ns[ok] - t0) // width, ts.temp_c[ok], n).mean
    t_s = (np.arange(n) + 0.5) * bin_s
    return Binned(t0, float(bin_s), t_s, force, count, temp)


@dataclass(frozen=True)
class Plateau:
    """A parked car: a long, flat stretch of a car excursion.

    Attributes:
        start_s, end_s: s after the record start. height_n: (2,) N above the baseline [south, north].
        sd_n: (2,) N, scatter of the 1 s bins on the plateau about their mean.

    """

    start_s: float
    end_s: float
    height_n: np.ndarray
    sd_n: np.ndarray

    def to_dict(self) -> dict[str, object]:
        """Plain data (SI)."""
        return {
            "start_s": self.start_s,
            "end_s": self.end_s,
            "height_n": self.height_n.tolist(),
            "sd_n": self.sd_n.tolist(),
        }


@dataclass
class CarDetection:
    """Where the car was on the bridge.

    Attributes:
        car: (n,) bool, bins affected by the car (or with no data).
        baseline: (2, 2) per channel ``[level at t = 0, slope N/s]`` of the car-free bins.
        intervals_s: car excursions as ``(start_s, end_s)``.
        plateaus: parked-car plateaus.
        iterations: refits until the flags settled.

    """

    car: np.ndarray
    baseline: np.ndarray
    intervals_s: list[tuple[float, float]] = field(default_factory=list)
    plateaus: list[Plateau] = field(default_factory=list)
    iterations: int = 0

    @property
    def free_fraction(self) -> float:
        """Share of the bins that are car-free."""
        return float(np.mean(~self.car)) if len(self.car) else 0.0


def detect_car(
    binned: Binned,
    threshold_n: float = 300.0,
    margin_s: float = 10.0,
    plateau_min_s: float = 60.0,
    plateau_rate_n_per_s: float = 50.0,
    max_iter: int = 20,
) -> CarDetection:
    """Flag the bins the test car affects and find its parked plateaus (see the module docstring).

    Args:
        binned: 1 s bins of the record (``bin_record``).
        threshold_n: distance of the reaction sum from the car-free baseline that counts as car, N
            (load-cell noise of 1 s means is ~20 N, the within-record drift is absorbed by the line).
        margin_s: flagged stretches are widened by this on each side, s.
        plateau_min_s: shortest parked stretch, s. plateau_rate_n_per_s: largest bin-to-bin change of
            the sum on a plateau, N per bin second.
        max_iter: refits at most.

    """
    t, y = binned.t_s, binned.force_n
    s = y.sum(axis=1)
    valid = np.isfinite(s)
    if not valid.any():
        return CarDetection(np.ones(len(s), bool), np.full((2, 2), np.nan))
    flags = flag_car(t, s, threshold_n, round(margin_s / binned.bin_s), max_iter)
    free = ~flags.car
    baseline = np.array([line_fit(t[free], y[free, c]) for c in range(2)])
    det = CarDetection(flags.car, baseline, iterations=flags.iterations)
    base_at = baseline[:, 0][None, :] + baseline[:, 1][None, :] * t[:, None]
    for i, j in runs(det.car & valid):
        det.intervals_s.append((float(t[i] - binned.bin_s / 2), float(t[j - 1] + binned.bin_s / 2)))
        flat = np.zeros(j - i, bool)
        flat[1:] = np.abs(np.diff(s[i:j])) < plateau_rate_n_per_s * binned.bin_s
        for a, b in runs(flat):
            a, b = i + a, i + b
            if (b - a) * binned.bin_s >= plateau_min_s:
                above = y[a:b] - base_at[a:b]
                det.plateaus.append(
                    Plateau(
                        float(t[a] - binned.bin_s / 2),
                        float(t[b - 1] + binned.bin_s / 2),
                        np.nanmean(above, axis=0),
                        np.nanstd(above, axis=0),
                    )
                )
    return det
