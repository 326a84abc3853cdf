"""The support-spring candidate: exact closed form, bounded nonlinear least squares.

A spring of compliance ``c_j = 1 / k_j`` (m/N) in series with central bearing ``j`` maps every
reaction of the rigid-support model through ``M(C) = (I + A C)^-1``, ``C = diag(c_s, c_n)``
(:func:`bridge_shadow.model.sensitivities.support_spring_change`). Against the baseline model
``B(t) = u0 + A x_k(t) + thermal_uniform dT(t)`` the reaction change is therefore

    D(C; t) = (M(C) - I) L(t)            (n, 2) N,

with ``L = B`` for a spring that carries the dead load from the nominal level (``loaded``), or
``L = B - u0`` for a support levelled under the dead load. ``D`` is exact for any stiffness, not a
first-order sensitivity: halving the settlement stiffness is as easy to fit as a 1 % change.

``L(t)`` is a combination of four drivers ``Z(t) = [1, x_k,south(t), x_k,north(t), dT(t)]``, so
``D(C; t) = Z(t) U(C)`` with a (4, 2) coefficient matrix ``U``. The sum of squares of what a spring
leaves, with any linear columns of other effects fitted jointly (profiled out), is then a
quadratic form in ``vec U`` over a few Gram matrices computed once per data mask: a fit is a
vectorized scan of a grid of compliances (log-spaced, plus no spring) refined by zooming in on the
best point, all on (8 + q)-sized arrays; the bounds are the grid's ends.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from bridge_shadow.engine import Mapper
from bridge_shadow.gap.fit import CvResult, held_out

__all__ = ["SpringFit", "SpringModel", "best_spring", "cross_validate_spring", "spring_change"]

#: Compliances scanned per bearing: log-spaced over this many decades below the largest one
#: searched, plus zero (no spring); then ``_ZOOMS`` times a linear grid of ``_ZOOM_POINTS`` between
#: the neighbours of the best point (relative precision of the compliance about 1e-4).
_GRID_DECADES = 6.0
_GRID_POINTS = 25
_ZOOMS = 7
_ZOOM_POINTS = 9


def spring_change(load_n: np.ndarray, a: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Reaction change ``(M(C) - I) L`` (n, 2) N for compliances ``c`` (2,) m/N."""
    m = np.linalg.inv(np.eye(2) + a @ np.diag(np.asarray(c, float)))
    return load_n @ (m - np.eye(2)).T


@dataclass
class SpringModel:
    """What the spring acts on.

    Attributes:
        a: (2, 2) N/m, the as-built ``A``.
        u0: (2,) N.
        thermal_uniform: (2,) N/K.
        z: (n, 4), the drivers ``[1, x_k,south, x_k,north, dT]``.

    """

    a: np.ndarray
    u0: np.ndarray
    thermal_uniform: np.ndarray
    z: np.ndarray

    def coefficients(self, c: np.ndarray, loaded: bool) -> np.ndarray:
        """``U(C)`` (..., 4, 2) for compliances ``c`` (..., 2): ``D = Z U``."""
        c = np.asarray(c, float)
        a = self.a
        # M = (I + A C)^-1 in closed form for every c at once.
        p = np.empty((*c.shape[:-1], 2, 2))
        p[..., 0, 0] = 1.0 + a[0, 0] * c[..., 0]
        p[..., 0, 1] = a[0, 1] * c[..., 1]
        p[..., 1, 0] = a[1, 0] * c[..., 0]
        p[..., 1, 1] = 1.0 + a[1, 1] * c[..., 1]
        m = np.linalg.inv(p) - np.eye(2)
        rows = [
            (m @ self.u0) if loaded else np.zeros((*c.shape[:-1], 2)),
            m @ a[:, 0],
            m @ a[:, 1],
            m @ self.thermal_uniform,
        ]
        return np.stack(rows, axis=-2)

    def change(self, c: np.ndarray, loaded: bool) -> np.ndarray:
        """Reaction change (n, 2) N."""
        return self.z @ self.coefficients(c, loaded)


@dataclass
class _Grams:
    """Sufficient statistics of one data mask for the spring and ``q`` jointly fitted columns."""

    vtv: np.ndarray  # (8, 8) block diagonal (channel-major: index ch * 4 + m)
    vr: np.ndarray  # (8,)
    fv: np.ndarray  # (q, 8)
    pinv_ff: np.ndarray  # (q, q)
    fr: np.ndarray  # (q,)
    rr: float

    @classmethod
    def of(cls, z: np.ndarray, resid: np.ndarray, mask: np.ndarray, extra: np.ndarray | None) -> _Grams:
        vtv = np.zeros((8, 8))
        vr = np.zeros(8)
        q = 0 if extra is None else extra.shape[2]
        fv = np.zeros((q, 8))
        for ch in range(2):
            m = mask[:, ch]
            zc = z[m]
            vtv[ch * 4 : ch * 4 + 4, ch * 4 : ch * 4 + 4] = zc.T @ zc
            vr[ch * 4 : ch * 4 + 4] = zc.T @ resid[m, ch]
            if q:
                fv[:, ch * 4 : ch * 4 + 4] = extra[m, ch, :].T @ zc
        y = resid[mask]
        if q:
            f = extra[mask]
            ff = f.T @ f
            w, v = np.linalg.eigh(ff)
            keep = w > 1e-12 * max(w.max(), 1e-300)
            pinv_ff = (v[:, keep] / w[keep]) @ v[:, keep].T
            fr = f.T @ y
        else:
            pinv_ff, fr = np.zeros((0, 0)), np.zeros(0)
        return cls(vtv, vr, fv, pinv_ff, fr, float(y @ y))

    def sse(self, u: np.ndarray) -> np.ndarray:
        """Sum of squares left for coefficient vectors ``u`` (..., 8), the extra columns profiled."""
        out = self.rr - 2.0 * u @ self.vr + np.einsum("...i,ij,...j->...", u, self.vtv, u)
        if len(self.fr):
            g = self.fr - u @ self.fv.T
            out = out - np.einsum("...i,ij,...j->...", g, self.pinv_ff, g)
        return out

    def beta(self, u: np.ndarray) -> np.ndarray:
        """Return the jointly fitted linear parameters for the coefficient vector ``u`` (8,)."""
        if not len(self.fr):
            return np.zeros(0)
        return self.pinv_ff @ (self.fr - self.fv @ u)


@dataclass
class SpringFit:
    """One fit of the support-spring candidate.

    Attributes:
        c: (2,) compliance [south, north] in m/N (0: rigid).
        sse: sum of squares of what is left on the fitted entries, N^2.
        part: (n, 2) N, the spring's reaction change.
        pred: (n, 2) N, the spring's change plus the jointly fitted linear columns.
        beta: (q,) the linear parameters fitted jointly (empty without ``extra``).
        at_bound: the fit ended on ``c_max`` for one of the bearings.

    """

    c: np.ndarray
    sse: float
    part: np.ndarray
    pred: np.ndarray
    beta: np.ndarray
    at_bound: bool


def _vec(u: np.ndarray) -> np.ndarray:
    """(..., 4, 2) -> (..., 8) channel-major."""
    return np.swapaxes(u, -1, -2).reshape((*u.shape[:-2], 8))


def fit_spring(
    model: SpringModel,
    grams: _Grams,
    bearings: Sequence[int],
    loaded: bool,
    c_max: float,
    extra: np.ndarray | None = None,
) -> SpringFit:
    """Fit the compliance(s) of ``bearings`` (0 south, 1 north) in ``[0, c_max]``.

    The least squares are taken over the mask the ``grams`` were computed on; ``extra``
    (n, 2, q) are the linear columns fitted jointly (those of the ``grams``).
    """
    idx = list(bearings)
    levels = [np.concatenate([[0.0], c_max * np.logspace(-_GRID_DECADES, 0.0, _GRID_POINTS)])] * len(idx)
    best = np.zeros(len(idx))
    for _ in range(_ZOOMS + 1):
        mesh = np.stack(np.meshgrid(*levels, indexing="ij"), axis=-1).reshape(-1, len(idx))
        cs = np.zeros((len(mesh), 2))
        cs[:, idx] = mesh
        sse = grams.sse(_vec(model.coefficients(cs, loaded)))
        k = int(np.argmin(sse))
        best = mesh[k]
        # zoom in: between the neighbours of the best level, on every bearing
        pos = np.unravel_index(k, [len(lv) for lv in levels])
        levels = [
            np.linspace(lv[max(i - 1, 0)], lv[min(i + 1, len(lv) - 1)], _ZOOM_POINTS)
            for lv, i in zip(levels, pos, strict=True)
        ]
    c = np.zeros(2)
    c[idx] = best
    u = _vec(model.coefficients(c, loaded))
    beta = grams.beta(u)
    part = model.change(c, loaded)
    pred = part + (extra @ beta if extra is not None and len(beta) else 0.0)
    return SpringFit(c, float(grams.sse(u)), part, pred, beta, bool(np.any(best >= c_max * (1 - 1e-9))))


#: One alternative of the spring candidate: its bearings and whether the spring is loaded.
Alternative = tuple[Sequence[int], bool]


def best_spring(
    model: SpringModel,
    alts: Sequence[Alternative],
    resid: np.ndarray,
    mask: np.ndarray,
    c_max: float,
    extra: np.ndarray | None = None,
) -> tuple[int, SpringFit]:
    """Fit every alternative on ``mask``; return the index and fit of the one that leaves least."""
    grams = _Grams.of(model.z, resid, mask, extra)
    fits = [fit_spring(model, grams, idx, loaded, c_max, extra) for idx, loaded in alts]
    i = int(np.argmin([f.sse for f in fits]))
    return i, fits[i]


def cross_validate_spring(
    model: SpringModel,
    alts: Sequence[Alternative],
    resid: np.ndarray,
    valid: np.ndarray,
    fold: np.ndarray,
    c_max: float,
    extra: np.ndarray | None = None,
    mapper: Mapper | None = None,
) -> tuple[CvResult, SpringFit]:
    """Cross-validate the spring candidate as ``cross_validate`` does a linear one (``mapper``: the folds').

    Returns the ``CvResult`` (``beta`` = the compliances (2,), ``grid_index`` = the choice,
    ``pred_part`` = the spring's own change) and the all-data ``SpringFit``.
    """

    def predict(train: np.ndarray, hold: np.ndarray) -> np.ndarray:
        return best_spring(model, alts, resid, train, c_max, extra)[1].pred[hold]

    pred, scores = held_out(resid, valid, fold, predict, mapper)
    i, fit = best_spring(model, alts, resid, valid, c_max, extra)
    cv = CvResult(
        pred_cv=pred,
        **scores,
        grid_index=i,
        beta=fit.c.copy(),
        pred_full=fit.pred,
        sse_full=fit.sse,
        pred_part=fit.part,
    )
    return cv, fit
