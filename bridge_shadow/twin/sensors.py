"""What the sensors add: correlated load-cell noise, dropouts (missing messages) and NaN readings.

Load-cell noise per channel is an Ornstein-Uhlenbeck process (time constant chosen so that 60 s
means have lag-1 correlation ``noise_window_phi``, about 0.9 as in the real residuals) plus a
white high-frequency part; their per-sample sd together is the paper's ``Sigma_E`` (60.4 N south,
82.7 N north).
"""

from __future__ import annotations

import numpy as np
from scipy.signal import lfilter

from bridge_shadow.twin.config import TwinConfig

__all__ = ["dropout_mask", "load_cell_noise", "nan_positions"]

NS = 1_000_000_000


def load_cell_noise(rng: np.random.Generator, dt_s: float, n: int, config: TwinConfig) -> np.ndarray:
    """Noise (n, 2) in N on a regular grid of step ``dt_s``: OU (exact AR(1) discretization) + white."""
    phi = np.exp(-dt_s / config.noise_tau_s)
    e = rng.standard_normal((n, 2))
    if n:
        e[0] /= np.sqrt(1.0 - phi**2)  # stationary start
    ou = lfilter([np.sqrt(1.0 - phi**2)], [1.0, -phi], e, axis=0) * config.ou_sd_n
    white = rng.standard_normal((n, 2)) * np.asarray(config.white_sd_n, float)
    return ou + white


def _gap_lengths_s(rng: np.random.Generator, count: int, median_s: float) -> np.ndarray:
    return np.clip(median_s * np.exp(rng.standard_normal(count)), 20.0, 7200.0)


def dropout_mask(
    rng: np.random.Generator,
    t_ns: np.ndarray,
    per_day: float,
    median_s: float,
    channels: int = 1,
    single_fraction: float = 0.0,
) -> np.ndarray:
    """Boolean keep-mask (n, channels): ``round(per_day * days)`` gaps at uniform random start times.

    A gap removes every message whose stamp falls inside it; with ``channels > 1`` a share
    ``single_fraction`` of the gaps hits one random channel only, the rest hit all channels.
    """
    t = np.asarray(t_ns, np.int64)
    keep = np.ones((len(t), channels), dtype=bool)
    if len(t) < 2:
        return keep
    span_ns = int(t[-1] - t[0])
    count = round(per_day * span_ns / (86_400 * NS))
    starts = t[0] + (rng.random(count) * span_ns).astype(np.int64)
    ends = starts + (_gap_lengths_s(rng, count, median_s) * NS).astype(np.int64)
    single = rng.random(count) < single_fraction
    which = rng.integers(0, channels, count)
    lo = np.searchsorted(t, starts, side="left")
    hi = np.searchsorted(t, ends, side="right")
    for i in range(count):  # a handful of gaps: the loop is over gaps, not samples
        cols = [which[i]] if single[i] and channels > 1 else slice(None)
        keep[lo[i] : hi[i], cols] = False
    return keep


def nan_positions(rng: np.random.Generator, n: int, per_day: float, days: float) -> np.ndarray:
    """Draw ``max(1, round(per_day * days))`` distinct sample indices to set to NaN (none if n == 0)."""
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    count = min(n, max(1, round(per_day * days)))
    return np.sort(rng.choice(n, size=count, replace=False))
