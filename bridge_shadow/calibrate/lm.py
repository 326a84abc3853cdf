"""Projected Levenberg-Marquardt for ``min 1/2 |r(x)|^2`` under simple bounds (no ROS import).

Each iteration solves ``(J_F' J_F + lam I) d_F = -J_F' r`` on the free coordinates ``F``: those not
held at a bound by a gradient that points out of the box (a projected Newton step, Bertsekas
1982), then projects ``x + d`` back into the box. The damping follows Nielsen (1999): after an
accepted step ``lam *= max(1/3, 1 - (2 rho - 1)^3)`` with ``rho`` the actual over the predicted
reduction, after a rejected one ``lam *= nu; nu *= 2``; an accepted step that reverses the
previous one raises ``lam`` (Gauss-Newton zig-zags across a curved valley when the residual
stays large, as for a saturating stiffness). The caller works in prior-whitened
coordinates, where ``J' J >= I``, so a scalar ``lam I`` is well scaled, and a step is never longer
than ``max_step`` (a trust-region cap in prior standard deviations: where a response saturates,
e.g. a joint much stiffer than needed, the Gauss-Newton step would overshoot far).

``fun(x, jacobian)`` returns ``(r, J)``, ``J`` None when ``jacobian`` is false (one FE solve in the
calibration; a trial step needs no derivatives, an accepted one gets them from the same solve).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

__all__ = ["LMResult", "levenberg_marquardt"]


@dataclass
class LMResult:
    """Outcome of :func:`levenberg_marquardt`.

    Attributes:
        x: (n,) solution. r: residual at ``x``. J: (m, n) Jacobian at ``x``. cost: ``|r|^2 / 2``.
        active: (n,) bool, coordinates held at a bound. iterations, evaluations: counts.
        converged: a convergence test passed. message: which one (or why it stopped).
        history: cost after each accepted step.

    """

    x: np.ndarray
    r: np.ndarray
    J: np.ndarray
    cost: float
    active: np.ndarray
    iterations: int
    evaluations: int
    converged: bool
    message: str
    history: list[float] = field(default_factory=list)


def _active(x: np.ndarray, g: np.ndarray, lower: np.ndarray, upper: np.ndarray, eps: float) -> np.ndarray:
    return ((x >= upper - eps) & (g < 0)) | ((x <= lower + eps) & (g > 0))


def levenberg_marquardt(
    fun: Callable[[np.ndarray, bool], tuple[np.ndarray, np.ndarray | None]],
    x0: np.ndarray,
    lower: np.ndarray | None = None,
    upper: np.ndarray | None = None,
    *,
    max_iter: int = 60,
    gtol: float = 1e-5,
    xtol: float = 1e-4,
    ftol: float = 1e-7,
    fatol: float = 1e-5,
    lam0: float = 1e-3,
    max_step: float = 2.0,
    report: Callable[[int, float], None] | None = None,
) -> LMResult:
    """Minimize ``|r(x)|^2 / 2`` with ``lower <= x <= upper`` (see the module docstring).

    Converged when the projected gradient is below ``gtol`` (inf-norm), or an accepted step is
    below ``xtol (1 + |x|)``, or it lowers the cost by less than ``ftol cost + fatol`` (in whitened
    coordinates ``1e-4`` is a ten-thousandth of a prior sd and ``1e-5`` of the cost is nothing for
    the evidence: a zig-zag along a curved valley stops there instead of crawling on).
    """
    n = len(x0)
    lower = np.full(n, -np.inf) if lower is None else np.asarray(lower, float)
    upper = np.full(n, np.inf) if upper is None else np.asarray(upper, float)
    x = np.clip(np.asarray(x0, float), lower, upper)
    r, jac = fun(x, True)
    evals = 1
    cost = 0.5 * float(r @ r)
    lam, nu = lam0, 2.0
    history = [cost]
    eps = 1e-12
    message, converged = "maximum iterations reached", False
    prev_step: np.ndarray | None = None
    it = 0
    for it in range(1, max_iter + 1):
        g = jac.T @ r
        active = _active(x, g, lower, upper, eps)
        free = ~active
        if np.max(np.abs(g[free]), initial=0.0) < gtol:
            message, converged = "projected gradient below gtol", True
            break
        h = jac.T @ jac
        hf = h[np.ix_(free, free)]
        while True:
            d = np.zeros(n)
            d[free] = -np.linalg.solve(hf + lam * np.eye(int(free.sum())), g[free])
            norm = np.linalg.norm(d)
            if norm > max_step:
                d *= max_step / norm
            x_new = np.clip(x + d, lower, upper)
            step = x_new - x
            predicted = -(g @ step + 0.5 * step @ h @ step)
            r_new, _ = fun(x_new, False)
            evals += 1
            cost_new = 0.5 * float(r_new @ r_new)
            if cost_new < cost and predicted > 0:
                rho = (cost - cost_new) / predicted
                lam *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
                if prev_step is not None and step @ prev_step < -0.5 * np.linalg.norm(step) * np.linalg.norm(
                    prev_step
                ):
                    lam = max(lam, 1e-3) * 4.0  # the step reversed: a zig-zag across a curved valley
                nu = 2.0
                break
            lam *= nu
            nu *= 2.0
            if (
                lam > 1e16
                or np.linalg.norm(step) <= xtol * (1.0 + np.linalg.norm(x))
                or predicted <= ftol * cost + fatol
            ):
                return LMResult(x, r, jac, cost, active, it, evals, True, "no further decrease", history)
        small_step = np.linalg.norm(step) <= xtol * (1.0 + np.linalg.norm(x))
        small_drop = cost - cost_new <= ftol * cost + fatol
        x, cost, prev_step = x_new, cost_new, step
        r, jac = fun(x, True)
        history.append(cost)
        if report is not None:
            report(it, cost)
        if small_step or small_drop:
            message, converged = ("step below xtol" if small_step else "cost change below ftol"), True
            break
    g = jac.T @ r
    return LMResult(x, r, jac, cost, _active(x, g, lower, upper, eps), it, evals, converged, message, history)
