"""Where the gap lies: channel, day, time of day, warming/cooling, sun/shade, frequency band."""

from __future__ import annotations

from typing import Any

import numpy as np

from bridge_shadow.contract import SUPPORTS
from bridge_shadow.gap.drivers import Drivers
from bridge_shadow.gap.windows import NS, Windows

__all__ = ["BANDS_H", "band_fractions", "where"]

#: Frequency bands by period in hours: (name, longest period, shortest period). The traffic band
#: (periods under one window) is measured by the within-window variance.
BANDS_H: tuple[tuple[str, float, float], ...] = (
    ("slower_than_day", np.inf, 30.0),
    ("diurnal", 30.0, 1.0),
    ("sub_hour", 1.0, 0.0),
)


def _nanmean(x: np.ndarray, axis: int = 0) -> np.ndarray:
    """``nanmean`` that gives NaN for an empty or all-NaN slice without a warning."""
    ok = np.isfinite(x)
    n = ok.sum(axis=axis)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 0, np.where(ok, x, 0.0).sum(axis=axis) / n, np.nan)


def _rms(x: np.ndarray, axis: int = 0) -> np.ndarray:
    return np.sqrt(_nanmean(x**2, axis=axis))


def _per_channel(x: np.ndarray) -> dict[str, float]:
    return {name: float(v) for name, v in zip(SUPPORTS, x, strict=True)}


def band_fractions(resid: np.ndarray, within_var: np.ndarray, dt_s: float) -> dict[str, dict[str, float]]:
    """Share of the residual power per band and channel (gaps filled by linear interpolation).

    ``resid``: (n, 2) N window means; ``within_var``: (n, 2) N^2 within-window variance.
    The traffic band is the mean within-window variance; the others come from the periodogram of
    the window means (Parseval: ``sum |X_k|^2 / n^2`` per band adds up to the mean square).
    """
    n = len(resid)
    freq_h = np.fft.rfftfreq(n, d=dt_s / 3600.0)
    with np.errstate(divide="ignore"):
        period_h = np.where(freq_h > 0, 1.0 / np.where(freq_h > 0, freq_h, 1.0), np.inf)
    out: dict[str, dict[str, float]] = {}
    powers = []
    for c in range(2):
        y = resid[:, c]
        ok = np.isfinite(y)
        if ok.sum() < 2:
            powers.append(np.full(len(BANDS_H) + 1, np.nan))
            continue
        idx = np.arange(n)
        y = np.interp(idx, idx[ok], y[ok])
        spec = np.abs(np.fft.rfft(y)) ** 2 / n**2
        spec[1 : (n + 1) // 2] *= 2.0  # one-sided
        p = [float(spec[(period_h <= hi) & (period_h > lo)].sum()) for _, hi, lo in BANDS_H]
        p.append(float(np.nanmean(within_var[:, c])) if np.isfinite(within_var[:, c]).any() else 0.0)
        powers.append(np.array(p))
    names = [b[0] for b in BANDS_H] + ["traffic"]
    for i, name in enumerate(names):
        out[name] = {}
        for c, sup in enumerate(SUPPORTS):
            tot = np.nansum(powers[c])
            out[name][sup] = float(powers[c][i] / tot) if tot > 0 else float("nan")
    return out


def where(w: Windows, d: Drivers, resid: np.ndarray) -> dict[str, Any]:
    """Summarize where the residual ``(n, 2)`` N lies (all magnitudes RMS in N)."""
    ss = np.nansum(resid**2, axis=0)
    hour = ((w.t_ns // NS) % 86400) // 3600
    prof = np.full((24, 2), np.nan)
    for h in range(24):
        sel = hour == h
        if sel.any():
            prof[h] = _nanmean(resid[sel], axis=0)
    # Share of the residual's mean square explained by its hour-of-day profile.
    fitted = prof[hour]
    with np.errstate(invalid="ignore", divide="ignore"):
        tod_share = np.nansum(np.nan_to_num(fitted) ** 2, axis=0) / ss
    daytime = d.sun > 0.05
    clr_med = np.median(np.unique(d.clearness))
    classes = {
        "night": ~daytime,
        "sunny": daytime & (d.clearness >= clr_med),
        "overcast": daytime & (d.clearness < clr_med),
    }
    with np.errstate(invalid="ignore"):
        sun_corr = [
            float(np.corrcoef(d.sun[ok], resid[ok, c])[0, 1])
            if (ok := np.isfinite(resid[:, c])).sum() > 2
            and np.std(d.sun[ok]) > 0
            and np.std(resid[ok, c]) > 0
            else float("nan")
            for c in range(2)
        ]
    return {
        "rms_n": _per_channel(_rms(resid)),
        "mean_n": _per_channel(_nanmean(resid, axis=0)),
        "channel_share": _per_channel(ss / ss.sum() if ss.sum() > 0 else np.full(2, np.nan)),
        "by_day": [{"day": int(k), "rms_n": _per_channel(_rms(resid[d.day == k]))} for k in np.unique(d.day)],
        "time_of_day": {
            "hour_utc": list(range(24)),
            "mean_n": {sup: prof[:, c].tolist() for c, sup in enumerate(SUPPORTS)},
            "share": _per_channel(tod_share),
        },
        "warming_cooling": {
            "warming_rms_n": _per_channel(_rms(resid[d.warming])),
            "cooling_rms_n": _per_channel(_rms(resid[~d.warming])),
        },
        "sun": {
            **{f"{k}_rms_n": _per_channel(_rms(resid[sel])) for k, sel in classes.items()},
            "correlation_with_sun": _per_channel(np.array(sun_corr)),
            "clearness_by_day": [float(d.clearness[d.day == k][0]) for k in np.unique(d.day)],
        },
        "bands": band_fractions(resid, w.std_n**2, w.width_s),
    }
