"""Laplace approximation of the posterior and the evidence, with parameters held at a bound.

Coordinates are prior-whitened (``u = (log p - mu) / sigma``, jack errors ``e / sigma_e``), so the
prior is ``N(0, I)``, truncated to the box ``a <= u <= b``: every parameter's plausible range
(``bridge_shadow.model.parameters``: +-3.29 sd, and ``b = 0`` for a fraction whose prior centre
is its hard bound 1, "as built"). With ``r(u)`` the stacked whitened residuals (data rows, then
the prior rows ``u``), ``J`` its Jacobian at the mode ``u*`` and ``H = J'J`` (Gauss-Newton):

    log p(D) = -|r*|^2 / 2 - log det(2 pi Sigma_D) / 2 - log det H / 2
               + g' H^-1 g / 2 + log P(a <= u* + d <= b) - sum log (Phi(b_i) - Phi(a_i))

The first three terms are the usual Laplace evidence (misfit, normalization, Occam factor). At a
mode on a bound the gradient ``g = J' r`` does not vanish: the quadratic model is integrated over
the feasible box only, ``d ~ N(-H^-1 g, H^-1)`` restricted to it (the term ``P``); the last term
is the truncated prior's normalization (``log 2`` per fraction whose centre is its bound, 0.001
for a +-3.29 sd range). For a bounded coordinate the reported marginal is that Gaussian truncated
to its range (exact for one coordinate; an approximation for several that are correlated), and
its 95 % interval the highest-density one: one-sided when a bound lies inside it (a central
interval would leave out the most probable values next to the bound). Unbounded coordinates get
the central interval (the same thing for a Gaussian).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize, stats

__all__ = ["Laplace", "laplace"]


@dataclass
class Laplace:
    """Gaussian (truncated) posterior at the mode and the log evidence.

    Attributes:
        mode: (n,) u*. centre: (n,) ``u* - H^-1 g``, the centre of the quadratic model (equal to
            the mode unless a bound is active). cov: (n, n) ``H^-1``.
        bounded: (n,) bool, coordinates with a bound. lower, upper: (n,) the bounds (-inf, inf if none).
        active: (n,) bool, held at a bound at the mode.
        mean, sd, q500: (n,) marginal mean, sd and median (truncated at the bound where there is one).
        lo95, hi95: (n,) 95 % interval (central; highest-density for a bounded coordinate).
        log_evidence: as in the module docstring; parts: its terms by name.

    """

    mode: np.ndarray
    centre: np.ndarray
    cov: np.ndarray
    bounded: np.ndarray
    upper: np.ndarray
    active: np.ndarray
    lower: np.ndarray
    mean: np.ndarray
    sd: np.ndarray
    q500: np.ndarray
    lo95: np.ndarray
    hi95: np.ndarray
    log_evidence: float
    parts: dict[str, float]

    def truncated_cov(self) -> np.ndarray:
        """``cov`` with each bounded coordinate's variance replaced by its truncated marginal's.

        ``D cov D`` with ``D_ii = sd_i / sqrt(cov_ii)``: correlations kept, the spread of a
        parameter pressed against its bound reduced to the feasible side.
        """
        d = self.sd / np.sqrt(np.diag(self.cov))
        return self.cov * np.outer(d, d)


_Z95 = 1.959963984540054


def _hpd95(dist: stats.rv_continuous, mode: float, lower: float, upper: float) -> tuple[float, float]:
    """95 % highest-density interval of a normal (centre ``mode``) truncated to ``[lower, upper]``."""
    m = min(max(mode, lower), upper)

    def mass(w: float) -> float:
        return float(dist.cdf(min(m + w, upper)) - dist.cdf(max(m - w, lower))) - 0.95

    # the density falls off symmetrically about the mode, so the interval is the mode +- w cut at
    # the bounds; w grows until it holds 95 %
    w_max = max(upper - m, m - lower)
    if not np.isfinite(w_max):
        w_max = abs(m) + 50.0 * float(dist.std()) + 1.0
    w = optimize.brentq(mass, 0.0, w_max)
    return max(m - w, lower), min(m + w, upper)


def _truncated_moments(
    dist: stats.rv_continuous, alpha: float, beta: float, lower: float, upper: float, scale: float
) -> tuple[float, float, float]:
    """Mean, sd and median of a normal truncated to ``[lower, upper]`` (``alpha``, ``beta`` in sds).

    scipy's moments cancel catastrophically when the centre lies hundreds of sds beyond a bound
    (a fit that fits nothing: a pair given with the wrong sign put it 1080 sds off, and the sd
    came out NaN with numpy's RuntimeWarnings on the terminal). There the density is the
    exponential limit at the near bound: rate ``z / scale``, ``z`` the bound's distance in sds.
    """
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        mean, sd, median = float(dist.mean()), float(dist.std()), float(dist.median())
    if np.isfinite(mean) and np.isfinite(sd) and np.isfinite(median):
        return mean, sd, median
    if alpha <= 0.0 <= beta:  # the centre inside: the interval's own spread, no wider than the normal's
        width = upper - lower
        return (
            float(np.clip(dist.kwds["loc"], lower, upper)),
            min(scale, width / math.sqrt(12.0)),
            float(np.clip(dist.kwds["loc"], lower, upper)),
        )
    edge, z, sign = (lower, alpha, 1.0) if alpha > 0 else (upper, -beta, -1.0)
    tail = scale / z
    return edge + sign * tail, tail, edge + sign * tail * math.log(2.0)


def _feasible_probability(mean: np.ndarray, cov: np.ndarray, low: np.ndarray, high: np.ndarray) -> float:
    """``P(low <= d <= high)`` for ``d ~ N(mean, cov)`` (1-D exact, else scipy's Genz integration)."""
    if len(mean) == 0:
        return 1.0
    if len(mean) == 1:
        sd = np.sqrt(cov[0, 0])
        return float(stats.norm.cdf(high[0], mean[0], sd) - stats.norm.cdf(low[0], mean[0], sd))
    return float(stats.multivariate_normal(mean, cov, allow_singular=True).cdf(high, lower_limit=low))


def laplace(
    r: np.ndarray,
    J: np.ndarray,
    u: np.ndarray,
    upper: np.ndarray,
    n_data: int,
    logdet_data_cov: float,
    lower: np.ndarray | None = None,
) -> Laplace:
    """Laplace posterior and evidence at ``u`` (see the module docstring).

    Args:
        r: (m,) whitened residuals at ``u`` (data rows first, then the ``n`` prior rows).
        J: (m, n) their Jacobian. u: (n,) the mode. upper, lower: (n,) bounds (inf, -inf: none).
        n_data: number of data rows. logdet_data_cov: ``log det Sigma_D`` of the data (SI units).

    """
    lower = np.full(len(u), -np.inf) if lower is None else np.asarray(lower, float)
    h = J.T @ J
    cov = np.linalg.inv(h)
    cov = 0.5 * (cov + cov.T)
    g = J.T @ r
    bounded = np.isfinite(upper) | np.isfinite(lower)
    active = ((u >= upper - 1e-9) & (g < 0)) | ((u <= lower + 1e-9) & (g > 0))
    shift = -cov @ np.where(active, g, 0.0)  # the gradient vanishes on the free coordinates
    centre = u + shift
    _, logdet_h = np.linalg.slogdet(h)
    b = np.flatnonzero(bounded)
    p_feas = _feasible_probability(shift[b], cov[np.ix_(b, b)], lower[b] - u[b], upper[b] - u[b])
    g_a = np.where(active, g, 0.0)
    prior_mass = stats.norm.cdf(upper[b]) - stats.norm.cdf(lower[b])
    parts = {
        "misfit": -0.5 * float(r @ r),
        "data_normalization": -0.5 * (n_data * np.log(2 * np.pi) + logdet_data_cov),
        "occam": -0.5 * float(logdet_h),
        "bound_gradient": 0.5 * float(g_a @ cov @ g_a),
        "bound_feasible": float(np.log(max(p_feas, 1e-300))),
        "truncated_prior": -float(np.sum(np.log(prior_mass))),
    }
    sd0 = np.sqrt(np.diag(cov))
    mean, sd, q500 = centre.copy(), sd0.copy(), centre.copy()
    lo95, hi95 = centre - _Z95 * sd0, centre + _Z95 * sd0
    for i in b:
        alpha, beta = (lower[i] - centre[i]) / sd0[i], (upper[i] - centre[i]) / sd0[i]
        dist = stats.truncnorm(alpha, beta, loc=centre[i], scale=sd0[i])
        mean[i], sd[i], q500[i] = _truncated_moments(dist, alpha, beta, lower[i], upper[i], sd0[i])
        lo95[i], hi95[i] = _hpd95(dist, centre[i], lower[i], upper[i])
    return Laplace(
        mode=u.copy(),
        centre=centre,
        cov=cov,
        bounded=bounded,
        upper=upper.copy(),
        active=active,
        lower=lower.copy(),
        mean=mean,
        sd=sd,
        q500=q500,
        lo95=lo95,
        hi95=hi95,
        log_evidence=float(sum(parts.values())),
        parts=parts,
    )
