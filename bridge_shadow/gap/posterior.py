"""Posterior settlements of the shadow, before and after adding the best effect to the model.

Two ways, both through ``bridge_shadow.estimate``:

- ``posterior``: the shadow's batch linear Gaussian update (``estimate.kalman.batch_posterior``,
  the paper's formula, equal to its Kalman filter with ``Q = 0``) on the 60 s window means with the
  prior and noise of ``config/shadow.yaml``: ``Sigma' = (Sigma_X^-1 + m A^T Sigma_E^-1 A)^-1``,
  ``mu' = Sigma' A^T Sigma_E^-1 sum_i (y_i - u0 - thermal_uniform dT_i)``. Fast; the default.
- ``replay_posterior``: the whole online ``Shadow`` (gate, P-spline compensation, adaptive noise,
  Kalman) replayed on the record, and on the record with the effect's fitted contribution
  subtracted from every force sample (interpolated between window centres).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from bridge_shadow.contract import CHANNELS
from bridge_shadow.model.surrogate_file import Surrogate
from bridge_shadow.series import ForceSeries, MonitoringData

__all__ = ["posterior", "replay_posterior"]


def _prior_and_noise(s: Surrogate) -> tuple[np.ndarray, np.ndarray]:
    """Prior covariance (2, 2) m^2 and window noise covariance (2, 2) N^2 from the shadow config."""
    from bridge_shadow.errors import ConfigError
    from bridge_shadow.estimate.config import ShadowConfig, load_config
    from bridge_shadow.estimate.prior import configured_prior_sigma

    try:
        cfg = load_config()
    except ConfigError:
        # The diagnosis needs only the paper's prior and noise: do not fail on a parameter file
        # written for a newer or older node; use the documented defaults instead.
        cfg = ShadowConfig()
    sigma_x = configured_prior_sigma(cfg.prior_sigma_m, cfg.prior_rule, s.A, s.u0)
    return np.diag(np.square(sigma_x)), np.diag(np.square(cfg.noise_sigma_n))


def posterior(force_n: np.ndarray, dtemp_k: np.ndarray, s: Surrogate) -> dict[str, Any]:
    """Return ``{"mean_m": [south, north], "covariance_m2": 2x2, "windows": m}`` from window means."""
    from bridge_shadow.estimate.kalman import batch_posterior

    ok = np.isfinite(force_n).all(axis=1)
    z = force_n[ok] - s.u0 - dtemp_k[ok, None] * s.thermal.get("uniform", np.zeros(2))
    sigma_x, sigma_e = _prior_and_noise(s)
    if not len(z):
        return {"mean_m": [0.0, 0.0], "covariance_m2": sigma_x.tolist(), "windows": 0}
    mean, cov = batch_posterior(s.A, sigma_x, sigma_e, z)
    return {
        "mean_m": mean.tolist(),
        "covariance_m2": (0.5 * (cov + cov.T)).tolist(),
        "windows": int(ok.sum()),
    }


def _subtract(data: MonitoringData, t_ns: np.ndarray, contribution_n: np.ndarray) -> MonitoringData:
    forces = {}
    for i, ch in enumerate(CHANNELS):
        f = data.forces[ch]
        c = np.interp(f.stamp_ns.astype(float), t_ns.astype(float), np.nan_to_num(contribution_n[:, i]))
        forces[ch] = ForceSeries(f.stamp_ns, f.force_n - c, f.frame_id, f.log_ns)
    return MonitoringData(forces, data.temperature)


def replay_posterior(
    data: MonitoringData, s: Surrogate, t_ns: np.ndarray, contribution_n: np.ndarray, min_samples: int
) -> dict[str, Any]:
    """Replay the online shadow before and after subtracting ``contribution_n`` (n, 2) N at ``t_ns``."""
    from bridge_shadow.estimate import Shadow, load_config

    cfg = load_config(overrides={"window_min_samples": int(max(1, min_samples)), "checkpoint_path": ""})
    out = {}
    for key, d in (("before", data), ("after", _subtract(data, t_ns, contribution_n))):
        r = Shadow(cfg, s).run(d)
        out[key] = {
            "mean_m": r.mean_m.tolist(),
            "covariance_m2": r.covariance_m2.tolist(),
            "updates": r.updates,
        }
    out["change_m"] = (np.array(out["after"]["mean_m"]) - np.array(out["before"]["mean_m"])).tolist()
    out["method"] = "online Shadow replay (bridge_shadow.estimate), before and after"
    return out
