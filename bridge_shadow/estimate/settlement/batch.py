"""The paper's batch method on a whole record, written directly (dense matrices, no running sums).

Bonari et al. aggregate to 60 s means, fit one smoothing spline of force on air temperature over the
record, compensate ``y - g(T) + ybar`` and apply the closed-form linear-Gaussian posterior. This
module does exactly that on the window means of a record, as an independent reference for the
online ``Shadow`` (which keeps sufficient statistics, refits on a schedule and runs a chain of
segments): at the end of a record without events, the two agree to rounding.

The choices the online shadow makes are made here too, so that the comparison is exact:

- the spline is weighted by the samples ``m`` of each window mean, with the same knots, curvature
  penalty ``lambda`` and slope prior ``kappa int (g' - s_FE)^2`` (``lambda`` and ``kappa`` are
  inputs: the REML search itself is checked against the dense criterion elsewhere);
- ``g`` is centred, ``sum m g(T) = 0``, so ``y - g(T)`` has the mean ``ybar`` (the paper's level);
- the noise covariance is the shadow's ``adaptive`` model from the residuals ``y - ybar - g(T)``:
  per-sample variance ``sum m e^2 / (n - f(n) - edf)``, the channels' correlation, lag-1
  autocorrelation of ``sqrt(m) e`` with Kendall's correction, and ``R_w = C(n) o R1 / sqrt(m m')``
  (``noise.py``); or, ``fixed``, the paper's ``Sigma_E / m``;
- the prior is ``N(0, Sigma_X)``; ``Sigma' = (Sigma_X^-1 + sum_w A' R_w^-1 A)^-1``,
  ``mu' = Sigma' sum_w A' R_w^-1 (y_w - g(T_w) - u0)``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from bridge_shadow.estimate.compensation.noise import ar1_factor
from bridge_shadow.estimate.compensation.spline import _basis, clamped_knots, gram_penalty, gram_slope

__all__ = ["BatchResult", "paper_batch", "paper_batch_of_run"]


@dataclass
class BatchResult:
    """The batch method's answer.

    Attributes:
        mean_m: (2,) m; covariance_m2: (2, 2) m^2 (the posterior).
        beta: (2, q) N, the centred spline; level_n: (2,) N, ``ybar``.
        r1: (2, 2) N^2 per sample, the residual covariance; phi: (2,) lag-1 autocorrelation.
        edf: (2,) the spline's effective degrees of freedom.

    """

    mean_m: np.ndarray
    covariance_m2: np.ndarray
    beta: np.ndarray
    level_n: np.ndarray
    r1: np.ndarray
    phi: np.ndarray
    edf: np.ndarray


def paper_batch(
    k: np.ndarray,
    samples: np.ndarray,
    force_n: np.ndarray,
    temp_c: np.ndarray,
    A: np.ndarray,
    u0: np.ndarray,
    prior_cov: np.ndarray,
    *,
    lam: np.ndarray,
    kappa: np.ndarray,
    slope_fe: np.ndarray,
    t_min_c: float = -20.0,
    t_max_c: float = 45.0,
    segments: int = 13,
    sigma_e: np.ndarray | None = None,
    adaptive: bool = True,
    phi_max: float = 0.999,
    floor: bool = True,
) -> BatchResult:
    """Return the batch posterior of a record of ``n`` window means.

    Args:
        k: (n,) window indices (adjacent windows differ by one).
        samples: (n, 2) samples per window mean; force_n: (n, 2) N; temp_c: (n, 2) C.
        A: (2, 2) N/m; u0: (2,) N; prior_cov: (2, 2) m^2.
        lam: (2,) curvature penalties; kappa: (2,) K, slope-prior weights; slope_fe: (2,) N/K.
        t_min_c, t_max_c, segments: the knots (as ``config/shadow.yaml``).
        sigma_e: (2,) N, the paper's per-sample noise (``fixed`` mode and floor).
        adaptive, phi_max, floor: the noise model's settings.

    """
    k = np.asarray(k, np.int64)
    m = np.asarray(samples, float)
    y = np.asarray(force_n, float)
    t = np.asarray(temp_c, float)
    n = len(k)
    knots = clamped_knots(np.linspace(t_min_c, t_max_c, segments + 1))
    q = len(knots) - 4
    omega, omega1 = gram_penalty(knots), gram_slope(knots)
    e_vec = np.zeros(q)
    e_vec[0], e_vec[-1] = -1.0, 1.0
    sigma_e = np.array([60.4, 82.7]) if sigma_e is None else np.asarray(sigma_e, float)
    beta = np.zeros((2, q))
    level = np.zeros(2)
    edf = np.zeros(2)
    resid = np.zeros((n, 2))
    for c in range(2):
        B = _basis(knots, np.clip(t[:, c], t_min_c, t_max_c))  # (n, q)
        w = m[:, c]
        # unknowns [level, beta]: min sum w (y - l - B beta)^2 + lam b'Omega b + kappa int (g' - s)^2
        # subject to sum w B beta = 0 (centred curve), by the KKT system
        X = np.column_stack([np.ones(n), B])
        H = X.T @ (w[:, None] * X)
        H[1:, 1:] += lam[c] * omega + kappa[c] * omega1
        rhs = X.T @ (w * y[:, c])
        rhs[1:] += kappa[c] * slope_fe[c] * e_vec
        con = np.concatenate([[0.0], B.T @ w])
        kkt = np.block([[H, con[:, None]], [con[None, :], np.zeros((1, 1))]])
        sol = np.linalg.lstsq(kkt, np.concatenate([rhs, [0.0]]), rcond=None)[0]
        level[c], beta[c] = sol[0], sol[1 : q + 1]
        resid[:, c] = y[:, c] - level[c] - B @ beta[c]
        # edf of the curve: trace of its hat matrix on the within (level-removed) data
        Bc = B - (w @ B) / w.sum()
        pen = Bc.T @ (w[:, None] * Bc) + lam[c] * omega + kappa[c] * omega1
        edf[c] = float(np.trace(np.linalg.lstsq(pen, Bc.T @ (w[:, None] * Bc), rcond=None)[0]))
    # noise model (noise.py, written out)
    u = np.sqrt(m) * resid  # per-sample-equivalent residuals
    if adaptive and n >= 3:
        adjacent = np.flatnonzero(np.diff(k) == 1)
        n_pairs = len(adjacent)
        phi = np.zeros(2)
        if n_pairs >= 2:
            lag = np.sum(u[adjacent] * u[adjacent + 1], axis=0)
            phi = (lag / n_pairs) / (np.sum(u * u, axis=0) / n)
            phi = np.clip(phi + (1.0 + 3.0 * phi) / n_pairs, 0.0, phi_max)
        dof = np.maximum(n - ar1_factor(phi, n) - edf, 1.0)
        s2 = np.sum(u * u, axis=0) / dof
        if floor:
            s2 = np.maximum(s2, sigma_e**2)
        rho = np.sum(u[:, 0] * u[:, 1]) / np.sqrt(np.sum(u[:, 0] ** 2) * np.sum(u[:, 1] ** 2))
        rho = float(np.clip(rho, -0.999, 0.999))
        sd = np.sqrt(s2)
        r1 = np.array([[s2[0], rho * sd[0] * sd[1]], [rho * sd[0] * sd[1], s2[1]]])
        f = ar1_factor(phi, n)
        run = np.sqrt(np.outer(f, f)) * r1
        if floor:
            d = np.maximum(np.diag(run), sigma_e**2)
            scale = np.sqrt(d / np.diag(run))
            run = run * np.outer(scale, scale)
    else:
        phi = np.zeros(2)
        r1 = run = np.diag(sigma_e**2)
    # closed-form posterior with R_w = S_w^-1 run S_w^-1, S_w = diag(sqrt(m_w))
    A = np.asarray(A, float)
    g = np.column_stack([_g(knots, t[:, c], beta[c], t_min_c, t_max_c) for c in range(2)])
    z = y - g - np.asarray(u0, float)  # compensated y - g(T) + ybar, minus u0 (g is centred)
    info = np.linalg.inv(np.asarray(prior_cov, float))
    eta = np.zeros(2)
    run_inv = np.linalg.inv(run)
    for i in range(n):
        s = np.sqrt(m[i])
        r_inv = run_inv * np.outer(s, s)  # R_w^-1
        info += A.T @ r_inv @ A
        eta += A.T @ r_inv @ z[i]
    cov = np.linalg.inv(info)
    cov = 0.5 * (cov + cov.T)
    return BatchResult(cov @ eta, cov, beta, level, r1, phi, edf)


def paper_batch_of_run(shadow: Any, result: Any) -> BatchResult:
    """Run the paper's batch method on the windows a ``Shadow`` run used, with its lambda and prior.

    The reference the online posterior is compared with (``result`` is the run's ``ReplayResult``).
    """
    h = result.history()
    used = h["updated"]
    sur = shadow.surrogate
    return paper_batch(
        h["end_ns"][used] // round(shadow.config.window_s * 1e9) - 1,
        h["samples"][used],
        h["force_n"][used],
        h["temp_c"][used],
        sur.A,
        sur.u0,
        np.diag(shadow.prior_sigma_m**2),
        lam=shadow.fit.lam,
        kappa=shadow.fit.kappa,
        slope_fe=sur.thermal.get("uniform", np.zeros(2)),
    )


def _g(knots: np.ndarray, t: np.ndarray, beta: np.ndarray, lo: float, hi: float) -> np.ndarray:
    return _basis(knots, np.clip(t, lo, hi)) @ beta
