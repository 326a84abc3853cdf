"""Kalman update of the two central-support settlements, over filterpy 2.0.0.

State ``x = [south, north]`` settlement in m (positive upward), ``F = I``, process noise ``Q``
(random walk, m^2 per s of stamp time), measurement ``z = compensated reactions - u0`` in N,
``H = A`` (N/m), ``R`` in N^2. Shapes are fixed at this boundary: ``x`` (2,), ``P`` (2, 2),
``z`` (2,). filterpy 2.0.0 turns ``x`` into a 2x2 array when ``update`` gets a 1-D ``z``
(DESIGN section 7), so the wrapper always passes ``z`` as a (2, 1) column, checks it for NaN/inf
before updating (filterpy would propagate a NaN for ever) and symmetrizes ``P``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from filterpy.kalman import KalmanFilter
from scipy import stats

__all__ = ["SettlementFilter", "UpdateResult", "batch_posterior"]


@dataclass
class UpdateResult:
    """Outcome of one measurement update.

    Attributes:
        accepted: False when the measurement was gated out (non-finite or Mahalanobis outlier).
        reason: ``""`` if accepted, else ``nonfinite`` or ``outlier``.
        mahalanobis2: squared Mahalanobis distance of the innovation (NaN if not computed).

    """

    accepted: bool
    reason: str = ""
    mahalanobis2: float = float("nan")


class SettlementFilter:
    """Linear Gaussian filter for ``z = A x + e`` with ``F = I`` (filterpy underneath).

    Attributes:
        kf: the filterpy ``KalmanFilter`` (x as a (2, 1) column inside).
        A: (2, 2) N/m measurement matrix.
        q_rate: (2,) m^2/s random-walk intensity (``Q = diag(q_rate) dt``).
        gate2: chi-square threshold on the squared Mahalanobis distance (inf = no gate).
        n_updates: accepted updates so far.

    """

    def __init__(
        self,
        A: np.ndarray,
        prior_sigma_m: np.ndarray,
        q_rate: np.ndarray | None = None,
        gate_probability: float = 1.0,
    ) -> None:
        self.A = np.asarray(A, dtype=float).reshape(2, 2)
        self.q_rate = np.zeros(2) if q_rate is None else np.asarray(q_rate, dtype=float).reshape(2)
        self.gate2 = float("inf") if gate_probability >= 1.0 else float(stats.chi2.ppf(gate_probability, 2))
        self.kf = KalmanFilter(dim_x=2, dim_z=2)
        self.kf.F = np.eye(2)
        self.kf.H = self.A.copy()
        self.kf.x = np.zeros((2, 1))
        self.kf.P = np.diag(np.asarray(prior_sigma_m, dtype=float).reshape(2) ** 2)
        self.n_updates = 0

    @property
    def x(self) -> np.ndarray:
        """Posterior mean (2,) in m."""
        return self.kf.x[:, 0].copy()

    @property
    def P(self) -> np.ndarray:
        """Posterior covariance (2, 2) in m^2."""
        return self.kf.P.copy()

    def predict(self, dt_s: float) -> None:
        """Propagate over ``dt_s`` seconds: ``x = F x``, ``P = F P F' + Q`` (no-op if Q = 0)."""
        if dt_s <= 0 or not np.any(self.q_rate > 0):
            return
        self.kf.predict(Q=np.diag(self.q_rate * dt_s))
        self.kf.P = 0.5 * (self.kf.P + self.kf.P.T)

    def mahalanobis2(self, z: np.ndarray, R: np.ndarray) -> float:
        """Squared Mahalanobis distance of the innovation ``y = z - H x`` under ``S = H P H' + R``."""
        y = np.asarray(z, float).reshape(2) - self.A @ self.x
        S = self.A @ self.kf.P @ self.A.T + R
        return float(y @ np.linalg.solve(S, y))

    def update(self, z: np.ndarray, R: np.ndarray, gate: bool = True) -> UpdateResult:
        """Update with ``z`` (2,) N and ``R`` (2, 2) N^2; gate NaN/inf and outliers first."""
        z = np.asarray(z, dtype=float).reshape(2)
        R = np.asarray(R, dtype=float).reshape(2, 2)
        if not (np.all(np.isfinite(z)) and np.all(np.isfinite(R))):
            return UpdateResult(False, "nonfinite")
        d2 = float("nan")
        if gate and np.isfinite(self.gate2):
            d2 = self.mahalanobis2(z, R)
            if not np.isfinite(d2):
                return UpdateResult(False, "nonfinite")
            if d2 > self.gate2:
                return UpdateResult(False, "outlier", d2)
        # y = z - Hx; S = HPH' + R; K = PH'inv(S); x = x + Ky; P = (I-KH)P(I-KH)' + KRK' (Joseph)
        self.kf.update(z.reshape(2, 1), R=R, H=self.A)
        self.kf.P = 0.5 * (self.kf.P + self.kf.P.T)
        self.n_updates += 1
        return UpdateResult(True, "", d2)

    def state_dict(self) -> dict[str, object]:
        """Plain-data filter state."""
        return {"x": self.x, "P": self.P, "n_updates": self.n_updates}

    def load_state_dict(self, state: dict[str, object]) -> None:
        """Restore ``x``, ``P`` and the update count."""
        self.kf.x = np.asarray(state["x"], dtype=float).reshape(2, 1).copy()
        self.kf.P = np.asarray(state["P"], dtype=float).reshape(2, 2).copy()
        self.n_updates = int(state["n_updates"])  # type: ignore[call-overload]


def batch_posterior(
    A: np.ndarray, sigma_x: np.ndarray, sigma_e: np.ndarray, residuals: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Paper's batch posterior (prior mean 0) for samples ``residuals = y_i - u0``, (m, 2) N.

    ``Sigma' = (Sigma_X^-1 + m A' Sigma_E^-1 A)^-1``, ``mu' = Sigma' A' Sigma_E^-1 sum_i (y_i - u0)``.
    ``sigma_x`` (2, 2) m^2 and ``sigma_e`` (2, 2) N^2 are covariances.
    """
    A = np.asarray(A, float)
    res = np.atleast_2d(np.asarray(residuals, float))
    se_inv = np.linalg.inv(sigma_e)
    cov = np.linalg.inv(np.linalg.inv(sigma_x) + len(res) * A.T @ se_inv @ A)
    mean = cov @ A.T @ se_inv @ res.sum(axis=0)
    return mean, cov
