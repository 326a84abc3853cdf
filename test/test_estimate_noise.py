"""Noise model.

The AR(1) factor is the variance of a mean of an AR(1) run; estimates from residual moments
recover a simulated AR(1) process; the float path equals the array path.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import lfilter

from bridge_shadow.estimate.compensation.noise import NoiseModel, ar1_factor
from bridge_shadow.estimate.compensation.sums import Moments


def test_ar1_factor_is_the_variance_of_a_mean_of_an_ar1_run() -> None:
    for phi in (0.0, 0.5, 0.9, 0.99):
        for n in (1, 2, 7, 60, 1440):
            lags = np.abs(np.subtract.outer(np.arange(n), np.arange(n)))
            brute = (phi**lags).sum() / n  # n var(mean) / var(one) for a unit AR(1)
            np.testing.assert_allclose(ar1_factor(phi, n), brute, rtol=1e-10)
    np.testing.assert_allclose(ar1_factor(0.9, 1e12), 19.0, rtol=1e-9)  # (1 + phi) / (1 - phi)


def test_estimates_recover_a_simulated_ar1_sequence() -> None:
    rng = np.random.default_rng(7)
    n, phi, s = 40_000, 0.9, np.array([150.0, 220.0])
    e = rng.normal(size=(n, 2)) @ np.linalg.cholesky(np.array([[1.0, 0.4], [0.4, 1.0]])).T
    u = lfilter([np.sqrt(1 - phi**2)], [1.0, -phi], e, axis=0) * s  # stationary-scale AR(1), sd s
    mom = Moments(u.T @ u, np.sum(u[:-1] * u[1:], axis=0), n, n - 1)
    noise = NoiseModel(np.array([60.4, 82.7]))
    noise.update(mom, np.zeros(2), np.array([n]))
    np.testing.assert_allclose(noise.phi, phi, atol=0.01)
    np.testing.assert_allclose(noise.sample_sigma, s, rtol=0.05)
    np.testing.assert_allclose(noise.r1[0, 1] / np.prod(noise.sample_sigma), 0.4, atol=0.03)
    for k in (1, 5, 300):
        np.testing.assert_allclose(
            noise.run_cov(k)[[0, 0, 1], [0, 1, 1]], noise.run_cov_floats(k), rtol=1e-12
        )
    # the floor: never below the paper's Sigma_E, and fixed mode is Sigma_E itself
    quiet = NoiseModel(np.array([60.4, 82.7]))
    quiet.update(Moments(np.eye(2) * 1e-3, np.zeros(2), 100, 99), np.zeros(2), np.array([100]))
    np.testing.assert_allclose(np.diag(quiet.run_cov(1)), [60.4**2, 82.7**2])
    fixed = NoiseModel(np.array([60.4, 82.7]), adaptive=False)
    fixed.update(mom, np.zeros(2), np.array([n]))
    np.testing.assert_allclose(fixed.long_run_cov(), np.diag([60.4**2, 82.7**2]))
