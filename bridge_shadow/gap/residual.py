"""The residual the diagnosis explains: window means minus the baseline model, with its folds.

``residual_of`` aggregates the record to windows (``gap.windows``), computes the drivers, reads the
levels of a day of records (``gap.day_levels``), and forms the residual against the baseline
``u0 + A x_known + thermal_uniform (T - mean T)`` with the known imposed settlement ``x_known``;
the folds of the cross-validation are whole days, the days held out, or (on a day of records)
the records.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from bridge_shadow.contract import CHANNELS
from bridge_shadow.effects import MODEL_FORM_EFFECTS, SETTLEMENT_EFFECTS
from bridge_shadow.gap.candidates import CANDIDATES, Candidate, Context, step_times, stiffness_sensitivities
from bridge_shadow.gap.day_levels import DayLevels, is_day_of_records, read_levels, sweeps_of
from bridge_shadow.gap.drivers import Drivers, compute_drivers
from bridge_shadow.gap.errors import GapError
from bridge_shadow.gap.fit import folds_of
from bridge_shadow.gap.records import one_channel_records, records_of
from bridge_shadow.gap.windows import NS, Windows, aggregate
from bridge_shadow.model.surrogate_file import Surrogate
from bridge_shadow.series import MonitoringData

__all__ = ["MIN_WINDOWS", "Residual", "baseline_residual", "folds", "imposed_path", "residual_of"]

#: Minimum number of valid windows (per channel) to diagnose at all.
MIN_WINDOWS = 8


def imposed_path(t_ns: np.ndarray, width_s: float, steps: Sequence[tuple[int, float, float]]) -> np.ndarray:
    """Known imposed settlement (n, 2) m at the window centres ``t_ns`` from steps ``(t_ns, dx_s, dx_n)``.

    A window that holds the step gets the share of it after the step.
    """
    t = np.asarray(t_ns, dtype=np.int64)
    half = 0.5 * width_s * NS
    x = np.zeros((len(t), 2))
    for when, dxs, dxn in steps:
        share = np.clip((t + half - int(when)) / (2.0 * half), 0.0, 1.0)
        x += share[:, None] * np.array([dxs, dxn])[None, :]
    return x


def baseline_residual(w: Windows, d: Drivers, s: Surrogate, x_known: np.ndarray | None = None) -> np.ndarray:
    """Window means minus the baseline ``u0 + A x_known + thermal_uniform (T - mean T)``; (n, 2) N."""
    return w.mean_n - Context.build(d, s, {}, x_known).baseline


def folds(d: Drivers, valid: np.ndarray, holdout_days: Sequence[int] | None) -> tuple[np.ndarray, str]:
    """Folds of the cross-validation: whole days (or blocks), or the days given to hold out."""
    if not holdout_days:
        return folds_of(d.day, valid)
    days = set(np.unique(d.day).tolist())
    bad = [h for h in holdout_days if h not in days]
    if bad:
        raise GapError(f"--holdout-days {bad} not in the record (days 0..{max(days)})")
    hold = np.isin(d.day, list(holdout_days))
    if hold.all():
        raise GapError("--holdout-days leaves no day to fit on")
    return np.where(hold, 0, -1), "holdout"


@dataclass
class Residual:
    """The residual on the window grid and what the fits need with it.

    Attributes:
        windows: the window statistics. drivers: the temporal drivers.
        sens: the stiffness sensitivities of the model in use.
        levels: the level analysis of a day of records (None for a stream).
        ctx: the candidates' context (model, drivers, imposed settlement, sweeps, step times).
        resid: (n, 2) N, window-mean residual against the baseline model; valid: its finite entries.
        fold: (n,) int, cross-validation fold per window (-1: training only).
        cv_kind: how the folds were made. n_folds: how many.
        record: (n,) record index per window on a day of records (None for a stream).
        candidates: the effects tried (on a day of records the levels own the settlement and
            model-form effects).

    """

    windows: Windows
    drivers: Drivers
    sens: dict[str, Any]
    levels: DayLevels | None
    ctx: Context
    resid: np.ndarray
    valid: np.ndarray
    fold: np.ndarray
    cv_kind: str
    n_folds: int
    record: np.ndarray | None
    candidates: tuple[Candidate, ...]


def residual_of(
    data: MonitoringData,
    s: Surrogate,
    width_s: float,
    holdout_days: Sequence[int] | None,
    imposed: Sequence[tuple[int, float, float]],
    imposed_sd_m: float,
    surrogate_path: str | None,
    baseline_change: str = "uncertainty",
) -> Residual:
    """Aggregate, read the levels of a day of records, form the residual and its folds."""
    w = aggregate(data, width_s)
    d = compute_drivers(w)
    sens = stiffness_sensitivities(s, surrogate_path)
    records = records_of(w.t_ns, w.valid, width_s)
    lv = None
    if is_day_of_records(d, w.valid, records, holdout_days):
        blind = one_channel_records(w.t_ns, w.valid, width_s, records, CHANNELS)
        lv = read_levels(
            data, records, imposed, imposed_sd_m, s, sens, surrogate_path, baseline_change, blind
        )
    model = lv.model if lv is not None else s
    x_known = imposed_path(w.t_ns, width_s, imposed)
    ctx = Context.build(d, model, sens, x_known, w.t_ns, width_s)
    if model is s:  # the sweeps are of the model in use (on a day of records the levels own them)
        ctx.sweeps = sweeps_of(s, surrogate_path)
    resid = w.mean_n - ctx.baseline
    valid = np.isfinite(resid)
    ctx.step_times = step_times(w.t_ns, resid, valid, width_s)
    if valid.sum(axis=0).min() < MIN_WINDOWS:
        have = int(valid.sum(axis=0).min())
        raise GapError(f"only {have} windows of {width_s:g} s with data; need {MIN_WINDOWS}")
    record = None
    candidates = CANDIDATES
    if lv is not None:
        # a day of records: each record a fold, its level the levels' business (demeaned)
        record = np.full(len(w), -1)
        for r in records:
            record[r.first : r.last + 1] = r.index
        fold, cv_kind = record.copy(), "record"
        levels_own = (*SETTLEMENT_EFFECTS, *MODEL_FORM_EFFECTS)
        candidates = tuple(c for c in CANDIDATES if c.name not in levels_own)
    else:
        fold, cv_kind = folds(d, valid, holdout_days)
    n_folds = len(np.unique(fold[fold >= 0]))
    if n_folds < 1:
        raise GapError("not enough data for a held-out check")
    return Residual(w, d, sens, lv, ctx, resid, valid, fold, cv_kind, n_folds, record, candidates)
