"""The structural response the twin uses: surrogate, stiffness sensitivities, traffic influence line.

``load_twin_surrogate`` gives the FE surrogate (``config/surrogate.yaml``) or its closed-form
placeholder, and ``stiffness_sensitivities`` the change of that surrogate per unit relative
stiffness change ``r`` (``k -> (1 + r) k``) of the central bearings and of the girder-slab
connectors: from the surrogate file's ``sensitivities`` block when the FE model wrote one
(``{bearing_stiffness: {A, u0, thermal}, connector_stiffness: {...}}``, each the change per
unit ``r``), else the closed-form placeholder; both come from :mod:`bridge_shadow.model.sensitivities`, the
one implementation the gap diagnosis uses too, so that a stiffness effect injected here has the
signature the diagnosis looks for.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from bridge_shadow.model.sensitivities import (
    BEARING_STIFFNESS_N_PER_M,
    CONNECTOR_EI_SHARE,
    StiffnessSensitivity,
    read_sensitivities_block,
    stiffness_sensitivities,
)
from bridge_shadow.model.surrogate_file import Surrogate, load_surrogate

__all__ = [
    "BEARING_STIFFNESS_N_PER_M",
    "CONNECTOR_EI_SHARE",
    "StiffnessSensitivity",
    "apply_stiffness",
    "load_twin_surrogate",
    "stiffness_sensitivities",
    "two_span_mid_influence",
]


def load_twin_surrogate(path: str | Path | None = None) -> tuple[Surrogate, dict[str, Any] | None]:
    """Return the surrogate and the raw ``sensitivities`` block of its file (None when absent)."""
    surrogate = load_surrogate(path)
    block = getattr(surrogate, "sensitivities", None)
    if block is None:
        block = read_sensitivities_block(path)
    return surrogate, block if isinstance(block, dict) else None


def apply_stiffness(
    surrogate: Surrogate, sens: dict[str, StiffnessSensitivity], ratios: dict[str, float]
) -> tuple[Surrogate, np.ndarray]:
    """Surrogate after relative stiffness changes ``ratios`` (name -> r), first order in ``r``.

    Returns the changed surrogate and the factor (2,) on the reactions to live loads (traffic):
    ``1 + sum r du0 / u0`` per channel (a live load acts like the dead load it is a part of).
    """
    a, u0 = surrogate.A.copy(), surrogate.u0.copy()
    thermal = {k: v.copy() for k, v in surrogate.thermal.items()}
    load_factor = np.ones(2)
    for name, r in ratios.items():
        if r == 0.0:
            continue
        s = sens[name]
        a += r * s.dA
        u0 += r * s.du0
        for k in thermal:
            thermal[k] = thermal[k] + r * s.dthermal.get(k, np.zeros(2))
        load_factor += r * s.du0 / surrogate.u0
    provenance = dict(surrogate.provenance)
    if any(ratios.values()):
        provenance["twin_stiffness_change"] = {k: float(v) for k, v in ratios.items() if v}
    return Surrogate(a, u0, thermal, provenance), load_factor


def two_span_mid_influence(position_m: np.ndarray, span_m: float) -> np.ndarray:
    """Central reaction of a continuous beam over two equal spans for a unit load at ``position_m``.

    ``R = xi (3 - xi^2) / 2`` with ``xi`` the distance from the outer support over the span, in
    either span (0 at the outer supports, 1 over the central support); 0 off the bridge.
    """
    p = np.asarray(position_m, float)
    xi = np.where(p <= span_m, p, 2.0 * span_m - p) / span_m
    inside = (p >= 0.0) & (p <= 2.0 * span_m)
    return np.where(inside, xi * (3.0 - xi**2) / 2.0, 0.0)
