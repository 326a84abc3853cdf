"""Least-squares fits of candidate effects with whole-day cross-validation, AR(1) noise, ranking.

The residual ``R: (n, 2)`` N (NaN where a window has no data) is explained by a candidate design
``X: (n, 2, p)``; a nonlinear parameter is searched on a grid inside each training fold. Held-out
predictions come from fits that never saw the held-out day (or block, for records under two days).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter

from bridge_shadow.engine import Mapper, serial_mapper

__all__ = [
    "CvResult",
    "ar1_phi",
    "chance_threshold",
    "chance_threshold_mc",
    "cross_validate",
    "effective_n",
    "fit_best",
    "folds_of",
    "lstsq_scaled",
]

#: Bounds of the parameters of one fit: ``(low (p,), high (p,))`` or None (unbounded).
Box = tuple[np.ndarray, np.ndarray] | None


def _pinv_solve(g: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Minimum-norm solution of ``g beta = b`` for a symmetric PSD ``g`` (eigenvalues < 1e-12 max dropped)."""
    if not len(b):
        return np.zeros(0)
    w, v = np.linalg.eigh(g)
    keep = w > 1e-12 * max(w.max(), 1e-300)
    vk = v[:, keep]
    return vk @ ((vk.T @ b) / w[keep])


def lstsq_scaled(x: np.ndarray, y: np.ndarray, box: Box = None) -> np.ndarray:
    """Solve ``min |x b - y|`` with columns scaled to unit norm (columns differ by 1e6 in scale).

    Through the normal equations of the scaled columns, solved with a pseudo-inverse: the
    minimum-norm solution, directions with a singular value under 1e-6 of the largest dropped
    (exactly collinear columns); much faster than an SVD of the tall design, and as accurate for
    the few scaled columns fitted here. With ``box = (low, high)`` the solution is the exact
    minimum inside the box: the unconstrained one when it lies inside, else the best of the
    active sets (each bounded parameter free, at its low or at its high end) whose free part
    lies inside; there are at most ``3^m`` of them for ``m`` bounded parameters (``m <= 2`` here).
    A column of zeros gets 0 (clipped into the box).
    """
    norm = np.linalg.norm(x, axis=0)
    live = norm > 0
    beta = np.zeros(x.shape[1])
    if not live.any():
        return beta if box is None else np.clip(beta, *box)
    xs = x[:, live] / norm[live]
    g = xs.T @ xs
    xty = xs.T @ y
    sol = _pinv_solve(g, xty)
    if box is not None:
        lo = np.asarray(box[0], float)[live] * norm[live]
        hi = np.asarray(box[1], float)[live] * norm[live]
        if not np.all((sol >= lo) & (sol <= hi)):
            sol = _box_solve(g, xty, lo, hi)
    beta[live] = sol / norm[live]
    if box is not None:
        # exactly inside (the scaling may round a bound by an ulp); dead columns at 0 if allowed
        beta[~live] = 0.0
        beta = np.clip(beta, np.asarray(box[0], float), np.asarray(box[1], float))
    return beta


def _box_solve(g: np.ndarray, xty: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Exact box-constrained least squares in normal-equation form by active-set enumeration."""
    import itertools

    bounded = np.flatnonzero(np.isfinite(lo) | np.isfinite(hi))
    best, best_val = None, np.inf
    for states in itertools.product((0, 1, 2), repeat=len(bounded)):
        beta = np.zeros(len(xty))
        fixed = np.zeros(len(xty), bool)
        ok = True
        for j, st in zip(bounded, states, strict=True):
            if st == 0:
                continue
            v = lo[j] if st == 1 else hi[j]
            if not np.isfinite(v):
                ok = False
                break
            beta[j], fixed[j] = v, True
        if not ok:
            continue
        free = ~fixed
        beta[free] = _pinv_solve(g[np.ix_(free, free)], xty[free] - g[np.ix_(free, fixed)] @ beta[fixed])
        if np.any(beta < lo - 1e-12 * np.abs(lo)) or np.any(beta > hi + 1e-12 * np.abs(hi)):
            continue
        val = float(beta @ g @ beta - 2.0 * beta @ xty)
        if val < best_val:
            best, best_val = beta, val
    return best if best is not None else np.clip(np.zeros(len(xty)), lo, hi)


def fit_best(
    alts: Sequence[np.ndarray],
    resid: np.ndarray,
    mask: np.ndarray,
    box: Box = None,
    boxes: Sequence[Box] | None = None,
) -> tuple[int, np.ndarray, float]:
    """Fit each alternative design ``(n, 2, p)`` on ``mask`` (n, 2); return (index, beta, SSE) of the best.

    ``box``: bounds of the parameters (see ``lstsq_scaled``), the same for every alternative;
    ``boxes``: one per alternative instead.
    """
    y = resid[mask]
    best = (0, np.zeros(alts[0].shape[2]), np.inf)
    for i, x in enumerate(alts):
        xm = x[mask]
        beta = lstsq_scaled(xm, y, box if boxes is None else boxes[i])
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
        pred_part: (n, 2) N, the all-data contribution of the last ``n_new`` parameters (the
            candidate added to fixed columns in a joint fit); ``pred_full`` when alone.

    """

    pred_cv: np.ndarray
    sse_before: np.ndarray
    sse_after: np.ndarray
    n_heldout: np.ndarray
    grid_index: int
    beta: np.ndarray
    pred_full: np.ndarray
    sse_full: float
    pred_part: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.pred_part is None:
            self.pred_part = self.pred_full

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


def held_out(
    resid: np.ndarray,
    valid: np.ndarray,
    fold: np.ndarray,
    predict: Callable[[np.ndarray, np.ndarray], np.ndarray],
    mapper: Mapper | None = None,
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Predict each fold from a fit on the others: ``predict(train, hold)`` gives ``pred[hold]``.

    The folds are independent: ``mapper(fn, folds)`` (``bridge_shadow.engine``; default: one
    after the other here) may fit them in parallel, on Dask with ``engine.client_mapper``.
    Returns the held-out predictions (NaN where a fold had no training data) and the
    ``CvResult`` scores ``sse_before``, ``sse_after`` and ``n_heldout`` per channel.
    """
    pred = np.full(resid.shape, np.nan)
    folds = np.unique(fold[fold >= 0]).tolist()

    def one(f: int) -> np.ndarray | None:
        hold = fold == f
        train = valid & ~hold[:, None]
        return predict(train, hold) if train.any() else None

    for f, p in zip(folds, (mapper or serial_mapper)(one, folds), strict=True):
        if p is not None:
            pred[fold == f] = p
    held = valid & np.isfinite(pred)
    r0 = np.where(held, resid, 0.0)
    r1 = np.where(held, resid - np.nan_to_num(pred), 0.0)
    scores = {
        "sse_before": np.sum(r0**2, axis=0),
        "sse_after": np.sum(r1**2, axis=0),
        "n_heldout": held.sum(axis=0),
    }
    return pred, scores


def cross_validate(
    alts: Sequence[np.ndarray],
    resid: np.ndarray,
    valid: np.ndarray,
    fold: np.ndarray,
    bounds: Sequence[tuple[float, float]] | None = None,
    caps: Sequence[tuple[float, float] | None] | None = None,
    mapper: Mapper | None = None,
) -> CvResult:
    """Fit on all folds but one, predict the left-out one, for every fold; then fit on all data.

    ``bounds``: plausible range of the last ``len(bounds)`` parameters (the candidate; earlier
    columns, fixed effects of a joint fit, stay free); every fit is kept inside it. ``caps``: per
    alternative, a narrower range of those parameters (None: ``bounds``), for an alternative that
    only holds near zero (a first-order tangent beside exact secants).
    ``mapper``: how the folds are fitted (``held_out``).
    """
    p = alts[0].shape[2]
    box: Box = None
    boxes: list[Box] | None = None
    n_new = p
    if bounds is not None:
        n_new = len(bounds)
        lo = np.full(p, -np.inf)
        hi = np.full(p, np.inf)
        lo[p - n_new :] = [b[0] for b in bounds]
        hi[p - n_new :] = [b[1] for b in bounds]
        box = (lo, hi)
        if caps is not None:
            boxes = []
            for cap in caps:
                if cap is None:
                    boxes.append(box)
                    continue
                lo_c, hi_c = lo.copy(), hi.copy()
                lo_c[p - n_new :] = np.maximum(lo_c[p - n_new :], cap[0])
                hi_c[p - n_new :] = np.minimum(hi_c[p - n_new :], cap[1])
                boxes.append((lo_c, hi_c))

    def predict(train: np.ndarray, hold: np.ndarray) -> np.ndarray:
        i, beta, _ = fit_best(alts, resid, train, box, boxes)
        return alts[i][hold] @ beta

    pred, scores = held_out(resid, valid, fold, predict, mapper)
    i, beta, sse = fit_best(alts, resid, valid, box, boxes)
    return CvResult(
        pred_cv=pred,
        **scores,
        grid_index=i,
        beta=beta,
        pred_full=alts[i] @ beta,
        sse_full=sse,
        pred_part=alts[i][:, :, p - n_new :] @ beta[p - n_new :],
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
    record: np.ndarray | None = None,
) -> dict[str, float]:
    """Chance level of the held-out gain by simulation, for short or strongly correlated records.

    Draws AR(1) noise with the given ``phi`` (independent channels, the record's mask and folds),
    cross-validates every candidate (name -> grid alternatives) on the same draws, and returns per
    candidate the ``quantile`` of its gain (the null distribution is skewed for few effective
    samples, so a quantile rather than mean plus sigmas). Used where the large-sample
    ``chance_threshold`` does not hold. ``record``: (n,) record index per window on a day of
    records, whose residual the diagnosis demeans per record: the draws are demeaned alike.
    """
    rng = np.random.default_rng(seed)
    n = valid.shape[0]
    e = rng.standard_normal((n, 2, draws))
    e[0] /= np.sqrt(max(1e-12, 1.0 - phi**2))  # stationary start
    noise = lfilter([1.0], [1.0, -phi], e, axis=0)
    if record is not None:
        for k in np.unique(record[record >= 0]):
            for ch in range(2):
                m = (record == k) & valid[:, ch]
                if m.any():
                    noise[m, ch] -= noise[m, ch].mean(axis=0)
    before = {name: np.zeros(draws) for name in designs}
    after = {name: np.zeros(draws) for name in designs}
    # Every draw at once: the fits are linear in the data (one right-hand side per draw). The
    # held-out sum of squares of a fit b is |y_h|^2 - 2 b'X_h'y_h + b'X_h'X_h b, and the products
    # with the draws of every alternative of every candidate are two matrix products per fold.
    for f in np.unique(fold[fold >= 0]):
        hold = valid & (fold == f)[:, None]
        train = valid & ~(fold == f)[:, None]
        if not train.any() or not hold.any():
            continue
        y_tr, y_h = noise[train], noise[hold]  # (k, draws), (h, draws)
        ss_tr, ss_h = np.sum(y_tr**2, axis=0), np.sum(y_h**2, axis=0)
        parts = []  # (name, q (k, p), r (p, p), scale (p,), x_h (h, p)) per alternative
        for name, alts in designs.items():
            for x in alts:
                xt = x[train]
                norm = np.linalg.norm(xt, axis=0)
                live = norm > 0
                if not live.any():
                    parts.append((name, None, None, None, None))
                    continue
                # x = Q R: b = R^-1 Q'y, SSE = |y|^2 - |Q'y|^2 (scaled columns; dependent
                # columns dropped through the diagonal of R).
                q, r = np.linalg.qr(xt[:, live] / norm[live])
                keep = np.abs(np.diag(r)) > 1e-10 * np.abs(np.diag(r)).max()
                xh = x[hold][:, live][:, keep]
                parts.append((name, q[:, keep], r[np.ix_(keep, keep)], norm[live][keep], xh))
        live_parts = [pt for pt in parts if pt[1] is not None]
        if live_parts:
            qty_all = np.concatenate([pt[1] for pt in live_parts], axis=1).T @ y_tr
            xhy_all = np.concatenate([pt[4] for pt in live_parts], axis=1).T @ y_h
        best_sse = {name: np.full(draws, np.inf) for name in designs}
        sse_after = {name: ss_h.copy() for name in designs}
        k = 0
        for name, q, r, scale, xh in parts:
            if q is None:
                sse, sse_h = ss_tr, ss_h
            else:
                p = q.shape[1]
                qty, xhy = qty_all[k : k + p], xhy_all[k : k + p]
                k += p
                sse = ss_tr - np.sum(qty**2, axis=0)
                b = np.linalg.solve(r, qty) / scale[:, None]
                sse_h = ss_h - 2.0 * np.sum(b * xhy, axis=0) + np.sum(b * ((xh.T @ xh) @ b), axis=0)
            better = sse < best_sse[name]
            best_sse[name] = np.where(better, sse, best_sse[name])
            sse_after[name] = np.where(better, sse_h, sse_after[name])
        for name in designs:
            before[name] += ss_h
            after[name] += sse_after[name]
    return {
        name: float(np.quantile(1.0 - after[name] / np.maximum(before[name], 1e-300), quantile))
        for name in designs
    }
