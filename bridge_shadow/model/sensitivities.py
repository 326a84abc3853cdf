"""Stiffness sensitivities of the surrogate: read from the surrogate file, or a closed-form placeholder.

For ``bearing_stiffness`` (the central bearings) and ``connector_stiffness`` (the girder-slab
connectors): the change of ``A``, ``u0`` and each thermal vector per unit relative stiffness
change ``r`` (``k -> (1 + r) k``). ``bridge-shadow surrogate`` writes them to the surrogate YAML
as a ``sensitivities`` block ``{name: {value, A, u0, thermal}}``; ``{dA, du0, dthermal}`` is
accepted too. When the file has no block (or no entry for a parameter), ``placeholder_sensitivities``
stands in. The gap diagnosis, the truth twin and :mod:`.surrogate` all read through this module, so
a stiffness effect injected by the twin has the signature the diagnosis looks for. No ROS import.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from bridge_shadow.errors import ConfigError
from bridge_shadow.model.surrogate_file import Surrogate
from bridge_shadow.paths import config_file

__all__ = [
    "BEARING_STIFFNESS_N_PER_M",
    "CONNECTOR_EI_SHARE",
    "StiffnessSensitivity",
    "parse_sensitivity",
    "placeholder_sensitivities",
    "read_sensitivities_block",
    "stiffness_sensitivities",
]

#: Placeholder vertical stiffness of one central bearing with its load cell, N/m (a stiff steel pot
#: bearing; assumption).
BEARING_STIFFNESS_N_PER_M = 2.0e9
#: Placeholder relative change of the composite bending stiffness per unit relative connector
#: stiffness change (about half of EI comes from composite action; a partially flexible connection
#: passes on about 0.6 of a connector stiffness change).
CONNECTOR_EI_SHARE = 0.3

_PLACEHOLDER = "closed-form placeholder"
_FROM_FILE = "surrogate sensitivities"


@dataclass(frozen=True)
class StiffnessSensitivity:
    """Change of the surrogate per unit relative stiffness change ``r`` (``k -> (1 + r) k``).

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
        """Plain data (lists), e.g. for the twin's ground-truth file."""
        return {
            "dA": self.dA.tolist(),
            "du0": self.du0.tolist(),
            "dthermal": {k: v.tolist() for k, v in self.dthermal.items()},
            "source": self.source,
        }


def placeholder_sensitivities(s: Surrogate) -> dict[str, StiffnessSensitivity]:
    """Closed-form stand-in for the FE sensitivities (used when the surrogate file has none).

    Bearings: each central bearing is a spring ``k_b`` (``BEARING_STIFFNESS_N_PER_M``) in series
    with the beam, ``A_eff = (A^-1 + I / k_b)^-1``, and every reaction to an imposed deformation
    or load scales by ``A_eff A^-1``; hence ``dA/dr = A_eff A_eff / k_b`` and
    ``du0/dr = dA/dr A^-1 u0`` (likewise the thermal cases). Connectors: the composite bending
    stiffness scales by ``1 + CONNECTOR_EI_SHARE r``, so ``A`` and the thermal cases scale by
    ``CONNECTOR_EI_SHARE`` per unit ``r``; ``u0`` of a uniform two-span beam does not depend on
    ``EI``.
    """
    k_b, kappa = BEARING_STIFFNESS_N_PER_M, CONNECTOR_EI_SHARE
    a_inv = np.linalg.inv(s.A)
    a_eff = np.linalg.inv(a_inv + np.eye(2) / k_b)
    da = a_eff @ a_eff / k_b
    bearing = StiffnessSensitivity(
        da, da @ a_inv @ s.u0, {k: da @ a_inv @ v for k, v in s.thermal.items()}, _PLACEHOLDER
    )
    connector = StiffnessSensitivity(
        kappa * s.A, np.zeros(2), {k: kappa * v for k, v in s.thermal.items()}, _PLACEHOLDER
    )
    return {"bearing_stiffness": bearing, "connector_stiffness": connector}


def read_sensitivities_block(
    path: str | Path | None = None, *, required: bool = False
) -> dict[str, Any] | None:
    """Return the raw ``sensitivities`` block of a surrogate YAML (default ``config/surrogate.yaml``).

    None when the file has no such block, or when it does not exist and ``required`` is false.
    Raises ConfigError when the file is not valid YAML mapping (or is missing and ``required``).
    """
    file = Path(path) if path is not None else config_file("surrogate.yaml")
    if not required and not file.is_file():
        return None
    try:
        data = yaml.safe_load(file.read_text()) or {}
        block = data.get("sensitivities")
    except (OSError, yaml.YAMLError, AttributeError) as err:
        raise ConfigError(f"{file}: not a valid surrogate file ({err})") from err
    return block if isinstance(block, dict) else None


def parse_sensitivity(name: str, entry: Any) -> StiffnessSensitivity | None:
    """One block entry ``{A, u0, thermal}`` or ``{dA, du0, dthermal}`` as arrays; None without ``u0``.

    Each key is looked up in the ``d``-spelling first; a missing ``A`` counts as zero.
    """
    if not isinstance(entry, dict):
        return None
    du0 = entry.get("du0", entry.get("u0"))
    if du0 is None:
        return None
    da = entry.get("dA", entry.get("A", np.zeros((2, 2))))
    dth = entry.get("dthermal", entry.get("thermal")) or {}
    try:
        return StiffnessSensitivity(
            np.asarray(da, float).reshape(2, 2),
            np.asarray(du0, float).reshape(2),
            {k: np.asarray(v, float).reshape(2) for k, v in dth.items()},
            _FROM_FILE,
        )
    except (TypeError, ValueError, AttributeError) as err:
        raise ConfigError(f"surrogate sensitivities for {name} are malformed ({err})") from err


def stiffness_sensitivities(
    surrogate: Surrogate, block: dict[str, Any] | None = None
) -> dict[str, StiffnessSensitivity]:
    """Sensitivities for ``bearing_stiffness`` and ``connector_stiffness``.

    Each from its entry in the file ``block`` (see ``parse_sensitivity``), else the placeholder.
    """
    out = placeholder_sensitivities(surrogate)
    for name in out:
        sens = parse_sensitivity(name, (block or {}).get(name))
        if sens is not None:
            out[name] = sens
    return out
