"""Measured reaction change between two records (before, after an imposed settlement), with its covariance.

Per record (``record_level``):

1. 1 s bins; the test car is flagged (:mod:`.car`) and left out;
2. the car-free stretches are cut into ``window_s`` windows (10 s by default: the car-free parts
   of the 12-minute records are a few minutes long, too short for the shadow's 60 s windows);
3. per channel a straight line ``level + rate (t - t_c)`` is fitted to the window means, ``t_c``
   the mean time of the windows (there the level and the rate are uncorrelated);
4. the uncertainty of the level is the shadow's noise model of window residuals
   (:class:`bridge_shadow.estimate.compensation.noise.NoiseModel`: AR(1) variance of the mean of a run of
   window means, with the channels' correlation).

Between the records (``measured_change``): ``dR = level_after - level_before``. The car-free
baseline drifts within a record (on 2022-04-11 about +0.07 kN/min on some channels while the air
warmed), and nothing is measured in the gap between two records. Three treatments:

- ``baseline_change="uncertainty"`` (default): the baseline's change over the time ``dt`` between
  the two levels is unknown with mean zero and covariance ``dt^2 (r_b r_b' + r_a r_a') / 2``, the
  second moment of the drift-rate vectors ``r`` measured within the two records; it adds to the
  covariance of ``dR``. Nothing is subtracted.
- ``baseline_change="linear"``: the drift is a modelled term: the mean rate ``(r_b + r_a) / 2``
  continues through the gap and ``dt`` times it is subtracted; the covariance then holds
  ``dt^2 (r_a - r_b)(r_a - r_b)' / 4`` (how far the two records disagree on the rate) and the
  rates' standard errors.
- ``baseline_change="sun"``: the baseline's change over hours is the deck's vertical temperature
  difference, driven by the sun (issue 20, item 4): ``dR_sun = v g (c_a s_a - c_b s_b)``, with
  ``v`` the model's response to one kelvin of it (``thermal["vertical_gradient"]``, N/K), ``s``
  the clear-sky covariate at the bridge (``bridge_shadow.sun.clear_sky``) averaged over each
  record's car-free windows, through a lag ``tau`` the deck's difference follows the sun with
  (``bridge_shadow.sun.lagged_clear_sky``; ``tau`` equally likely each of ``sun_change.SUN_LAGS_H``: 0, the
  sun term's own instantaneous covariate, to 3 h, just above the 0.25 m slab's diffusion time
  ``h^2 / (pi^2 alpha)`` of 1.9-2.8 h for concrete's ``alpha = lambda / (rho c)`` of
  EN 1992-1-2, 3.3: ``lambda`` 1.33-1.95 W/(m K), ``c`` 900 J/(kg K), ``rho`` 2300-2400 kg/m^3:
  an evening record keeps part of the afternoon's difference), ``c`` the day's clearness from
  the air's warming over the whole day (``bridge_shadow.sun.daily_warming``; a day without its
  morning and afternoon in the data: 0..1 uniform), and ``g`` the difference at full clear sky
  under the shadow's own prior of its sun term (``sun_gradient_prior_mean_k`` / ``sd_k``:
  EN 1991-1-5, ``config/shadow.yaml``) held at ``g >= 0`` as there (a top warmer than the
  bottom; a truncated normal). Its mean ``v E[X]`` is subtracted and ``v v' Var[X]`` added,
  ``X = g (c_a s_a - c_b s_b)``. The drift each record shows within itself (relaxation after a
  step, the bearings' seating, the sun's own course) is added as an uncertainty over that
  record's own length, ``(D_b^2 r_b r_b' + D_a^2 r_a r_a') / 2``, not over the hours between:
  such a course is not assumed to go on for hours at the rate twelve minutes showed. What this
  treatment assumes and the default does not: that the sun's vertical difference is what moves a
  baseline over hours. The two public records are both from the morning, 44 minutes apart, so
  only the twin checks it (``test_calibrate_sun.py``).

The model's own uniform thermal response to the change of the air temperature between the
records is a modelled term of the forward model, not of this module (``air_temp_change_k``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bridge_shadow.calibrate.car import Binned, CarDetection, bin_record, detect_car
from bridge_shadow.calibrate.errors import CalibrationError
from bridge_shadow.errors import InputError
from bridge_shadow.estimate.compensation.noise import NoiseModel
from bridge_shadow.estimate.compensation.sums import Moments
from bridge_shadow.estimate.parameters.config import ShadowConfig
from bridge_shadow.series import MonitoringData
from bridge_shadow.sun import clearness_of_warming, daily_warming
from bridge_shadow.sun_change import (
    SUN_LAGS_H,
    g_moments,
    lagged_sun,
    solar_day,
    sun_change_moments,
)

__all__ = [
    "BASELINE_CHANGES",
    "MeasuredChange",
    "RecordLevel",
    "SunBaseline",
    "clearness_by_day",
    "clearness_of_day",
    "measured_change",
    "record_level",
]

NS = 1_000_000_000
#: Per-sample load-cell noise of the paper (Sigma_E, DESIGN 2), N: the floor of the window noise.
PAPER_SIGMA_E_N = (60.4, 82.7)
#: Treatments of the baseline's change between two records (see the module docstring).
BASELINE_CHANGES = ("uncertainty", "linear", "sun")


@dataclass(frozen=True)
class SunBaseline:
    """What ``baseline_change="sun"`` needs beside the records (see the module docstring).

    Attributes:
        response_n_per_k: (2,) N/K, the model's reactions per kelvin of a linear vertical
            temperature difference through the deck, top warmer (``thermal["vertical_gradient"]``).
        prior_mean_k, prior_sd_k: the normal prior of that difference at full clear sky, K, held at
            ``g >= 0`` (default: the shadow's sun term's, ``config/shadow.yaml``).

    """

    response_n_per_k: np.ndarray
    prior_mean_k: float = ShadowConfig.sun_gradient_prior_mean_k
    prior_sd_k: float = ShadowConfig.sun_gradient_prior_sd_k

    @classmethod
    def of(cls, surrogate: Any, name: str) -> SunBaseline:
        """Return ``surrogate``'s sun baseline; InputError (naming it ``name``) without the case."""
        response = surrogate.thermal.get("vertical_gradient")
        if response is None:
            raise InputError(
                f"baseline change sun: {name} has no thermal vertical_gradient case "
                "(regenerate it with `bridge-shadow surrogate`)"
            )
        return cls(np.asarray(response, float))

    def moments(self) -> tuple[float, float]:
        """``E[g]`` and ``E[g^2]`` of the prior held at ``g >= 0`` (a truncated normal), K and K^2."""
        return g_moments(self.prior_mean_k, self.prior_sd_k)


@dataclass
class RecordLevel:
    """The car-free level of one record.

    Attributes:
        t_ns: stamp (UTC ns) of the level: the mean time of the car-free windows.
        level_n: (2,) N, car-free level at ``t_ns`` [south, north].
        cov_n2: (2, 2) N^2, covariance of ``level_n`` (AR(1) window noise, ``NoiseModel``).
        rate_n_per_s: (2,) N/s, drift of the car-free baseline within the record.
        rate_se: (2,) N/s, standard error of the rate (same noise model).
        windows: number of car-free windows. window_s: their length, s.
        phi: (2,) lag-1 correlation of the window residuals. sd_n: (2,) N, their sd.
        temp_c: mean air temperature over the car-free windows, C (NaN without temperature).
        car: the car detection (intervals, plateaus).
        start_ns, duration_s: the record's first stamp and length.
        sun: the clear-sky covariate (0..1) averaged over the car-free windows, through each lag
            of ``SUN_LAGS_H``.
        clearness: the day's clearness 0..1 from the air's warming over the whole day in the data
            (NaN when the data hold no morning and afternoon of that day).

    """

    t_ns: int
    level_n: np.ndarray
    cov_n2: np.ndarray
    rate_n_per_s: np.ndarray
    rate_se: np.ndarray
    windows: int
    window_s: float
    phi: np.ndarray
    sd_n: np.ndarray
    temp_c: float
    car: CarDetection
    start_ns: int
    duration_s: float
    sun: tuple[float, ...] = ()
    clearness: float = float("nan")

    def to_dict(self) -> dict[str, Any]:
        """Plain data (SI)."""
        return {
            "start_ns": int(self.start_ns),
            "duration_s": self.duration_s,
            "t_ns": int(self.t_ns),
            "level_n": self.level_n.tolist(),
            "sd_n": np.sqrt(np.diag(self.cov_n2)).tolist(),
            "rate_n_per_s": self.rate_n_per_s.tolist(),
            "rate_se_n_per_s": self.rate_se.tolist(),
            "car_free_windows": self.windows,
            "window_s": self.window_s,
            "residual_phi": self.phi.tolist(),
            "residual_sd_n": self.sd_n.tolist(),
            "air_temp_c": self.temp_c,
            "car_free_fraction": self.car.free_fraction,
            "car_intervals_s": [list(iv) for iv in self.car.intervals_s],
            "plateaus": [p.to_dict() for p in self.car.plateaus],
            "sun_clear_sky": list(self.sun),
            "sun_lags_s": [3600.0 * h for h in SUN_LAGS_H],  # SI (the JSON's); the fit's lags in hours
            "clearness": None if np.isnan(self.clearness) else self.clearness,
        }


def _windows(binned: Binned, car: np.ndarray, per: int) -> list[np.ndarray]:
    """Bin indices of consecutive ``per``-bin windows inside each car-free run (remainders dropped)."""
    free = ~car & np.all(binned.samples > 0, axis=1)
    m = np.concatenate([[False], free, [False]]).astype(np.int8)
    d = np.diff(m)
    out = []
    for i, j in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1), strict=True):
        for k in range((j - i) // per):
            out.append(np.arange(i + k * per, i + (k + 1) * per))
    return out


def record_level(
    data: MonitoringData,
    *,
    window_s: float = 10.0,
    min_windows: int = 3,
    car_threshold_n: float = 300.0,
    car_margin_s: float = 10.0,
) -> RecordLevel:
    """Car-free level, drift rate and their uncertainty of one record (see the module docstring)."""
    binned = bin_record(data, 1.0)
    det = detect_car(binned, threshold_n=car_threshold_n, margin_s=car_margin_s)
    per = max(1, round(window_s / binned.bin_s))
    wins = _windows(binned, det.car, per)
    if len(wins) < min_windows:
        raise CalibrationError(
            f"record from {_iso(binned.start_ns)}: only {len(wins)} car-free windows of {window_s:g} s "
            f"(need {min_windows}); the test car covers {100 * (1 - det.free_fraction):.0f} % of it"
        )
    w_force = np.array([np.average(binned.force_n[w], axis=0, weights=binned.samples[w]) for w in wins])
    w_samples = np.array([binned.samples[w].sum(axis=0) for w in wins])
    w_t = np.array([binned.t_s[w].mean() for w in wins])
    t_c = float(w_t.mean())
    dt = w_t - t_c
    design = np.column_stack([np.ones_like(dt), dt])
    coef, *_ = np.linalg.lstsq(design, w_force, rcond=None)  # (2, 2): [level, rate] x channel
    resid = w_force - design @ coef
    # the shadow's noise model on these residuals: per-sample-equivalent u = sqrt(m) e, lag-1
    # pairs between adjacent windows (a car excursion between two windows breaks the chain)
    u = resid * np.sqrt(w_samples)
    adjacent = np.array([wins[i - 1][-1] + 1 == wins[i][0] for i in range(1, len(wins))], dtype=bool)
    lag = (u[:-1] * u[1:])[adjacent].sum(axis=0) if len(wins) > 1 else np.zeros(2)
    moments = Moments(s2=u.T @ u, lag=lag, n=len(wins), n_pairs=int(adjacent.sum()))
    noise = NoiseModel(np.asarray(PAPER_SIGMA_E_N), adaptive=True, floor=True)
    n_w = len(wins)
    # one level per record plus a rate: the level as a run of n_w windows, the rate as one more dof
    noise.update(moments, edf=np.ones(2), segment_windows=np.array([n_w]))
    m_bar = w_samples.mean(axis=0)
    scale = np.sqrt(np.outer(m_bar, m_bar))
    cov_level = noise.run_cov(n_w) / (n_w * scale)  # AR(1) variance of the mean of the run
    r_window = noise.long_run_cov() / scale  # long-run covariance of one window mean
    sxx = float(np.sum(dt**2))
    rate_se = np.sqrt(np.diag(r_window) / sxx) if sxx > 0 else np.full(2, np.inf)
    temps = np.concatenate([binned.temp_c[w] for w in wins])
    temp = float(np.nanmean(temps)) if np.isfinite(temps).any() else float("nan")
    t_ns = int(binned.start_ns + round(t_c * NS))
    sun = lagged_sun(binned.start_ns + np.round(w_t * NS).astype(np.int64))
    return RecordLevel(
        t_ns=t_ns,
        level_n=coef[0].copy(),
        cov_n2=cov_level,
        rate_n_per_s=coef[1].copy(),
        rate_se=rate_se,
        windows=n_w,
        window_s=per * binned.bin_s,
        phi=noise.phi,
        sd_n=np.sqrt(np.diag(noise.r1) / m_bar),
        temp_c=temp,
        car=det,
        start_ns=int(binned.start_ns),
        duration_s=float(binned.t_s[-1] + binned.bin_s / 2),
        sun=sun,
        clearness=clearness_of_day(data, t_ns),
    )


def clearness_by_day(data: MonitoringData) -> dict[int, float]:
    """Return each solar day's clearness from the air in ``data`` (days without both parts left out)."""
    temp = data.temperature
    if temp is None or not len(temp.stamp_ns):
        return {}
    _, days, warming = daily_warming(temp.stamp_ns, temp.temp_c)
    pairs = zip(days, warming, strict=True)
    return {int(d): float(clearness_of_warming(w)) for d, w in pairs if np.isfinite(w)}


def clearness_of_day(data: MonitoringData, t_ns: int) -> float:
    """Return the clearness of the solar day of ``t_ns`` from the air in ``data`` (NaN: not there)."""
    return clearness_by_day(data).get(solar_day(t_ns), float("nan"))


def _iso(ns: int) -> str:
    import datetime as dt

    return dt.datetime.fromtimestamp(ns / NS, dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")


@dataclass
class MeasuredChange:
    """Reaction change between two records and its covariance.

    Attributes:
        dR_n: (2,) N, after minus before [south, north] (drift-corrected with ``linear``).
        cov_n2: (2, 2) N^2, total covariance: both levels + the baseline change between the records.
        parts: name -> (2, 2) N^2, the covariance's parts (``level_before``, ``level_after``,
            ``baseline_change``; with ``sun`` also ``baseline_wander``).
        dt_s: s between the two levels. air_temp_change_k: K, mean air temperature after minus
            before (NaN without temperature). baseline_change: the treatment used.
        drift_correction_n: (2,) N subtracted from the raw difference (zero for ``uncertainty``).
        before, after: the two record levels.
        sun: with ``sun``: the sun's part (``sun_change_k``: mean and sd of ``X``, the vertical
            difference's change between the records, K; ``exposure``: ``c s`` of each record,
            mean; the prior of ``g``).

    """

    dR_n: np.ndarray
    cov_n2: np.ndarray
    parts: dict[str, np.ndarray] = field(default_factory=dict)
    dt_s: float = 0.0
    air_temp_change_k: float = float("nan")
    baseline_change: str = "uncertainty"
    drift_correction_n: np.ndarray = field(default_factory=lambda: np.zeros(2))
    before: RecordLevel | None = None
    after: RecordLevel | None = None
    sun: dict[str, Any] | None = None

    @property
    def sd_n(self) -> np.ndarray:
        """(2,) N, standard deviation of each channel's change."""
        return np.sqrt(np.diag(self.cov_n2))

    def to_dict(self) -> dict[str, Any]:
        """Plain data (SI)."""
        return {
            "dR_n": self.dR_n.tolist(),
            "sd_n": self.sd_n.tolist(),
            "cov_n2": self.cov_n2.tolist(),
            "parts_sd_n": {k: np.sqrt(np.diag(v)).tolist() for k, v in self.parts.items()},
            "dt_s": self.dt_s,
            "air_temp_change_k": self.air_temp_change_k,
            "baseline_change": self.baseline_change,
            "drift_correction_n": self.drift_correction_n.tolist(),
            "before": self.before.to_dict() if self.before else None,
            "after": self.after.to_dict() if self.after else None,
            "sun": self.sun,
        }


def measured_change(
    before: RecordLevel,
    after: RecordLevel,
    baseline_change: str = "uncertainty",
    sun: SunBaseline | None = None,
) -> MeasuredChange:
    """``after - before`` with the baseline change between them handled as ``baseline_change``.

    ``sun``: the model's response and the prior for ``baseline_change="sun"`` (needed there).
    """
    if baseline_change not in BASELINE_CHANGES:
        raise CalibrationError(
            f"baseline_change must be one of {', '.join(BASELINE_CHANGES)}, got {baseline_change!r}"
        )
    dt = (after.t_ns - before.t_ns) / NS
    if dt <= 0:
        raise CalibrationError("the 'after' record must come after the 'before' record")
    rb, ra = before.rate_n_per_s, after.rate_n_per_s
    correction = np.zeros(2)
    sun_part = None
    parts = {"level_before": before.cov_n2, "level_after": after.cov_n2}
    if baseline_change == "uncertainty":
        parts["baseline_change"] = dt**2 * 0.5 * (np.outer(rb, rb) + np.outer(ra, ra))
    elif baseline_change == "linear":
        correction = dt * 0.5 * (rb + ra)
        diff = ra - rb
        rate_var = np.diag(before.rate_se**2 + after.rate_se**2)
        parts["baseline_change"] = dt**2 * (0.25 * np.outer(diff, diff) + 0.25 * rate_var)
    else:
        if sun is None:
            raise CalibrationError(
                "baseline_change sun needs the model's response to the deck's vertical temperature "
                "difference (thermal vertical_gradient)"
            )
        mean_x, var_x, exposure = sun_change_moments(before, after, sun.prior_mean_k, sun.prior_sd_k)
        v = np.asarray(sun.response_n_per_k, float).reshape(2)
        correction = v * mean_x
        parts["baseline_change"] = np.outer(v, v) * var_x
        parts["baseline_wander"] = 0.5 * (
            before.duration_s**2 * np.outer(rb, rb) + after.duration_s**2 * np.outer(ra, ra)
        )
        sun_part = {
            "sun_change_k": [mean_x, float(np.sqrt(var_x))],
            "exposure": exposure,
            "g_prior_k": [sun.prior_mean_k, sun.prior_sd_k],
            "response_n_per_k": v.tolist(),
        }
    d_temp = after.temp_c - before.temp_c
    return MeasuredChange(
        dR_n=after.level_n - before.level_n - correction,
        cov_n2=sum(parts.values()),
        parts=parts,
        dt_s=dt,
        air_temp_change_k=float(d_temp),
        baseline_change=baseline_change,
        drift_correction_n=correction,
        before=before,
        after=after,
        sun=sun_part,
    )
