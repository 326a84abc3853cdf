"""Every parameter of the truth twin, with its unit, default and where the default comes from.

The effects (``bridge_shadow.effects``) are switched on separately; these are the parts of the
synthetic world that are always there: weather, sensors, data loss, traffic timing. All of them go
into ``truth.yaml``.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import asdict, dataclass, fields
from typing import Any
from zoneinfo import ZoneInfo

import numpy as np
from scipy.optimize import brentq

__all__ = ["DEFAULT_START", "LOCAL_TZ", "TwinConfig", "ou_time_constant_for_window_phi", "window_phi"]

#: Local time of the bridge (the real records are in local time without a zone).
LOCAL_TZ = ZoneInfo("Europe/Berlin")
#: Default start of a synthetic record: the first full day of the March 2022 campaign.
DEFAULT_START = dt.datetime(2022, 3, 14, 0, 0, tzinfo=LOCAL_TZ)


def window_phi(window_s: float, tau_s: float) -> float:
    """Lag-1 correlation of consecutive ``window_s`` means of an Ornstein-Uhlenbeck process.

    For correlation ``exp(-|t| / tau)`` and ``a = window_s / tau``:
    ``phi = (1 - e^-a)^2 / (2 (a - 1 + e^-a))`` (adjacent-window covariance over the window-mean
    variance).
    """
    a = window_s / tau_s
    return float(np.expm1(-a) ** 2 / (2.0 * (a + np.expm1(-a))))


def ou_time_constant_for_window_phi(phi: float, window_s: float = 60.0) -> float:
    """Time constant (s) of the OU process whose ``window_s`` means have lag-1 correlation ``phi``."""
    if not 0.0 < phi < 1.0:
        raise ValueError("phi must lie in (0, 1)")
    return float(brentq(lambda tau: window_phi(window_s, tau) - phi, 1e-3 * window_s, 1e6 * window_s))


@dataclass(frozen=True)
class TwinConfig:
    """Parameters of the synthetic world (SI units; temperatures in C, differences in K).

    Weather (fitted by eye to the March 2022 record at the bridge,
    ``Weather/TemperatureComparisonMUC.csv``: mean daily swing 16.6 K, range 3.7-23.6 K, mean of
    the daily mid-range 6.6 C with day-to-day sd 1.9 K and lag-1 correlation 0.76, extremes -6.0
    and 20.7 C; March 2022 was unusually sunny in Bavaria):

    Attributes:
        temp_level_c: mean daily mid-range air temperature, C.
        temp_level_sd_k: day-to-day sd of the daily mid-range, K.
        temp_level_phi: day-to-day AR(1) correlation of the mid-range.
        clearness_a: Beta(a, b) shape of the daily clearness (0 overcast .. 1 clear sky).
        clearness_b: second Beta shape.
        clearness_phi: day-to-day correlation of the latent Gaussian behind the clearness.
        swing_min_k: daily swing (max - min) of an overcast day, K.
        swing_clear_k: extra daily swing of a clear day, K (swing = min + clear * clearness).
        t_min_solar_h: time of the daily minimum, mean solar time, h (about sunrise in March).
        t_max_solar_h: time of the daily maximum, mean solar time, h.
        weather_sd_k: sd of the irregular part of the air temperature (OU), K.
        weather_tau_h: time constant of the irregular part, h.
        temp_sensor_sd_k: white noise of the air-temperature sensor, K (also its ``variance``).
        noise_sd_n: per-sample sd of the load-cell noise [south, north], N (the paper's Sigma_E).
        white_sd_n: white (high-frequency) part of that noise, N (100 Hz noise 15-26 N, DESIGN 3).
        noise_window_phi: lag-1 correlation of 60 s means of the noise (DESIGN 6: about 0.9).
        gaps_per_day: force dropouts per day (messages missing, both channels unless single).
        gap_median_s: median dropout length, s (lognormal, sd of log 1.0, clipped to 20 s .. 2 h).
        gap_single_fraction: share of dropouts that hit one channel only.
        nan_per_day: NaN force messages per channel per day (at least one per channel).
        temp_gaps_per_day: air-temperature dropouts per day (same length law).
        temp_nan_per_day: NaN air-temperature messages per day (at least one).
        traffic_per_hour: test-car crossings per hour in the traffic window (traffic effect only).
        traffic_start_h: start of the traffic window, local time, h.
        traffic_end_h: end of the traffic window, local time, h.
        traffic_duration_s: mean crossing time of the 30 m bridge, s (uniform +-20 %).
        traffic_lateral_sd: sd of the south share of a car's weight around 0.5 (lane position, about +-10 cm).
        span_m: span length of each of the two equal spans, m.
        spinup_days: days of weather simulated before the start (lagged states in steady state).

    """

    temp_level_c: float = 6.6
    temp_level_sd_k: float = 1.9
    temp_level_phi: float = 0.75
    clearness_a: float = 1.3
    clearness_b: float = 0.7
    clearness_phi: float = 0.8
    swing_min_k: float = 2.5
    swing_clear_k: float = 20.0
    t_min_solar_h: float = 6.0
    t_max_solar_h: float = 14.5
    weather_sd_k: float = 0.4
    weather_tau_h: float = 1.5
    temp_sensor_sd_k: float = 0.05
    noise_sd_n: tuple[float, float] = (60.4, 82.7)
    white_sd_n: tuple[float, float] = (20.0, 25.0)
    noise_window_phi: float = 0.9
    gaps_per_day: float = 1.0
    gap_median_s: float = 300.0
    gap_single_fraction: float = 0.3
    nan_per_day: float = 3.0
    temp_gaps_per_day: float = 0.5
    temp_nan_per_day: float = 1.0
    traffic_per_hour: float = 6.0
    traffic_start_h: float = 8.0
    traffic_end_h: float = 18.0
    traffic_duration_s: float = 10.0
    traffic_lateral_sd: float = 0.02
    span_m: float = 15.0
    spinup_days: float = 2.0

    @property
    def noise_tau_s(self) -> float:
        """Time constant of the correlated (OU) part of the load-cell noise, s."""
        return ou_time_constant_for_window_phi(self.noise_window_phi, 60.0)

    @property
    def ou_sd_n(self) -> np.ndarray:
        """Sd of the correlated part of the load-cell noise [south, north], N."""
        total, white = np.asarray(self.noise_sd_n, float), np.asarray(self.white_sd_n, float)
        return np.sqrt(np.maximum(total**2 - white**2, 0.0))

    def to_dict(self) -> dict[str, Any]:
        """Plain data (lists, floats) plus the derived noise time constant."""
        out = {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}
        out["noise_tau_s"] = self.noise_tau_s
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> TwinConfig:
        """Inverse of ``to_dict`` (derived keys are ignored)."""
        names = {f.name for f in fields(cls)}
        kwargs = {k: tuple(v) if isinstance(v, list) else v for k, v in data.items() if k in names}
        return cls(**kwargs)
