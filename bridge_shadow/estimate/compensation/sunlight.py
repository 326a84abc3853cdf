"""The sun covariate of the compensation's sun term, from the clock and the air temperature alone.

``s(t) = clear_sky(t) * clearness``: the clear-sky irradiance at the bridge over its yearly peak
(``bridge_shadow.sun``) times the day's clearness, estimated *causally* (online, window by window)
from how much the air has warmed since the morning:

- the air's daily course rises from its minimum near sunrise (``RISE_FROM_H``, mean solar time) to
  its maximum in the early afternoon (``RISE_TO_H``) along half a cosine (the daytime part of
  Parton and Logan's 1981 model of the daily air temperature);
- per solar day the morning minimum is the lowest temperature from 02 h until the maximum; the
  warming since it over the share of the rise made since it estimates the day's swing (after
  ``RISE_TO_H``: the day's highest temperature less the minimum, over the rest of the rise). The
  minimum is normally read about sunrise, where the rise begins; when the day's data begin later
  (a load-test day's first record at 08:36), it is the first reading, partway up, and the share
  made before it is not counted (counted, as first written, a clear day's morning records read
  as grey and the day's sun term fitted ``g`` at a quarter of the twin's), and the swing maps linearly to a
  clearness 0..1 between an overcast and a clear day (the smallest and largest daily ranges of
  March 2022 at the bridge, ``bridge_shadow.sun``; ``gap.drivers`` uses them too);
- that estimate is weighed against the day before's clearness by precision: its noise is the air's
  irregular wander (``WANDER_K``) over the warming a clear day would have made by then, the day
  before's is the day-to-day spread of clearness (``DAY_SD``). Early in the morning (little sun,
  little warming yet) the day before holds; by noon the day's own warming. The covariate does not
  jump when the day's own estimate takes over, and the day's value replaces the day before's at
  solar midnight, when the sun is down. Without a day before: the middle of the range, with the
  spread of a uniform clearness. A day whose morning was not seen (the data start after
  ``MORNING_TO_H``) keeps the day before's.

A rate limit on the clearness (a tenth per hour, so that the air's minute-to-minute wander over the
small share of the rise made early in the morning cannot shake the prediction) was tried: it made
the twin's load-test days worse (the afternoon records' clearness lagged) and was left out.

The state is eight numbers, so the covariate of every window is the same however the data are
chunked, checkpointed or split into archive bags.
"""

from __future__ import annotations

import math

import numpy as np

from bridge_shadow.sun import CLEAR_SWING_K, LON_DEG, OVERCAST_SWING_K, clear_sky

__all__ = ["SunCovariate"]

_NS = 1_000_000_000
_DAY_S = 86_400
#: Mean solar hours of the air's daily minimum and maximum (Parton and Logan 1981: the minimum
#: about sunrise, the maximum about 1.5 h after solar noon; sunrise here 4-8 h over the year).
RISE_FROM_H, RISE_TO_H = 6.0, 14.5
#: The morning minimum is looked for from 02 h (after the previous evening's cooling); a day whose
#: first temperature comes after 08 h (a quarter of the way up a clear day's rise) has no morning.
MORNING_FROM_H, MORNING_TO_H = 2.0, 8.0
#: Irregular wander of the air temperature over hours, K (the twin's ``weather_sd_k``, fitted to the
#: March 2022 record at the bridge), and the day-to-day sd of the clearness (the twin's Beta(1.3,
#: 0.7) of the same fit: 0.275).
WANDER_K, DAY_SD = 0.4, 0.275
#: Spread of the clearness without a day before (uniform on 0..1).
FIRST_SD = 1.0 / math.sqrt(12.0)
#: Windows whose clear-sky values a live shadow computes together, ahead of the windows that need
#: them (``SunCovariate.values`` with ``window_ns``): a window at a time, one ``clear_sky`` call
#: costs most of the covariate (about 0.2 ms of a 0.1 s window's close), a block of 64 about as much.
SKY_BLOCK = 64


def _rise_share(hour: float) -> float:
    """Share of the day's rise the air has made by solar ``hour`` (half a cosine, 0..1)."""
    x = min(max((hour - RISE_FROM_H) / (RISE_TO_H - RISE_FROM_H), 0.0), 1.0)
    return 0.5 * (1.0 - math.cos(math.pi * x))


def _clearness(swing_k: float) -> float:
    return min(max((swing_k - OVERCAST_SWING_K) / (CLEAR_SWING_K - OVERCAST_SWING_K), 0.0), 1.0)


class SunCovariate:
    """Online sun covariate (see the module docstring).

    Attributes:
        day: mean-solar day number of the last window seen (-1: none yet).
        t_min: C, that day's morning minimum so far (inf: none yet); h_min: its solar hour.
        t_max: C, that day's highest temperature since ``RISE_FROM_H`` (-inf: none yet).
        morning: that day's morning was seen (a temperature before ``MORNING_TO_H``).
        today: that day's clearness so far (NaN: none yet).
        today_var: its variance (the precision-weighted one; the prior's before the day's own).
        before: the clearness the day before ended with (NaN: none).

    """

    def __init__(self) -> None:
        self.day = -1
        self.t_min = math.inf
        self.h_min = RISE_FROM_H
        self.t_max = -math.inf
        self.morning = False
        self.today = math.nan
        self.today_var = math.nan
        self.before = math.nan
        self._sky_block: tuple[int, int, np.ndarray] | None = None  # (window_ns, block, values)

    def _sky(self, t_ns: np.ndarray, window_ns: int | None) -> np.ndarray:
        """``clear_sky`` at ``t_ns``; at a few window mid-times, from blocks of ``SKY_BLOCK`` windows.

        A block's values are ``clear_sky`` of its windows' mid-times, element for element the
        values one call over the whole batch gives (numpy's functions act element by element), so
        the covariate is the same however the windows are batched. The block is a cache, not state.
        """
        if window_ns is None or len(t_ns) > SKY_BLOCK:
            return clear_sky(t_ns)
        k = ((t_ns - window_ns // 2) // window_ns).tolist()
        out = np.empty(len(k))
        for i, ki in enumerate(k):
            block = ki // SKY_BLOCK
            cached = self._sky_block
            if cached is None or cached[0] != window_ns or cached[1] != block:
                first = block * SKY_BLOCK
                mids = (np.arange(first, first + SKY_BLOCK, dtype=np.int64) * window_ns) + window_ns // 2
                cached = self._sky_block = (window_ns, block, clear_sky(mids))
            out[i] = cached[2][ki - block * SKY_BLOCK]
        return out

    def _update(self, h: float, t: float) -> None:
        """Take one temperature ``t`` at solar hour ``h`` of the current day."""
        if h >= MORNING_FROM_H and h < RISE_TO_H:
            if t < self.t_min:
                self.t_min, self.h_min = t, h
            self.morning = self.morning or h < MORNING_TO_H
        if h >= RISE_FROM_H:
            self.t_max = max(self.t_max, t)
        # the rise made since the minimum was read: all of it from sunrise, less when the day's
        # data begin after sunrise (the minimum then is the first reading, partway up)
        share = _rise_share(h) - _rise_share(self.h_min)
        if not self.morning or share <= 0.0:
            return
        swing = (t - self.t_min if h < RISE_TO_H else self.t_max - self.t_min) / share
        own = _clearness(swing)
        w_own = (share * (CLEAR_SWING_K - OVERCAST_SWING_K) / WANDER_K) ** 2
        prior, sd = (self.before, DAY_SD) if math.isfinite(self.before) else (0.5, FIRST_SD)
        w_prior = 1.0 / sd**2
        self.today = (w_prior * prior + w_own * own) / (w_prior + w_own)
        self.today_var = 1.0 / (w_prior + w_own)

    def values(
        self, t_ns: np.ndarray, temp_c: np.ndarray, window_ns: int | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Return the covariate (n,) and its variance at window mid-times ``t_ns``, temperatures ``temp_c``.

        Windows come in time order; a NaN temperature leaves the clearness as it is. ``window_ns``
        (optional): ``t_ns`` are the mid-times of windows that long, ``k window_ns + window_ns //
        2``, and the clear sky of a few comes from blocks of them (``_sky``). The variance
        (n,) is the clearness estimate's times ``clear_sky^2``: what the covariate itself does not
        know (a misread sky moves the prediction of a whole run of windows: the step test and the
        segment levels take it).
        """
        t_ns = np.asarray(t_ns, np.int64).reshape(-1)
        temp = np.asarray(temp_c, float).reshape(-1)
        solar_s = t_ns // _NS + round(LON_DEG / 15.0 * 3600.0)
        days = (solar_s // _DAY_S).tolist()
        hours = ((solar_s % _DAY_S) / 3600.0).tolist()
        clear = np.empty(len(t_ns))
        var = np.empty(len(t_ns))
        for i, (d, h, t) in enumerate(zip(days, hours, temp.tolist(), strict=True)):
            clear[i], var[i] = self._step(d, h, t)
        sky = self._sky(t_ns, window_ns)
        return sky * clear, sky**2 * var

    def value_one(self, t_ns: int, temp_c: float, window_ns: int) -> tuple[float, float]:
        """``values`` of one window (mid-time ``t_ns``, ``window_ns`` long) in Python numbers.

        The same integer and float operations as ``values`` of a one-element batch (the square
        as numpy's, ``x * x``), so the same covariate bit for bit, without numpy's per-call cost.
        """
        solar_s = t_ns // _NS + round(LON_DEG / 15.0 * 3600.0)
        clear, var = self._step(solar_s // _DAY_S, (solar_s % _DAY_S) / 3600.0, temp_c)
        k = (t_ns - window_ns // 2) // window_ns
        block = k // SKY_BLOCK
        cached = self._sky_block
        if cached is None or cached[0] != window_ns or cached[1] != block:
            self._sky(np.array([t_ns], np.int64), window_ns)  # computes and keeps the block
            cached = self._sky_block
            assert cached is not None
        sky = float(cached[2][k - block * SKY_BLOCK])
        return sky * clear, sky * sky * var

    def _step(self, day: int, hour: float, temp: float) -> tuple[float, float]:
        """Take one window's temperature (NaN: none) on solar ``day`` at ``hour``: its clearness, variance."""
        if day != self.day:
            if self.day >= 0 and math.isfinite(self.today):
                self.before = self.today
            self.day, self.t_min, self.t_max, self.morning = day, math.inf, -math.inf, False
            self.h_min = RISE_FROM_H
            self.today = self.today_var = math.nan
        if math.isfinite(temp):
            self._update(hour, temp)
        if math.isfinite(self.today):
            return self.today, self.today_var
        if math.isfinite(self.before):
            return self.before, DAY_SD**2
        return 0.5, FIRST_SD**2

    def state_dict(self) -> dict[str, float]:
        """Plain-data state."""
        return {
            "day": float(self.day),
            "t_min": self.t_min,
            "h_min": self.h_min,
            "t_max": self.t_max,
            "morning": float(self.morning),
            "today": self.today,
            "today_var": self.today_var,
            "before": self.before,
        }

    def load_state_dict(self, state: dict[str, object]) -> None:
        """Restore the state."""
        self.day = int(float(state["day"]))  # type: ignore[arg-type]
        self.t_min = float(state["t_min"])  # type: ignore[arg-type]
        self.h_min = float(state.get("h_min", RISE_FROM_H))  # type: ignore[arg-type]
        self.t_max = float(state["t_max"])  # type: ignore[arg-type]
        self.morning = bool(float(state["morning"]))  # type: ignore[arg-type]
        self.today = float(state["today"])  # type: ignore[arg-type]
        self.today_var = float(state["today_var"])  # type: ignore[arg-type]
        self.before = float(state["before"])  # type: ignore[arg-type]
