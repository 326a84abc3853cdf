"""Temporal drivers of the candidate effects, computed on the window grid from the data alone.

Nothing here reads the truth twin's ground-truth file: the drivers are time, air temperature (raw and
first-order lagged), the clear-sky sun covariate at Neubiberg times a daily clearness estimated
from the daily air-temperature range, and traffic events detected from the within-window spread.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.signal import lfilter

from bridge_shadow.gap.windows import NS, Windows
from bridge_shadow.sun import clear_sky, clearness_of_warming, daily_warming

__all__ = ["Drivers", "compute_drivers", "lowpass"]

DAY_S = 86400.0


def lowpass(x: np.ndarray, tau_s: float, dt_s: float) -> np.ndarray:
    """First-order lag ``tau dy/dt = x - y`` on a regular grid (exact for piecewise-constant x).

    ``y`` starts in steady state at ``x[0]``.
    """
    x = np.asarray(x, float)
    if tau_s <= 0.0:
        return x.copy()
    a = np.exp(-dt_s / tau_s)
    y, _ = lfilter([1.0 - a], [1.0, -a], x, zi=[a * x[0]])
    return y


@dataclass
class Drivers:
    """Covariates on the window grid (``n`` windows).

    Attributes:
        t_day: (n,) days since the first window.
        day: (n,) int, whole-day block index (24 h blocks from the first window).
        temp_c: (n,) air temperature in C.
        dtemp_k: (n,) air temperature minus its mean over the record, K.
        dt_s: window length in s.
        sun: (n,) clear-sky sun covariate, 0..1.
        clearness: (n,) daily clearness estimate 0..1 from the daily warming of the air.
        warming: (n,) bool, smoothed air temperature rising.
        traffic: (n,) N, excess of the window mean over its median on the summed channels in windows
            flagged as events (within-window maximum far above the noise), 0 elsewhere.
        has_temperature: False when the record holds no air temperature (temperature drivers 0).
        _lag_cache: memo of lowpassed temperature per time constant.

    """

    t_day: np.ndarray
    day: np.ndarray
    temp_c: np.ndarray
    dtemp_k: np.ndarray
    dt_s: float
    sun: np.ndarray
    clearness: np.ndarray
    warming: np.ndarray
    traffic: np.ndarray
    has_temperature: bool = True
    _lag_cache: dict[float, np.ndarray] = field(default_factory=dict, repr=False)

    def __len__(self) -> int:
        return len(self.t_day)

    def lagged_temp(self, tau_h: float) -> np.ndarray:
        """Air temperature through a first-order lag with time constant ``tau_h`` hours, C."""
        if tau_h not in self._lag_cache:
            self._lag_cache[tau_h] = lowpass(self.temp_c, tau_h * 3600.0, self.dt_s)
        return self._lag_cache[tau_h]


def _traffic_driver(w: Windows, z: float = 6.0) -> np.ndarray:
    """Mean-minus-median excess of the summed channels in windows with an outlying maximum, N."""
    spike = np.nansum(w.max_n - w.median_n, axis=1)
    excess = np.nansum(w.mean_n - w.median_n, axis=1)
    ok = np.isfinite(spike) & (w.count.min(axis=1) > 0)
    if ok.sum() < 3:
        return np.zeros(len(w))
    centre = np.median(spike[ok])
    scale = 1.4826 * np.median(np.abs(spike[ok] - centre)) + 1e-9
    event = ok & (spike > centre + z * scale)
    return np.where(event, excess, 0.0)


def _clearness(t_ns: np.ndarray, temp: np.ndarray) -> np.ndarray:
    """Daily clearness 0..1 from the sun-driven warming of the air.

    Per solar day (mean solar time at the site) the warming is the afternoon maximum (10-18 h)
    minus the morning minimum (02-10 h); the clearness maps it linearly from an overcast day
    (``OVERCAST_SWING_K``) to a clear one (``CLEAR_SWING_K``). A day without both parts gets the
    record's median (``bridge_shadow.sun.daily_warming``).
    """
    sday, days, warming = daily_warming(t_ns, temp)
    if not np.isfinite(warming).any():
        return np.ones(len(t_ns))
    warming = np.where(np.isfinite(warming), warming, np.nanmedian(warming))
    return clearness_of_warming(warming)[np.searchsorted(days, sday)]


def compute_drivers(w: Windows) -> Drivers:
    """Compute every temporal driver from the windows (no truth, no model)."""
    t_s = (w.t_ns - w.t_ns[0]) / NS
    t_day = t_s / DAY_S
    day = np.floor(t_day + 1e-9).astype(int)
    temp = np.asarray(w.temp_c, float)
    has_temp = bool(np.isfinite(temp).any())
    if not has_temp:
        # No air temperature: temperature-driven candidates get a zero driver, the sun one a
        # clear sky every day.
        temp = np.zeros(len(w))
    sun = np.asarray(clear_sky(np.asarray(w.t_ns, dtype=np.int64)), dtype=float)
    clearness = _clearness(w.t_ns, temp) if has_temp else np.ones(len(w))
    smooth = lowpass(temp, 1800.0, w.width_s)
    warming = np.gradient(smooth) > 0
    return Drivers(
        t_day=t_day,
        day=day,
        temp_c=temp,
        dtemp_k=temp - temp.mean(),
        dt_s=float(w.width_s),
        sun=sun,
        clearness=clearness,
        warming=warming,
        traffic=_traffic_driver(w),
        has_temperature=has_temp,
    )
