"""Measurement-noise model of window means: honest ``R`` under autocorrelated residuals.

The paper's ``Sigma_E`` is a per-sample covariance; for a window mean of ``m`` i.i.d. samples it
is ``Sigma_E / m`` (``fixed`` mode). Real residuals are strongly autocorrelated, so the window
means scatter far more than that. The ``adaptive`` mode estimates online, per channel, the
second moments of the scaled window residuals ``e_w sqrt(m_w)`` and their lag-1
autocorrelation ``phi`` between adjacent windows, and uses

    R_w = D C D / sqrt(m_i m_j),  D = diag(sqrt(s_ii (1 + phi_i) / (1 - phi_i)))

with ``C`` the residual correlation between channels: the long-run variance of an AR(1) mean,
so that a run of ``N`` windows carries ``N (1 - phi) / (1 + phi)`` windows' worth of
information. With ``noise_floor`` the diagonal never drops below the paper's ``Sigma_E / m``.

The residuals ``e_w`` come from the shadow: leave-one-out residuals of the spline fit for the
warm-up windows, then the innovation ``z_w - A x`` of each kept window (so a settlement change
that the filter tracks with ``Q > 0`` does not count as noise).
"""

from __future__ import annotations

import numpy as np

__all__ = ["WindowNoise"]


class WindowNoise:
    """Online second moments and lag-1 autocorrelation of scaled window residuals.

    Attributes:
        sigma_e: (2,) N, per-sample noise standard deviation (the paper's ``Sigma_E``).
        adaptive: estimate from residuals (True) or use ``Sigma_E / m`` (False).
        phi_max: cap on the estimated autocorrelation.
        floor: keep the diagonal of R at least ``Sigma_E / m``.
        n: residual windows seen; S2: (2, 2) sum of e e'; n_pairs, S1: (2,) lag-1 products sum
            over adjacent windows; S0: (2,) sum of e_{w-1}^2 over those pairs; last: previous
            scaled residual and its window index.

    """

    def __init__(
        self, sigma_e: np.ndarray, adaptive: bool = True, phi_max: float = 0.99, floor: bool = True
    ) -> None:
        self.sigma_e = np.asarray(sigma_e, dtype=float).reshape(2)
        self.adaptive = adaptive
        self.phi_max = float(phi_max)
        self.floor = floor
        self.n = 0
        self.S2 = np.zeros((2, 2))
        self.S1 = np.zeros(2)
        self.S0 = np.zeros(2)
        self.n_pairs = 0
        self.last = np.full(2, np.nan)
        self.last_index = -(2**62)

    def add(self, residual_n: np.ndarray, samples: np.ndarray, window_index: int) -> None:
        """Add one window's residual (2,) N of means over ``samples`` (2,) samples."""
        e = np.asarray(residual_n, float).reshape(2) * np.sqrt(np.asarray(samples, float).reshape(2))
        self.S2 += np.outer(e, e)
        self.n += 1
        if window_index == self.last_index + 1:
            self.S1 += e * self.last
            self.S0 += self.last * self.last
            self.n_pairs += 1
        self.last = e
        self.last_index = int(window_index)

    @property
    def phi(self) -> np.ndarray:
        """Lag-1 autocorrelation per channel, clipped to ``[0, phi_max]`` (0 before two pairs)."""
        if self.n_pairs < 2:
            return np.zeros(2)
        with np.errstate(divide="ignore", invalid="ignore"):
            phi = np.where(self.S0 > 0, self.S1 / self.S0, 0.0)
        # first-order bias correction of the lag-1 estimator (Kendall): E[phi^] ~ phi - (1 + 3 phi) / n
        phi = phi + (1.0 + 3.0 * phi) / self.n_pairs
        return np.clip(phi, 0.0, self.phi_max)

    def sample_cov(self) -> np.ndarray:
        """(2, 2) N^2: per-sample-equivalent covariance of the residuals (``Sigma_E`` if unknown)."""
        if not self.adaptive or self.n < 2:
            return np.diag(self.sigma_e**2)
        return self.S2 / self.n

    def R(self, samples: np.ndarray) -> np.ndarray:
        """Measurement covariance (2, 2) N^2 of a window mean over ``samples`` (2,)."""
        m = np.asarray(samples, float).reshape(2)
        paper = self.sigma_e**2 / m
        if not self.adaptive or self.n < 2:
            return np.diag(paper)
        cov = self.sample_cov()
        phi = self.phi
        var = np.diag(cov) * (1.0 + phi) / (1.0 - phi) / m
        if self.floor:
            var = np.maximum(var, paper)
        sd = np.sqrt(var)
        denom = np.sqrt(cov[0, 0] * cov[1, 1])
        rho = float(np.clip(cov[0, 1] / denom, -0.999, 0.999)) if denom > 0 else 0.0
        return np.array([[var[0], rho * sd[0] * sd[1]], [rho * sd[0] * sd[1], var[1]]])

    def state_dict(self) -> dict[str, object]:
        """Plain-data state."""
        return {
            "n": self.n,
            "S2": self.S2.copy(),
            "S1": self.S1.copy(),
            "S0": self.S0.copy(),
            "n_pairs": self.n_pairs,
            "last": self.last.copy(),
            "last_index": self.last_index,
        }

    def load_state_dict(self, state: dict[str, object]) -> None:
        """Restore the sums."""
        self.n = int(state["n"])  # type: ignore[call-overload]
        self.S2 = np.array(state["S2"], float).reshape(2, 2)
        self.S1 = np.array(state["S1"], float).reshape(2)
        self.S0 = np.array(state["S0"], float).reshape(2)
        self.n_pairs = int(state["n_pairs"])  # type: ignore[call-overload]
        self.last = np.array(state["last"], float).reshape(2)
        self.last_index = int(state["last_index"])  # type: ignore[call-overload]
