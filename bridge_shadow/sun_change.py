"""The change of the deck's sun-driven vertical temperature difference between two records.

``X = g (c_a s_a - c_b s_b)``: ``g`` the difference at full clear sky (the shadow's sun prior, held
at ``g >= 0``), ``c`` a day's clearness from its air's warming, ``s`` the clear-sky sun at the
bridge over a record's windows through the lag the deck follows the sun with (``SUN_LAGS_H``, each
equally likely). ``calibrate``'s ``baseline_change: sun`` (and ``gap``'s) reads a baseline's change
between records so (``calibrate.change``). Plain numpy/scipy; no ROS.

The lags: 0 is the sun term's own instantaneous covariate (and the twin's sun); 3 h lies just
above the 0.25 m slab's diffusion time ``h^2 / (pi^2 alpha)`` of 1.9-2.8 h for concrete's
``alpha = lambda / (rho c)`` of EN 1992-1-2, 3.3 (``lambda`` 1.33-1.95 W/(m K), ``c`` 900 J/(kg K),
``rho`` 2300-2400 kg/m^3): an evening record keeps part of the afternoon's difference.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
from scipy.stats import truncnorm

from bridge_shadow.estimate.compensation.sunlight import FIRST_SD, WANDER_K
from bridge_shadow.sun import CLEAR_SWING_K, LON_DEG, OVERCAST_SWING_K, lagged_clear_sky

__all__ = [
    "CLEARNESS_SD",
    "SUN_LAGS_H",
    "Exposed",
    "exposure_change_moments",
    "g_moments",
    "lagged_sun",
    "solar_day",
    "sun_change_moments",
]

#: Lags (h) the deck's vertical difference may follow the sun with, equally likely (module docstring).
SUN_LAGS_H = (0.0, 1.0, 2.0, 3.0)
#: sd of a day's clearness read from its warming: the air's irregular wander at the morning's
#: minimum and at the afternoon's maximum (``sunlight.WANDER_K`` each) over the clear-overcast span.
CLEARNESS_SD = float(np.sqrt(2.0) * WANDER_K / (CLEAR_SWING_K - OVERCAST_SWING_K))
_NS = 1_000_000_000


class Exposed(Protocol):
    """A record as the sun saw it: its time, its sun per lag, its day's clearness (NaN: unread)."""

    t_ns: int
    sun: tuple[float, ...]
    clearness: float


def solar_day(t_ns: int) -> int:
    """Return the solar day (days since 1970 in mean solar time at the bridge) of ``t_ns``."""
    return int(np.floor((t_ns / _NS + LON_DEG / 15.0 * 3600.0) / 86_400.0))


def lagged_sun(times_ns: np.ndarray) -> tuple[float, ...]:
    """Return the clear-sky sun averaged over ``times_ns`` through each lag of ``SUN_LAGS_H``."""
    times = np.asarray(times_ns, dtype=np.int64)
    return tuple(float(np.mean(lagged_clear_sky(times, tau))) for tau in SUN_LAGS_H)


def g_moments(mean_k: float, sd_k: float) -> tuple[float, float]:
    """``E[g]`` and ``E[g^2]`` of a normal prior held at ``g >= 0`` (a truncated normal), K and K^2."""
    g = truncnorm(-mean_k / sd_k, np.inf, loc=mean_k, scale=sd_k)
    mean = float(g.mean())
    return mean, float(g.var()) + mean**2


def exposure_change_moments(before: Exposed, after: Exposed) -> tuple[float, float, list[float]]:
    """``E[D]``, ``E[D^2]`` of ``D = c_a s_a - c_b s_b`` and each record's ``E[c s]``.

    A day's clearness read from its air is known to ``CLEARNESS_SD``; unread, it is uniform on
    0..1. Two records of one solar day share it (the one read, if only one was). The lag of the
    deck behind the sun is each of ``SUN_LAGS_H`` with equal probability: the moments are the
    means of the moments under each.
    """
    moments = [_at_lag(before, after, j) for j in range(len(SUN_LAGS_H))]
    e_d, e_d2 = (float(np.mean([m[k] for m in moments])) for k in (0, 1))
    return e_d, e_d2, [float(np.mean([m[2][k] for m in moments])) for k in (0, 1)]


def _at_lag(before: Exposed, after: Exposed, lag: int) -> tuple[float, float, list[float]]:
    """``exposure_change_moments`` at the lag ``SUN_LAGS_H[lag]``."""

    def clearness(record: Exposed) -> tuple[float, float]:
        if np.isnan(record.clearness):
            return 0.5, FIRST_SD
        return record.clearness, CLEARNESS_SD

    (cb, sdb), (ca, sda) = clearness(before), clearness(after)
    sb, sa = before.sun[lag], after.sun[lag]
    if solar_day(before.t_ns) == solar_day(after.t_ns):
        c, sd = (ca, sda) if sda <= sdb else (cb, sdb)
        ds = sa - sb
        return c * ds, (c**2 + sd**2) * ds**2, [c * sb, c * sa]
    mean = ca * sa - cb * sb
    return mean, mean**2 + (sda * sa) ** 2 + (sdb * sb) ** 2, [cb * sb, ca * sa]


def sun_change_moments(
    before: Exposed, after: Exposed, prior_mean_k: float, prior_sd_k: float
) -> tuple[float, float, list[float]]:
    """Mean and variance of ``X`` (K, K^2) and each record's ``E[c s]`` (see the module docstring)."""
    e_g, e_g2 = g_moments(prior_mean_k, prior_sd_k)
    e_d, e_d2, exposure = exposure_change_moments(before, after)
    mean = e_g * e_d
    return mean, max(e_g2 * e_d2 - mean**2, 0.0), exposure
