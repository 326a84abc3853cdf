"""The structural response the twin uses: surrogate, stiffness sensitivities, traffic influence line.

``load_twin_surrogate`` gives the FE surrogate (``config/surrogate.yaml``) or its closed-form
placeholder, and ``stiffness_sensitivities`` the change of that surrogate per unit relative
stiffness change ``r`` (``k -> (1 + r) k``) of the central bearings and of the girder-slab
connectors: from the surrogate file's ``sensitivities`` block when the FE model wrote one
(``{bearing_stiffness: {A, u0, thermal}, connector_stiffness: {...}}``, each the change per
unit ``r``), else a closed-form placeholder with the same numbers as the gap diagnosis' stand-in
(``gap.candidates``), so that a stiffness effect injected here has the signature the diagnosis
looks for.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from bridge_shadow.errors import ConfigError
from bridge_shadow.model.surrogate_file import Surrogate, load_surrogate
from bridge_shadow.paths import config_file

__all__ = [
    "BEARING_STIFFNESS_N_PER_M",
    "CONNECTOR_EI_SHARE",
    "StiffnessSensitivity",
    "apply_stiffness",
    "load_twin_surrogate",
    "stiffness_sensitivities",
    "two_span_mid_influence",
]

#: Placeholder vertical stiffness of one central bearing with its load cell, N/m (a stiff steel
#: bearing; an assumption shared with the gap diagnosis' placeholder).
BEARING_STIFFNESS_N_PER_M = 2.0e9
#: Placeholder relative change of the composite bending stiffness per unit relative connector
#: stiffness change (about half of EI comes from composite action, partially flexible connection).
CONNECTOR_EI_SHARE = 0.3


@dataclass(frozen=True)
class StiffnessSensitivity:
    """Change of the surrogate per unit relative stiffness change ``r``.

    Attributes:
        dA: (2, 2) N/m.
        du0: (2,) N.
        dthermal: case -> (2,) N/K.
        source: ``surrogate sensitivities`` or ``closed-form placeholder``.

    """

    dA: np.ndarray
    du0: np.ndarray
    dthermal: dict[str, np.ndarray] = field(default_factory=dict)
    source: str = ""

    def to_dict(self) -> dict[str, Any]:
        """Plain data for ``truth.yaml``."""
        return {
            "dA": self.dA.tolist(),
            "du0": self.du0.tolist(),
            "dthermal": {k: v.tolist() for k, v in self.dthermal.items()},
            "source": self.source,
        }


def load_twin_surrogate(path: str | Path | None = None) -> tuple[Surrogate, dict[str, Any] | None]:
    """Return the surrogate and the raw ``sensitivities`` block of its file (None when absent)."""
    surrogate = load_surrogate(path)
    block = getattr(surrogate, "sensitivities", None)
    if block is None:
        file = Path(path) if path is not None else config_file("surrogate.yaml")
        if file.is_file():
            try:
                block = (yaml.safe_load(file.read_text()) or {}).get("sensitivities")
            except (yaml.YAMLError, AttributeError) as err:
                raise ConfigError(f"{file}: not a valid surrogate file ({err})") from err
    return surrogate, block if isinstance(block, dict) else None


def _placeholder(s: Surrogate) -> dict[str, StiffnessSensitivity]:
    """Closed-form sensitivities (see the module docstring and ``gap.candidates``).

    Bearings: a spring ``k_b`` in series with the beam, ``A_eff = (A^-1 + I / k_b)^-1``; every
    reaction to an imposed deformation or load scales by ``A_eff A^-1``, hence
    ``dA/dr = A_eff A_eff / k_b`` and ``du0/dr = dA/dr A^-1 u0`` (likewise the thermal cases).
    Connectors: ``A`` and the thermal cases scale with ``EI``, ``dX/dr = 0.3 X``; ``u0`` of a
    uniform two-span beam does not depend on ``EI``.
    """
    a_inv = np.linalg.inv(s.A)
    a_eff = np.linalg.inv(a_inv + np.eye(2) / BEARING_STIFFNESS_N_PER_M)
    da = a_eff @ a_eff / BEARING_STIFFNESS_N_PER_M
    bearing = StiffnessSensitivity(
        da, da @ a_inv @ s.u0, {k: da @ a_inv @ v for k, v in s.thermal.items()}, "closed-form placeholder"
    )
    connector = StiffnessSensitivity(
        CONNECTOR_EI_SHARE * s.A,
        np.zeros(2),
        {k: CONNECTOR_EI_SHARE * v for k, v in s.thermal.items()},
        "closed-form placeholder",
    )
    return {"bearing_stiffness": bearing, "connector_stiffness": connector}


def stiffness_sensitivities(
    surrogate: Surrogate, block: dict[str, Any] | None = None
) -> dict[str, StiffnessSensitivity]:
    """Sensitivities for ``bearing_stiffness`` and ``connector_stiffness`` (file block wins)."""
    out = _placeholder(surrogate)
    for name in out:
        entry = (block or {}).get(name)
        if not isinstance(entry, dict):
            continue
        # ``bridge-shadow surrogate`` writes {A, u0, thermal}; {dA, du0, dthermal} is accepted too.
        keys = ("dA", "du0", "dthermal") if "du0" in entry else ("A", "u0", "thermal")
        if keys[1] not in entry:
            continue
        try:
            out[name] = StiffnessSensitivity(
                np.asarray(entry.get(keys[0], np.zeros((2, 2))), float).reshape(2, 2),
                np.asarray(entry[keys[1]], float).reshape(2),
                {k: np.asarray(v, float).reshape(2) for k, v in (entry.get(keys[2]) or {}).items()},
                "surrogate sensitivities",
            )
        except (TypeError, ValueError, AttributeError) as err:
            raise ConfigError(f"surrogate sensitivities for {name} are malformed ({err})") from err
    return out


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
