"""Sun position and the clear-sky sun covariate at the bridge (Neubiberg, 48.08 N, 11.64 E).

Solar position: the low-precision formulas of the Astronomical Almanac (declination, right
ascension and sidereal time from days since J2000.0), good to about 0.01 degree in declination and
well under 1 degree in elevation for 1950-2050, which is far below what a thermal covariate needs.

Clear-sky irradiance: the Haurwitz model, ``GHI = 1098 W/m^2 cos(z) exp(-0.059 / cos(z))`` with
``z`` the solar zenith angle (Haurwitz 1945; the simplest clear-sky model that is within about 10 %
of the detailed ones, Reno et al., Sandia SAND2012-2389). ``clear_sky`` normalizes it by its peak
at the site, the value at solar noon on the June solstice, so it runs from 0 (night) to 1; in
mid-March its daily maximum at Neubiberg is about 0.72.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "CLEAR_SWING_K",
    "LAT_DEG",
    "LON_DEG",
    "OVERCAST_SWING_K",
    "clear_sky",
    "clearness_of_warming",
    "daily_warming",
    "haurwitz_ghi",
    "lagged_clear_sky",
    "solar_elevation_deg",
]

#: Site of the bridge (UniBw Munich campus, Neubiberg), degrees north and east.
LAT_DEG: float = 48.08
LON_DEG: float = 11.64
#: Daily air-temperature swing at the bridge on an overcast and on a clear day, K: the smallest and
#: largest daily ranges of March 2022 (``Weather/TemperatureComparisonMUC.csv``: 3.7 and 23.6 K,
#: DESIGN section 3), less about 1 K of irregular weather in each. A day's clearness maps its
#: swing linearly between them (``gap.drivers``, ``estimate.compensation.sunlight``).
OVERCAST_SWING_K, CLEAR_SWING_K = 3.0, 22.5

_NS_PER_DAY = 86_400 * 1_000_000_000
#: 2000-01-01 12:00 UTC (J2000.0) in ns since the Unix epoch.
_J2000_NS = 946_728_000 * 1_000_000_000
#: Obliquity of the ecliptic at J2000.0, degrees.
_OBLIQUITY_DEG = 23.439


def solar_elevation_deg(
    t_ns: np.ndarray | int, lat_deg: float = LAT_DEG, lon_deg: float = LON_DEG
) -> np.ndarray:
    """Geometric solar elevation above the horizon in degrees for stamps ``t_ns`` (UTC ns), any shape."""
    days = (np.asarray(t_ns, dtype=np.int64) - _J2000_NS) / _NS_PER_DAY
    mean_anomaly = np.radians((357.529 + 0.98560028 * days) % 360.0)
    mean_longitude = (280.459 + 0.98564736 * days) % 360.0
    ecl_longitude = np.radians(
        mean_longitude + 1.915 * np.sin(mean_anomaly) + 0.020 * np.sin(2.0 * mean_anomaly)
    )
    eps = np.radians(_OBLIQUITY_DEG - 3.6e-7 * days)
    declination = np.arcsin(np.sin(eps) * np.sin(ecl_longitude))
    right_ascension = np.arctan2(np.cos(eps) * np.sin(ecl_longitude), np.cos(ecl_longitude))
    gmst_h = (18.697374558 + 24.06570982441908 * days) % 24.0
    hour_angle = np.radians(gmst_h * 15.0 + lon_deg) - right_ascension
    lat = np.radians(lat_deg)
    sin_el = np.sin(lat) * np.sin(declination) + np.cos(lat) * np.cos(declination) * np.cos(hour_angle)
    return np.degrees(np.arcsin(np.clip(sin_el, -1.0, 1.0)))


def haurwitz_ghi(elevation_deg: np.ndarray | float) -> np.ndarray:
    """Clear-sky global horizontal irradiance in W/m^2 for a solar elevation in degrees (0 at night)."""
    cos_z = np.sin(np.radians(np.asarray(elevation_deg, dtype=float)))
    safe = np.where(cos_z > 0.0, cos_z, 1.0)
    return np.where(cos_z > 0.0, 1098.0 * cos_z * np.exp(-0.059 / safe), 0.0)


def _site_peak_ghi(lat_deg: float) -> float:
    """Clear-sky irradiance at solar noon on the June solstice at latitude ``lat_deg``, W/m^2."""
    return float(haurwitz_ghi(min(90.0, 90.0 - lat_deg + _OBLIQUITY_DEG)))


def clear_sky(t_ns: np.ndarray | int, lat_deg: float = LAT_DEG, lon_deg: float = LON_DEG) -> np.ndarray:
    """Clear-sky sun covariate, 0..1, for stamps ``t_ns`` (UTC ns), any shape.

    The Haurwitz clear-sky irradiance at the site divided by its yearly peak (solar noon at the
    June solstice). It carries the daily and seasonal course of the sun, not the clouds.
    """
    ghi = haurwitz_ghi(solar_elevation_deg(t_ns, lat_deg, lon_deg))
    return np.clip(ghi / _site_peak_ghi(lat_deg), 0.0, 1.0)


def lagged_clear_sky(t_ns: np.ndarray, tau_h: float, step_s: float = 60.0) -> np.ndarray:
    """Return the clear-sky covariate through a first-order lag of ``tau_h`` hours, at ``t_ns``.

    ``s_tau(t) = integral of clear_sky(t - u) exp(-u / tau) / tau du``: how a deck whose vertical
    temperature difference follows the sun with a delay sees it (``tau_h`` 0: ``clear_sky`` itself).
    Integrated on a ``step_s`` grid from a day before the first stamp (the night between sets every
    earlier sun to nothing that matters), exactly for a piecewise constant sun on the grid.
    """
    t_ns = np.asarray(t_ns, dtype=np.int64)
    if tau_h <= 0.0 or not t_ns.size:
        return clear_sky(t_ns)
    step_ns = round(step_s * 1e9)
    start = int(t_ns.min()) - 86_400 * 1_000_000_000
    grid = np.arange(start, int(t_ns.max()) + step_ns, step_ns, dtype=np.int64)
    sun = clear_sky(grid + step_ns // 2)  # the sun over each step
    keep = float(np.exp(-step_s / (tau_h * 3600.0)))
    # imported here: this module is part of the shadow's start-up (estimate.compensation.sunlight),
    # scipy.signal is 70 ms of it, and only calibrate and gap lag the sun
    from scipy.signal import lfilter

    lagged = lfilter([1.0 - keep], [1.0, -keep], sun)  # the lag's value at the end of each step
    return np.interp(t_ns.astype(float), (grid + step_ns).astype(float), lagged)


def daily_warming(
    t_ns: np.ndarray, temp_c: np.ndarray, lon_deg: float = LON_DEG
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each solar day's sun-driven warming of the air, K (whole days, not causal).

    Per solar day (mean solar time at the site) the warming is the afternoon maximum (10-18 h)
    minus the morning minimum (02-10 h), both needing more than ten readings (a NaN reading makes
    its day's warming NaN).

    Returns:
        The solar day of each stamp (days since 1970 in mean solar time), the distinct days, and
        each day's warming (NaN for a day without both parts).

    """
    t_ns = np.asarray(t_ns, dtype=np.int64)
    temp_c = np.asarray(temp_c, dtype=float)
    solar_s = t_ns // 1_000_000_000 + lon_deg / 15.0 * 3600.0
    sday = np.floor(solar_s / 86_400.0).astype(np.int64)
    hour = (solar_s % 86_400.0) / 3600.0
    days = np.unique(sday)
    warming = np.full(len(days), np.nan)
    for k, dd in enumerate(days):
        sel = sday == dd
        morning = sel & (hour >= 2.0) & (hour < 10.0)
        afternoon = sel & (hour >= 10.0) & (hour < 18.0)
        if morning.sum() > 10 and afternoon.sum() > 10:
            warming[k] = temp_c[afternoon].max() - temp_c[morning].min()
    return sday, days, warming


def clearness_of_warming(warming_k: np.ndarray | float) -> np.ndarray:
    """Return a day's clearness 0..1: its warming mapped from an overcast to a clear day, clipped."""
    return np.clip(
        (np.asarray(warming_k, float) - OVERCAST_SWING_K) / (CLEAR_SWING_K - OVERCAST_SWING_K), 0.0, 1.0
    )
