"""Least-squares fits of candidate effects with whole-day cross-validation, AR(1) noise, ranking.

The residual ``R: (n, 2)`` N (NaN where a window has no data) is explained by a candidate design
``X: (n, 2, p)``; a nonlinear parameter is searched on a grid inside each training fold. Held-out
predictions come from fits that never saw the held-out day (or block, for records under two days).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter

__all__ = [
    "CvResult",
    "ar1_phi",
    "chance_threshold",
    "chance_threshold_mc",
    "cross_validate",
    "effective_n",
    "fit_best",
    "folds_of",
]


def _lstsq(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Solve ``min |x b - y|`` with columns scaled to unit norm (columns differ by 1e6 in scale)."""
    norm = np.linalg.norm(x, axis=0)
    live = norm > 0
    beta = np.zeros(x.shape[1])
    if live.any():
        sol, *_ = np.linalg.lstsq(x[:, live] / norm[live], y, rcond=1e-10)
        beta[live] = sol / norm[live]
    return beta


def fit_best(
    alts: Sequence[np.ndarray], resid: np.ndarray, mask: np.ndarray
) -> tuple[int, np.ndarray, float]:
    """Fit each alternative design ``(n, 2, p)`` on ``mask`` (n, 2); return (index, beta, SSE) of the best."""
    y = resid[mask]
    best = (0, np.zeros(alts[0].shape[2]), np.inf)
    for i, x in enumerate(alts):
        xm = x[mask]
        beta = _lstsq(xm, y)
        sse = float(np.sum((y - xm @ beta) ** 2))
        if sse < best[2]:
            best = (i, beta, sse)
    return best


def folds_of(day: np.ndarray, valid: np.ndarray, min_fraction: float = 0.25) -> tuple[np.ndarray, str]:
    """Fold index per window: whole days when two or more days hold data, else contiguous blocks.

    A day with fewer than ``min_fraction`` of the windows of the fullest day joins the training
    data of every fold (fold index -1). Returns ``(fold (n,), kind)``, kind ``"day"`` or ``"block"``.
    """
    have = valid.any(axis=1)
    days, counts = np.unique(day[have], return_counts=True)
    keep = days[counts >= min_fraction * counts.max()] if len(days) else days
    if len(keep) >= 2:
        fold = np.where(np.isin(day, keep), day, -1)
        return fold, "day"
    idx = np.flatnonzero(have)
    k = int(min(4, max(2, len(idx) // 3)))
    fold = np.full(len(day), -1)
    if len(idx) >= 2 * 2:
        for j, part in enumerate(np.array_split(idx, k)):
            fold[part[0] : part[-1] + 1] = j
    return fold, "block"


@dataclass
class CvResult:
    """Cross-validated fit of one model (a candidate, or a candidate given another).

    Attributes:
        pred_cv: (n, 2) N, held-out prediction (NaN outside the folds).
        sse_before: (2,) N^2, held-out sum of squares of the residual per channel.
        sse_after: (2,) N^2, the same after subtracting the held-out prediction.
        n_heldout: (2,) held-out windows per channel.
        grid_index: index of the grid value chosen on all data.
        beta: (p,) parameters fitted on all data.
        pred_full: (n, 2) N, prediction of the all-data fit.
        sse_full: in-sample SSE of the all-data fit, N^2.

    """

    pred_cv: np.ndarray
    sse_before: np.ndarray
    sse_after: np.ndarray
    n_heldout: np.ndarray
    grid_index: int
    beta: np.ndarray
    pred_full: np.ndarray
    sse_full: float

    @property
    def reduction(self) -> np.ndarray:
        """(2,) per-channel held-out RMS reduction ``1 - rms_after / rms_before``."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return 1.0 - np.sqrt(self.sse_after / self.sse_before)

    @property
    def reduction_total(self) -> float:
        """Held-out RMS reduction over both channels."""
        return float(1.0 - np.sqrt(self.sse_after.sum() / self.sse_before.sum()))

    @property
    def mse_gain(self) -> float:
        """Held-out fraction of the squared residual removed, ``1 - SSE_after / SSE_before``."""
        return float(1.0 - self.sse_after.sum() / self.sse_before.sum())


def cross_validate(
    alts: Sequence[np.ndarray], resid: np.ndarray, valid: np.ndarray, fold: np.ndarray
) -> CvResult:
    """Fit on all folds but one, predict the left-out one, for every fold; then fit on all data."""
    pred = np.full(resid.shape, np.nan)
    for f in np.unique(fold[fold >= 0]):
        hold = fold == f
        train = valid & ~hold[:, None]
        if not train.any():
            continue
        i, beta, _ = fit_best(alts, resid, train)
        pred[hold] = alts[i][hold] @ beta
    held = valid & np.isfinite(pred)
    r0 = np.where(held, resid, 0.0)
    r1 = np.where(held, resid - np.nan_to_num(pred), 0.0)
    i, beta, sse = fit_best(alts, resid, valid)
    return CvResult(
        pred_cv=pred,
        sse_before=np.sum(r0**2, axis=0),
        sse_after=np.sum(r1**2, axis=0),
        n_heldout=held.sum(axis=0),
        grid_index=i,
        beta=beta,
        pred_full=alts[i] @ beta,
        sse_full=sse,
    )


def ar1_phi(resid: np.ndarray) -> float:
    """Lag-one autocorrelation of a residual ``(n, 2)`` on a regular grid (pairs of valid windows).

    Each channel is centred first; the result is clipped to ``[0, 0.995]``.
    """
    num = den = 0.0
    for c in range(resid.shape[1]):
        e = resid[:, c] - np.nanmean(resid[:, c])
        pair = np.isfinite(e[1:]) & np.isfinite(e[:-1])
        num += float(np.sum(e[1:][pair] * e[:-1][pair]))
        den += float(np.sum(e[np.isfinite(e)] ** 2))
    return float(np.clip(num / den if den > 0 else 0.0, 0.0, 0.995))


def effective_n(n: int, phi: float) -> float:
    """Effective sample size of ``n`` AR(1) samples for a mean: ``n (1 - phi) / (1 + phi)``."""
    return max(1.0, n * (1.0 - phi) / (1.0 + phi))


def chance_threshold(p: int, n_eff: float, n_folds: int, z: float = 4.0) -> float:
    """Held-out squared-residual gain a p-parameter fit of pure AR(1) noise reaches by chance.

    A fit on ``N_tr`` effective training samples predicts the held-out day with a noise-only
    prediction of energy ``p / N_tr`` (relative to the noise variance); its covariance with the
    held-out noise, over ``N_h`` effective samples, has a standard deviation of
    ``sqrt(p / (N_tr N_h))``, so the gain ``2 <pred, r> - |pred|^2`` has a standard deviation of
    about ``2 sqrt(p / (N_tr N_h))``. The threshold is ``z`` such deviations (``z = 4`` covers the
    ten candidates at a family-wise false-alarm rate of about 1e-3 for Gaussian noise).
    """
    k = max(2, n_folds)
    n_tr = max(1.0, n_eff * (k - 1) / k)
    n_h = max(1.0, n_eff / k)
    return float(z * 2.0 * np.sqrt(max(p, 1) / (n_tr * n_h)))


def chance_threshold_mc(
    designs: Mapping[str, Sequence[np.ndarray]],
    valid: np.ndarray,
    fold: np.ndarray,
    phi: float,
    quantile: float = 0.995,
    draws: int = 400,
    seed: int = 0,
) -> dict[str, float]:
    """Chance level of the held-out gain by simulation, for short or strongly correlated records.

    Draws AR(1) noise with the given ``phi`` (independent channels, the record's mask and folds),
    cross-validates every candidate (name -> grid alternatives) on the same draws, and returns per
    candidate the ``quantile`` of its gain (the null distribution is skewed for few effective
    samples, so a quantile rather than mean plus sigmas). Used where the large-sample
    ``chance_threshold`` does not hold.
    """
    rng = np.random.default_rng(seed)
    n = valid.shape[0]
    e = rng.standard_normal((n, 2, draws))
    e[0] /= np.sqrt(max(1e-12, 1.0 - phi**2))  # stationary start
    noise = lfilter([1.0], [1.0, -phi], e, axis=0)
    before = {name: np.zeros(draws) for name in designs}
    after = {name: np.zeros(draws) for name in designs}
    # Every draw at once: the fits are linear in the data (one right-hand side per draw).
    for f in np.unique(fold[fold >= 0]):
        hold = valid & (fold == f)[:, None]
        train = valid & ~(fold == f)[:, None]
        if not train.any() or not hold.any():
            continue
        y_tr, y_h = noise[train], noise[hold]  # (k, draws), (h, draws)
        ss_tr, ss_h = np.sum(y_tr**2, axis=0), np.sum(y_h**2, axis=0)
        for name, alts in designs.items():
            best_sse = np.full(draws, np.inf)
            pred = np.zeros_like(y_h)
            for x in alts:
                xt = x[train]
                norm = np.linalg.norm(xt, axis=0)
                live = norm > 0
                if not live.any():
                    sse, p_h = ss_tr, np.zeros_like(y_h)
                else:
                    # x = Q R: b = R^-1 Q'y, SSE = |y|^2 - |Q'y|^2 (scaled columns; dependent
                    # columns dropped through the diagonal of R).
                    q, r = np.linalg.qr(xt[:, live] / norm[live])
                    keep = np.abs(np.diag(r)) > 1e-10 * np.abs(np.diag(r)).max()
                    q, r = q[:, keep], r[np.ix_(keep, keep)]
                    qty = q.T @ y_tr
                    sse = ss_tr - np.sum(qty**2, axis=0)
                    b = np.linalg.solve(r, qty) / norm[live][keep][:, None]
                    p_h = x[hold][:, live][:, keep] @ b
                better = sse < best_sse
                best_sse = np.where(better, sse, best_sse)
                pred[:, better] = p_h[:, better]
            before[name] += ss_h
            after[name] += np.sum((y_h - pred) ** 2, axis=0)
    return {
        name: float(np.quantile(1.0 - after[name] / np.maximum(before[name], 1e-300), quantile))
        for name in designs
    }
