"""Which parameter combinations the data fix: SVD of the prior-whitened, noise-weighted Jacobian.

With whitened coordinates (prior ``N(0, I)``) and the data rows ``J_D = L^-1 d(model)/du`` of the
Jacobian, ``J_D = U S V'``: along the right singular vector ``v_i`` the posterior sd is the prior
sd times ``1 / sqrt(1 + s_i^2)``. A direction with ``s_i >> 1`` is fixed by the data, one with
``s_i << 1`` stays at the prior. There are at most as many such directions as measured numbers:
one pair of records gives two.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = ["identifiability"]


def identifiability(
    j_data: np.ndarray, labels: Sequence[str], cov: np.ndarray | None = None, loading: float = 0.15
) -> dict[str, Any]:
    """Report of the data-informed directions (see the module docstring).

    Args:
        j_data: (n_data, n) whitened data Jacobian. labels: (n,) coordinate names.
        cov: (n, n) posterior covariance in whitened coordinates (for per-coordinate ratios).
        loading: smallest |component| of a singular vector listed in its combination.

    Returns:
        ``{"data_numbers", "directions": [{"singular_value", "posterior_to_prior_sd",
        "combination": {label: component}}], "posterior_to_prior_sd": {label: ratio},
        "summary"}``.

    """
    _, s, vt = np.linalg.svd(np.atleast_2d(j_data), full_matrices=False)
    directions = []
    for si, v in zip(s, vt, strict=True):
        v = v * np.sign(v[np.argmax(np.abs(v))])
        order = np.argsort(-np.abs(v))
        combo = {labels[i]: round(float(v[i]), 3) for i in order if abs(v[i]) >= loading}
        directions.append(
            {
                "singular_value": float(si),
                "posterior_to_prior_sd": float(1.0 / np.sqrt(1.0 + si**2)),
                "combination": combo,
            }
        )
    out: dict[str, Any] = {"data_numbers": int(j_data.shape[0]), "directions": directions}
    if cov is not None:
        out["posterior_to_prior_sd"] = {lab: float(np.sqrt(cov[i, i])) for i, lab in enumerate(labels)}
    fixed = sum(1 for d in directions if d["singular_value"] > 1.0)
    out["summary"] = (
        f"{j_data.shape[0]} measured numbers fix at most {j_data.shape[0]} combinations of "
        f"{j_data.shape[1]} unknowns; {fixed} are data-dominated (singular value > 1), every "
        "other direction stays at its prior"
    )
    return out
