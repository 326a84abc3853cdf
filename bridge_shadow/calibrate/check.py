"""Score a surrogate on record pairs with a known imposed settlement, without calibrating.

For each pair the measured reaction change ``dR`` (car-free levels, the shadow's noise model, the
baseline change between the records: ``change.measured_change``) is read through the surrogate:
``x = A^-1 dR``, with covariance ``A^-1 C_dR A^-T`` (the measurement) plus the surrogate's own
model uncertainty of a change (``Surrogate.model_covariance(x, with_u0=False)``; u0 cancels in a
change). Against the imposed settlement (and the jacks' uncertainty ``imposed_sd_m``) it reports
the error per support and in the common mode, whether each 95 % interval holds the imposed value,
and the chi-square distance of the whole error. This is the held-out check of a calibrated model:
list a later record pair (for example a further lowering) and check the surrogate in use on it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from bridge_shadow.calibrate.change import MeasuredChange
from bridge_shadow.estimate.result import CHI2_2DOF_95
from bridge_shadow.model.surrogate_file import Surrogate

__all__ = ["PairCheck", "check_pair", "check_text"]

#: 95 % quantile of the standard normal (two-sided).
Z95 = 1.959963984540054
_COMMON = np.array([0.5, 0.5])


@dataclass
class PairCheck:
    """A surrogate's reading of one pair. SI units (m, m^2).

    Attributes:
        name: the pair. x_m: (2,) ``A^-1 dR``. cov_m2: (2, 2) its covariance (measurement and
            model). measurement_cov_m2, model_cov_m2: the two parts. imposed_m, imposed_sd_m: (2,).
        sun: with ``baseline_change: sun``, the sun's part of the baseline change
            (``MeasuredChange.sun``), else None.

    """

    name: str
    x_m: np.ndarray
    cov_m2: np.ndarray
    measurement_cov_m2: np.ndarray
    model_cov_m2: np.ndarray
    imposed_m: np.ndarray
    imposed_sd_m: np.ndarray
    sun: dict[str, Any] | None = None

    @property
    def sd_m(self) -> np.ndarray:
        """(2,) m, standard deviation of each support's reading."""
        return np.sqrt(np.diag(self.cov_m2))

    @property
    def common_m(self) -> float:
        """Mean of the two supports' readings."""
        return float(_COMMON @ self.x_m)

    @property
    def common_sd_m(self) -> float:
        """Standard deviation of ``common_m``."""
        return float(np.sqrt(_COMMON @ self.cov_m2 @ _COMMON))

    @property
    def common_error_rel(self) -> float:
        """(common reading - common imposed) / common imposed (NaN when nothing was imposed)."""
        imposed = float(_COMMON @ self.imposed_m)
        return (self.common_m - imposed) / imposed if imposed else float("nan")

    @property
    def chi2(self) -> float:
        """Squared Mahalanobis distance of ``x - imposed`` (both uncertainties); chi-square, 2 dof."""
        err = self.x_m - self.imposed_m
        return float(err @ np.linalg.solve(self.cov_m2 + np.diag(self.imposed_sd_m**2), err))

    def held(self) -> list[bool]:
        """Per support: True when the 95 % interval (with the jacks' uncertainty) holds the imposed value."""
        sd = np.sqrt(self.sd_m**2 + self.imposed_sd_m**2)
        return [bool(v) for v in np.abs(self.x_m - self.imposed_m) <= Z95 * sd]

    def to_dict(self) -> dict[str, Any]:
        """Plain data (SI)."""
        return {
            "pair": self.name,
            "x_m": self.x_m.tolist(),
            "sigma_m": self.sd_m.tolist(),
            "covariance_m2": self.cov_m2.tolist(),
            "measurement_sigma_m": np.sqrt(np.diag(self.measurement_cov_m2)).tolist(),
            "model_sigma_m": np.sqrt(np.diag(self.model_cov_m2)).tolist(),
            "imposed_m": self.imposed_m.tolist(),
            "imposed_sd_m": self.imposed_sd_m.tolist(),
            "common_m": self.common_m,
            "common_sigma_m": self.common_sd_m,
            "common_error_rel": self.common_error_rel,
            "held95": self.held(),
            "chi2": self.chi2,
            "consistent95": bool(self.chi2 <= CHI2_2DOF_95),
            "sun": self.sun,
        }


def check_pair(
    name: str, change: MeasuredChange, surrogate: Surrogate, imposed_m: np.ndarray, imposed_sd_m: np.ndarray
) -> PairCheck:
    """Read one pair's measured change through ``surrogate`` (see the module docstring)."""
    a_inv = np.linalg.inv(surrogate.A)
    x = a_inv @ change.dR_n
    measurement = a_inv @ change.cov_n2 @ a_inv.T
    model = surrogate.model_covariance(x, with_u0=False)
    cov = measurement + model
    return PairCheck(
        name,
        x,
        0.5 * (cov + cov.T),
        measurement,
        model,
        np.asarray(imposed_m, float).reshape(2),
        np.asarray(imposed_sd_m, float).reshape(2),
        change.sun,
    )


def check_text(checks: list[PairCheck], surrogate_name: str) -> str:
    """Human summary in mm: one block per pair."""
    mm = 1e3
    lines = [f"surrogate {surrogate_name}, {len(checks)} pair(s): x = A^-1 dR against the imposed settlement"]
    for c in checks:
        lines.append(f"  {c.name}:")
        model_sd = np.sqrt(np.diag(c.model_cov_m2))
        model_part = [
            f"model part {Z95 * v * mm:.2f}"
            if np.any(model_sd > 0)
            else "the surrogate carries no model uncertainty"
            for v in model_sd
        ]
        for k, side in enumerate(("south", "north")):
            lines.append(
                f"    {side}  {c.x_m[k] * mm:+8.2f} mm ± {Z95 * c.sd_m[k] * mm:.2f} (95 %; {model_part[k]}), "
                f"imposed {c.imposed_m[k] * mm:+.2f} "
                f"± {Z95 * c.imposed_sd_m[k] * mm:.2f}: {'holds' if c.held()[k] else 'MISSES'}"
            )
        if c.sun is not None:
            mean_k, sd_k = c.sun["sun_change_k"]
            before, after = c.sun["exposure"]
            lines.append(
                f"    the sun, by its prior (not measured): the deck's vertical difference changes by "
                f"{mean_k:+.2f} ± {Z95 * sd_k:.2f} K (95 %) between the records (sun x clearness "
                f"{before:.2f} -> {after:.2f}; prior at full sun {c.sun['g_prior_k'][0]:g} ± "
                f"{c.sun['g_prior_k'][1]:g} K, g >= 0): that expectation subtracted, its spread in the "
                "interval"
            )
        lines.append(
            f"    common {c.common_m * mm:+8.2f} mm ± {Z95 * c.common_sd_m * mm:.2f}, "
            f"error {100 * c.common_error_rel:+.1f} %; chi-square {c.chi2:.2f} (2 dof, 95 % limit "
            f"{CHI2_2DOF_95:.2f}): {'consistent' if c.chi2 <= CHI2_2DOF_95 else 'NOT consistent'}"
        )
    return "\n".join(lines)
