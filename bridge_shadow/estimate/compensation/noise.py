"""Measurement-noise model of window means: honest ``R`` under autocorrelated residuals.

The paper's ``Sigma_E`` is a per-sample covariance; for a window mean of ``m`` i.i.d. samples it
is ``Sigma_E / m`` (``fixed`` mode). Real residuals are strongly autocorrelated, so window means
scatter far more than that and neighbouring windows repeat each other. The ``adaptive`` mode
estimates, from the residuals of the current fit (``e = y - l_s - g(T)`` of every accepted window,
computed from the sufficient statistics, never from innovations), per channel:

- the lag-1 autocorrelation ``phi_c`` of the scaled residuals ``sqrt(m) e`` of adjacent windows
  (with Kendall's first-order bias correction ``+ (1 + 3 phi) / n``), capped at ``phi_max`` and at
  the correlation time of the mean run of adjacent windows (``run_cap``);
- the per-sample-equivalent variance ``s_c^2 = sum m e^2 / dof`` with
  ``dof = n - sum_s f(n_s) - edf``: a fitted level of an AR(1) run of ``n_s`` windows takes
  ``f(n_s)`` windows' worth of residual variance (not one), and the curve ``edf``; and the
  correlation between channels.

A run of ``n`` windows of an AR(1) sequence has a mean whose variance is ``s^2 f(n) / (n m)``,

    f(n) = (1 + phi) / (1 - phi) - 2 phi (1 - phi^n) / (n (1 - phi)^2),

``f(1) = 1`` (one window) and ``f -> (1 + phi) / (1 - phi)`` (the long-run variance) for long runs.
So the covariance used for a settlement segment of ``n`` windows is ``C(n) o R1`` per sample
(Hadamard product, ``C_ij = sqrt(f_i f_j)``), divided by the samples of each window; with
``noise_floor`` its diagonal never drops below the paper's ``Sigma_E``. A window's own scatter
(for the event detector) is ``R1 / m`` (``f = 1``).
"""

from __future__ import annotations

import math

import numpy as np

from bridge_shadow.estimate.compensation.sums import Moments

__all__ = ["NoiseModel", "ar1_factor", "run_cap"]


def run_cap(n: int, n_pairs: int) -> float:
    """Largest ``phi`` the adjacent windows can show: ``1 - runs / n`` (1 for one unbroken run).

    ``phi`` is read from pairs of adjacent windows; ``n`` windows in ``runs = n - n_pairs`` runs of
    adjacent windows have a mean run of ``L = n / runs``. A correlation time ``1 / (1 - phi)``
    longer than ``L`` looks, within every run the data hold, like a constant offset of that run,
    and the bias correction of a few short runs sends the estimate to ``phi_max`` whatever the
    truth (a load-test day with its test car cut: runs of 2 to 4 windows, phi 0.999, and each
    record's level then takes all of its windows' variance). So ``phi`` is capped at the
    correlation time of the mean run, ``1 - 1 / L``; continuous monitoring (runs of hundreds of
    windows) is not affected.
    """
    runs = n - n_pairs
    return 1.0 if runs <= 0 or n <= 0 else 1.0 - runs / n


def ar1_factor(phi: np.ndarray | float, n: np.ndarray | float) -> np.ndarray:
    """``f(n)``: variance of the mean of ``n`` AR(1) terms over that of ``n`` independent ones."""
    p = np.asarray(phi, float)
    n = np.maximum(np.asarray(n, float), 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        f = (1.0 + p) / (1.0 - p) - 2.0 * p * (1.0 - p**n) / (n * (1.0 - p) ** 2)
    return np.where(p > 0.0, np.maximum(f, 1.0), 1.0)


class NoiseModel:
    """Per-sample-equivalent residual covariance ``R1`` and lag-1 autocorrelation ``phi``.

    Attributes:
        sigma_e: (2,) N, the paper's per-sample noise (``Sigma_E``; ``fixed`` mode, and the floor).
        adaptive: estimate from residuals (True) or use ``Sigma_E`` with ``phi = 0`` (False).
        phi_max: cap on ``phi``.
        floor: keep the diagonal at least ``Sigma_E``.
        r1: (2, 2) N^2, per-sample-equivalent covariance of the residuals.
        phi: (2,) lag-1 autocorrelation between adjacent windows.
        n: windows behind the estimate; dof: (2,) residual degrees of freedom ``n - S - edf``;
        dof_ar: (2,) the same with ``f(n_s)`` per level (the divisor of ``s^2``).

    """

    def __init__(
        self, sigma_e: np.ndarray, adaptive: bool = True, phi_max: float = 0.999, floor: bool = True
    ) -> None:
        self.sigma_e = np.asarray(sigma_e, float).reshape(2)
        self.adaptive = adaptive
        self.phi_max = float(phi_max)
        self.floor = floor
        self.r1 = np.diag(self.sigma_e**2)
        self.phi = np.zeros(2)
        self.n = 0
        self.dof = np.zeros(2)
        self.dof_ar = np.zeros(2)
        #: (2,) N^2: the residuals' per-sample-equivalent variance ``sum m e^2 / dof`` as i.i.d.
        #: samples would show it (NaN until a fit): measured in both modes, so that ``fixed``
        #: mode can say when its ``Sigma_E`` does not hold (``report.fixed_noise_lines``)
        self.scatter = np.full(2, np.nan)
        self._cache()

    def update(self, moments: Moments, edf: np.ndarray, segment_windows: np.ndarray) -> None:
        """Re-estimate from the residual moments of the current fit (``adaptive`` mode only).

        ``edf`` (2,) is the curve's effective degrees of freedom and ``segment_windows`` the window
        count of each segment (each segment's level was fitted too).
        """
        self.n = moments.n
        sizes = np.asarray(segment_windows, float)
        sizes = sizes[sizes > 0]
        self.dof = np.maximum(moments.n - len(sizes) - np.asarray(edf, float).reshape(2), 1.0)
        if moments.n >= 3:
            self.scatter = np.maximum(np.diag(moments.s2), 0.0) / self.dof
        if not self.adaptive or moments.n < 3:
            return
        self._update(moments, sizes, np.asarray(edf, float).reshape(2))
        self._cache()

    def _update(self, moments: Moments, sizes: np.ndarray, edf: np.ndarray) -> None:
        if moments.n_pairs >= 2:
            mean_sq = np.maximum(np.diag(moments.s2) / moments.n, 1e-300)
            phi = (moments.lag / moments.n_pairs) / mean_sq
            phi = phi + (1.0 + 3.0 * phi) / moments.n_pairs  # Kendall's first-order bias
            self.phi = np.clip(phi, 0.0, min(self.phi_max, run_cap(moments.n, moments.n_pairs)))
        else:
            self.phi = np.zeros(2)
        # E[sum (e - mean)^2] = s^2 (n - f(n)) for an AR(1) run of n windows: each fitted level
        # takes f(n_s) windows' worth of variance, not one (short autocorrelated records would
        # otherwise look far quieter than they are)
        taken = np.array([float(np.sum(ar1_factor(p, sizes))) for p in self.phi])
        self.dof_ar = np.maximum(moments.n - taken - edf, 1.0)
        var = np.maximum(np.diag(moments.s2) / self.dof_ar, 0.0)
        if self.floor:
            var = np.maximum(var, self.sigma_e**2)
        sd = np.sqrt(var)
        denom = np.sqrt(max(moments.s2[0, 0], 0.0) * max(moments.s2[1, 1], 0.0))
        rho = float(np.clip(moments.s2[0, 1] / denom, -0.999, 0.999)) if denom > 0 else 0.0
        self.r1 = np.array([[var[0], rho * sd[0] * sd[1]], [rho * sd[0] * sd[1], var[1]]])

    def factors(self, n_windows: float) -> np.ndarray:
        """(2, 2) ``C(n)``: the AR(1) variance factor of a run of ``n`` windows, per channel pair."""
        f = ar1_factor(self.phi, n_windows)
        return np.sqrt(np.outer(f, f))

    def run_cov(self, n_windows: float) -> np.ndarray:
        """(2, 2) N^2 per sample: ``C(n) o R1`` (diagonal floored at ``Sigma_E``)."""
        cov = self.factors(n_windows) * self.r1
        if self.floor:
            d = np.maximum(np.diag(cov), self.sigma_e**2)
            scale = np.sqrt(d / np.maximum(np.diag(cov), 1e-300))
            cov = cov * np.outer(scale, scale)
        return cov

    def run_cov_floats(self, n_windows: int) -> tuple[float, float, float]:
        """``run_cov(n)`` as ``(c00, c01, c11)`` plain floats (the per-window hot path)."""
        f = []
        for p in self._phi_f:
            if p > 0.0:
                v = (1.0 + p) / (1.0 - p) - 2.0 * p * (1.0 - p**n_windows) / (n_windows * (1.0 - p) ** 2)
                f.append(max(v, 1.0))
            else:
                f.append(1.0)
        r00, r01, r11 = self._r1_f
        c00, c11 = f[0] * r00, f[1] * r11
        c01 = math.sqrt(f[0] * f[1]) * r01
        if self.floor:
            s0, s1 = self._se2_f
            g0 = math.sqrt(s0 / c00) if c00 < s0 else 1.0
            g1 = math.sqrt(s1 / c11) if c11 < s1 else 1.0
            c00, c01, c11 = c00 * g0 * g0, c01 * g0 * g1, c11 * g1 * g1
        return (c00, c01, c11)

    def window_floats(self, m0: float, m1: float) -> tuple[float, float, float]:
        """``window_cov`` as ``(a, b, d)`` plain floats."""
        r00, r01, r11 = self._r1_f
        return (r00 / m0, r01 / math.sqrt(m0 * m1), r11 / m1)

    def _cache(self) -> None:
        self._r1_f = (float(self.r1[0, 0]), float(self.r1[0, 1]), float(self.r1[1, 1]))
        self._phi_f = (float(self.phi[0]), float(self.phi[1]))
        self._se2_f = (float(self.sigma_e[0] ** 2), float(self.sigma_e[1] ** 2))

    def long_run_cov(self) -> np.ndarray:
        """(2, 2) N^2 per sample: ``R1`` with the long-run AR(1) factor ``(1 + phi) / (1 - phi)``."""
        return self.run_cov(1e12)

    def window_cov(self, samples: np.ndarray) -> np.ndarray:
        """(2, 2) N^2: scatter of one window mean over ``samples`` (2,) (no AR factor)."""
        s = np.sqrt(np.asarray(samples, float).reshape(2))
        return self.r1 / np.outer(s, s)

    @property
    def sample_sigma(self) -> np.ndarray:
        """(2,) N, per-sample-equivalent residual standard deviation."""
        return np.sqrt(np.diag(self.r1))

    def state_dict(self) -> dict[str, object]:
        """Plain-data state."""
        return {
            "r1": self.r1.copy(),
            "phi": self.phi.copy(),
            "n": self.n,
            "dof": self.dof.copy(),
            "dof_ar": self.dof_ar.copy(),
            "scatter": self.scatter.copy(),
        }

    def load_state_dict(self, state: dict[str, object]) -> None:
        """Restore the estimate."""
        self.r1 = np.asarray(state["r1"], float).reshape(2, 2)
        self.phi = np.asarray(state["phi"], float).reshape(2)
        self.n = int(state["n"])  # type: ignore[call-overload]
        self.dof = np.asarray(state["dof"], float).reshape(2)
        self.dof_ar = np.asarray(state["dof_ar"], float).reshape(2)
        # a checkpoint written before the field: unknown until the next fit
        self.scatter = np.asarray(state.get("scatter", (np.nan, np.nan)), float).reshape(2)
        self._cache()
