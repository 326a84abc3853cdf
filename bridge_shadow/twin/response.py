"""The structural response the twin uses: surrogate, model-form changes, traffic influence line.

``load_twin_surrogate`` gives the FE surrogate (``config/surrogate.yaml``) or its closed-form
placeholder, and ``stiffness_sensitivities`` the change of that surrogate per unit relative
change ``r`` of the central bearings' stiffness, the girder-slab connectors' and the slab joints'
kept fraction: from the surrogate file's ``sensitivities`` block when the FE model wrote one
(``{bearing_stiffness: {A, u0, thermal}, ...}``, each the change per unit ``r``), else the
closed-form placeholder. ``apply_stiffness`` adds support springs by their exact closed form. All of
it comes from :mod:`bridge_shadow.model.sensitivities`, the one implementation the gap diagnosis
uses too, so that a model-form effect injected here has the signature the diagnosis looks for.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from bridge_shadow.model.sensitivities import (
    BEARING_STIFFNESS_N_PER_M,
    CONNECTOR_EI_SHARE,
    StiffnessSensitivity,
    change_surrogate,
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
    surrogate: Surrogate,
    sens: dict[str, StiffnessSensitivity],
    ratios: dict[str, float],
    springs_n_per_m: Any = (np.inf, np.inf),
) -> tuple[Surrogate, np.ndarray]:
    """Surrogate after relative changes ``ratios`` (name -> r, first order) and support springs.

    Returns the changed surrogate and the load map (2, 2) that takes the central reactions to a
    live load (traffic) of the as-built model to the changed one
    (``bridge_shadow.model.sensitivities.change_surrogate``).
    """
    changed, load_map = change_surrogate(surrogate, sens, ratios, springs_n_per_m)
    if "model_form_change" in changed.provenance:
        changed.provenance["twin_stiffness_change"] = changed.provenance.pop("model_form_change")
    return changed, load_map


def two_span_mid_influence(position_m: np.ndarray, span_m: float) -> np.ndarray:
    """Central reaction of a continuous beam over two equal spans for a unit load at ``position_m``.

    ``R = xi (3 - xi^2) / 2`` with ``xi`` the distance from the outer support over the span, in
    either span (0 at the outer supports, 1 over the central support); 0 off the bridge.
    """
    p = np.asarray(position_m, float)
    xi = np.where(p <= span_m, p, 2.0 * span_m - p) / span_m
    inside = (p >= 0.0) & (p <= 2.0 * span_m)
    return np.where(inside, xi * (3.0 - xi**2) / 2.0, 0.0)
