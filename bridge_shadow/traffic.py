"""The test car's rule: excursions of the reaction sum above a car-free baseline.

Shared by the calibration and the shadow's input screen.

A live load only adds to the central reactions (the influence line of a continuous beam's middle
reaction is positive over both spans), so a vehicle shows as an excursion of ``s(t)``, the sum of
the two central reactions, above a slowly drifting baseline. On 1 s bin means: start from the
lowest fifth of the bins (car-free whatever the drift), fit a straight baseline, flag every bin
further than ``threshold_n`` from it (either side), widen the flagged stretches by ``margin``
bins (a crossing's edges are small), refit on the rest, repeat until the flags settle.

Used by ``calibrate.car.detect_car`` (record levels for the calibration) and by
``estimate.inputs.traffic`` (the shadow's screen of a short record).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["CarFlags", "dilate", "flag_car", "line_fit", "runs"]


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Half-open index runs ``[i, j)`` where ``mask`` is True."""
    m = np.concatenate([[False], mask, [False]]).astype(np.int8)
    d = np.diff(m)
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1), strict=True))


def dilate(mask: np.ndarray, k: int) -> np.ndarray:
    """Widen every True stretch of ``mask`` by ``k`` elements on each side."""
    if k <= 0 or not mask.any():
        return mask
    kernel = np.ones(2 * k + 1)
    return np.convolve(mask.astype(float), kernel, mode="same") > 0


def line_fit(t: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Least-squares ``[intercept at t = 0, slope]``; a flat line through one point."""
    if len(t) < 2 or np.ptp(t) == 0:
        return np.array([float(np.mean(y)) if len(y) else np.nan, 0.0])
    slope, intercept = np.polyfit(t, y, 1)
    return np.array([intercept, slope])


@dataclass(frozen=True)
class CarFlags:
    """Result of ``flag_car``.

    Attributes:
        car: (n,) bool, bins further than the threshold from the baseline (widened), and bins
            without data unless ``empty_is_car`` was False.
        residual_n: (n,) N, ``s`` minus the baseline (NaN without data).
        iterations: refits until the flags settled.

    """

    car: np.ndarray
    residual_n: np.ndarray
    iterations: int


def flag_car(
    t_s: np.ndarray,
    s_n: np.ndarray,
    threshold_n: float,
    margin_bins: int,
    max_iter: int = 20,
    empty_is_car: bool = True,
    parts: int = 1,
    start: np.ndarray | None = None,
) -> CarFlags:
    """Flag the bins of the reaction sum ``s_n`` (N, NaN without data) that a vehicle affects.

    Bins without data are flagged too (they cannot be shown car-free), unless ``empty_is_car`` is
    False (sparse data: a record sampled every few seconds leaves most 1 s bins empty).
    ``parts``: the first baseline starts from the lowest fifth of each of this many equal parts
    of the record (2: both ends, so that a drift of the baseline through the record, ~1 N/s on
    the real records, does not put the whole start on one end and flag the other end as a car).
    ``start``: (n,) bool, the first car-free bins instead (``parts`` is then not used).
    """
    valid = np.isfinite(s_n)
    if not valid.any():
        return CarFlags(np.ones(len(s_n), bool), np.full(len(s_n), np.nan), 0)
    free = np.zeros(len(s_n), bool)
    if start is not None:
        free = valid & np.asarray(start, bool)
    else:
        for part in np.array_split(np.flatnonzero(valid), max(1, parts)):
            if len(part):
                free[part[s_n[part] <= np.quantile(s_n[part], 0.2)]] = True
    resid = np.full(len(s_n), np.nan)
    it = 0
    for it in range(1, max_iter + 1):  # noqa: B007 - the count is reported
        line = line_fit(t_s[free], s_n[free])
        resid = s_n - (line[0] + line[1] * t_s)
        new_free = valid & ~dilate(valid & (np.abs(resid) > threshold_n), margin_bins)
        if not new_free.any() or np.array_equal(new_free, free):
            free = new_free
            break
        free = new_free
    return CarFlags(~free if empty_is_car else valid & ~free, resid, it)
