"""Synthetic air temperature at the bridge: diurnal cycle plus day-to-day weather.

Each solar day ``d`` (mean solar time at the site) gets a cloudiness ``clearness_d`` in 0..1 and a
mid-range level ``m_d``, both persistent from day to day (AR(1)). Its minimum ``m_d - s_d / 2``
falls at ``t_min_solar_h`` (about sunrise), its maximum ``m_d + s_d / 2`` at ``t_max_solar_h``,
with the swing ``s_d = swing_min + swing_clear * clearness_d``: clear days are warm in the
afternoon and cold at dawn, overcast days flat. Between consecutive extremes the temperature
follows a half cosine (zero slope at each extreme). An Ornstein-Uhlenbeck term adds the irregular
part. The noise-free air temperature is a deterministic function of time once the daily values are
drawn, so it can be evaluated at the force and the temperature stamps alike.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter
from scipy.stats import beta, norm

from bridge_shadow.sun import LON_DEG
from bridge_shadow.twin.config import TwinConfig

__all__ = ["Weather", "ar1", "first_order_lag"]

NS = 1_000_000_000
DAY_NS = 86_400 * NS
#: Mean solar time minus UTC at the site, ns.
SOLAR_OFFSET_NS = round(LON_DEG / 15.0 * 3600.0 * NS)
#: Step of the internal weather grid (irregular part, lagged temperatures), ns.
GRID_NS = 60 * NS


def ar1(rng: np.random.Generator, n: int, phi: float, sd: float) -> np.ndarray:
    """Stationary AR(1) series of length ``n`` with lag-1 correlation ``phi`` and marginal sd ``sd``."""
    if n == 0:
        return np.zeros(0)
    e = rng.standard_normal(n)
    e[0] *= 1.0 / np.sqrt(max(1.0 - phi**2, 1e-300))  # start in the stationary law
    y = lfilter([np.sqrt(1.0 - phi**2)], [1.0, -phi], e)
    return sd * y


def first_order_lag(x: np.ndarray, tau_s: float, dt_s: float) -> np.ndarray:
    """``tau dy/dt = x - y`` on a regular grid (exact for x linear between samples), y0 = x0.

    Uses the exact discretization of a first-order system driven by a piecewise-linear input.
    """
    x = np.asarray(x, float)
    if tau_s <= 0.0 or len(x) < 2:
        return x.copy()
    a = np.exp(-dt_s / tau_s)
    # y[k+1] = a y[k] + (1 - a) x[k+1] - (tau/dt)(1 - a)(x[k+1] - x[k]) - ... written as a filter:
    # y[k+1] = a y[k] + b0 x[k+1] + b1 x[k], b0 = 1 - c, b1 = c - a, c = tau/dt (1 - a).
    c = tau_s / dt_s * (1.0 - a)
    b0, b1 = 1.0 - c, c - a
    y, _ = lfilter([b0, b1], [1.0, -a], x[1:], zi=[a * x[0] + b1 * x[0]])
    return np.concatenate([[x[0]], y])


@dataclass
class Weather:
    """Drawn weather over ``[t0_ns, t1_ns]``.

    Attributes:
        day0: index of the first solar day (days since the epoch in mean solar time).
        clearness: (n_days,) daily clearness 0..1.
        level_c: (n_days,) daily mid-range air temperature, C.
        swing_k: (n_days,) daily swing, K.
        grid_ns: (m,) int64, regular 60 s grid covering the span.
        irregular_k: (m,) irregular part of the air temperature on the grid, K.
        config: the parameters used.

    """

    day0: int
    clearness: np.ndarray
    level_c: np.ndarray
    swing_k: np.ndarray
    grid_ns: np.ndarray
    irregular_k: np.ndarray
    config: TwinConfig

    @classmethod
    def draw(cls, t0_ns: int, t1_ns: int, rng: np.random.Generator, config: TwinConfig) -> Weather:
        """Draw the daily values and the irregular part for the span ``[t0_ns, t1_ns]``."""
        day0 = int((t0_ns + SOLAR_OFFSET_NS) // DAY_NS) - 1
        day1 = int((t1_ns + SOLAR_OFFSET_NS) // DAY_NS) + 2
        n_days = day1 - day0 + 1
        latent = ar1(rng, n_days, config.clearness_phi, 1.0)
        clearness = beta.ppf(norm.cdf(latent), config.clearness_a, config.clearness_b)
        level = config.temp_level_c + ar1(rng, n_days, config.temp_level_phi, config.temp_level_sd_k)
        swing = config.swing_min_k + config.swing_clear_k * clearness
        grid = np.arange(t0_ns - GRID_NS, t1_ns + 2 * GRID_NS, GRID_NS, dtype=np.int64)
        phi = np.exp(-60.0 / (config.weather_tau_h * 3600.0))
        irregular = ar1(rng, len(grid), phi, config.weather_sd_k)
        return cls(day0, clearness, level, swing, grid, irregular, config)

    def _day_index(self, t_ns: np.ndarray) -> np.ndarray:
        idx = (np.asarray(t_ns, np.int64) + SOLAR_OFFSET_NS) // DAY_NS - self.day0
        return np.clip(idx, 0, len(self.clearness) - 1)

    def clearness_at(self, t_ns: np.ndarray) -> np.ndarray:
        """Return the clearness (0..1) of the solar day of each stamp."""
        return self.clearness[self._day_index(t_ns)]

    def diurnal_c(self, t_ns: np.ndarray) -> np.ndarray:
        """Smooth part of the air temperature (daily extremes joined by half cosines), C."""
        cfg = self.config
        days = np.arange(len(self.clearness))
        base = (self.day0 + days) * DAY_NS - SOLAR_OFFSET_NS
        t_min = base + int(cfg.t_min_solar_h * 3600 * NS)
        t_max = base + int(cfg.t_max_solar_h * 3600 * NS)
        anchors_t = np.column_stack([t_min, t_max]).ravel()
        anchors_v = np.column_stack(
            [self.level_c - self.swing_k / 2, self.level_c + self.swing_k / 2]
        ).ravel()
        t = np.asarray(t_ns, np.int64)
        k = np.clip(np.searchsorted(anchors_t, t, side="right") - 1, 0, len(anchors_t) - 2)
        frac = (t - anchors_t[k]) / (anchors_t[k + 1] - anchors_t[k])
        w = 0.5 * (1.0 - np.cos(np.pi * np.clip(frac, 0.0, 1.0)))
        return anchors_v[k] + (anchors_v[k + 1] - anchors_v[k]) * w

    def air_temp_c(self, t_ns: np.ndarray) -> np.ndarray:
        """Noise-free air temperature at the stamps, C (diurnal part plus irregular part)."""
        t = np.asarray(t_ns, np.int64)
        irregular = np.interp(
            (t - self.grid_ns[0]) / NS, (self.grid_ns - self.grid_ns[0]) / NS, self.irregular_k
        )
        return self.diurnal_c(t) + irregular

    def lagged_temp_c(self, t_ns: np.ndarray, tau_h: float) -> np.ndarray:
        """Air temperature through a first-order lag with time constant ``tau_h`` hours, C.

        Computed on the 60 s grid from the start of the drawn span (the spin-up before the record
        puts the lag in its steady state) and interpolated to the stamps.
        """
        t = np.asarray(t_ns, np.int64)
        if tau_h <= 0.0:
            return self.air_temp_c(t)
        rel = (self.grid_ns - self.grid_ns[0]) / NS
        lagged = first_order_lag(self.air_temp_c(self.grid_ns), tau_h * 3600.0, 60.0)
        return np.interp((t - self.grid_ns[0]) / NS, rel, lagged)
