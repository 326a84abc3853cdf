"""Posterior settlements of the shadow on window means, before and after adding an effect.

Stand-in for the online pipeline (``bridge_shadow.estimate``) until its batch interface is used
here: the linear Gaussian update of DESIGN section 2 on ``m`` window means,
``Sigma' = (Sigma_X^-1 + m A^T Sigma_E^-1 A)^-1`` and
``mu' = Sigma' A^T Sigma_E^-1 sum_i (y_i - u0 - thermal_uniform dT_i)``, with the paper's prior and
noise. Windows missing a channel are skipped.
"""

from __future__ import annotations

import numpy as np

from bridge_shadow.model.surrogate_file import Surrogate

__all__ = ["PRIOR_SD_M", "SIGMA_E_N", "posterior"]

#: Prior standard deviation of each settlement, m (paper: 0.3 mm).
PRIOR_SD_M = 3.0e-4
#: Load-cell noise standard deviations [south, north], N (paper: 0.0604 kN, 0.0827 kN).
SIGMA_E_N = np.array([60.4, 82.7])


def posterior(force_n: np.ndarray, dtemp_k: np.ndarray, s: Surrogate) -> dict[str, list]:
    """Return ``{"mean_m": [south, north], "covariance_m2": 2x2, "windows": m}`` from window means."""
    ok = np.isfinite(force_n).all(axis=1)
    z = force_n[ok] - s.u0 - dtemp_k[ok, None] * s.thermal.get("uniform", np.zeros(2))
    m = int(ok.sum())
    r_inv = np.diag(1.0 / SIGMA_E_N**2)
    # Sigma' = (Sigma_X^-1 + m A' R^-1 A)^-1 ; mu' = Sigma' A' R^-1 sum z
    info = np.eye(2) / PRIOR_SD_M**2 + m * s.A.T @ r_inv @ s.A
    cov = np.linalg.inv(info)
    cov = 0.5 * (cov + cov.T)
    mean = cov @ s.A.T @ r_inv @ z.sum(axis=0)
    return {"mean_m": mean.tolist(), "covariance_m2": cov.tolist(), "windows": m}
