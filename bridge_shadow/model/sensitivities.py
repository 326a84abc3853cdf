"""Model-form changes of the surrogate: stiffness sensitivities (file or placeholder), support springs.

For ``bearing_stiffness`` (the central bearings), ``connector_stiffness`` (the girder-slab
connectors) and ``slab_joint_opening`` (the fraction of slab-joint stiffness kept over the hogging
zone): the change of ``A``, ``u0`` and each thermal vector per unit relative change ``r`` of the
parameter (``p -> (1 + r) p``). ``bridge-shadow surrogate`` writes them to the surrogate YAML as a
``sensitivities`` block ``{name: {value, A, u0, thermal}}``; ``{dA, du0, dthermal}`` is accepted
too. When the file has no block (or no entry for a parameter), ``placeholder_sensitivities`` stands
in. A changed surrogate is first order in ``r``: ``A + r dA`` and likewise ``u0`` and the thermal
cases.

A support spring (``support_spring``: a trestle, jack or foundation in series with a central
bearing) has an exact closed form instead, ``support_spring_change``. ``change_surrogate`` applies
both. The gap diagnosis, the truth twin and :mod:`.surrogate` all read through this module, so a
model-form effect injected by the twin has the signature the diagnosis looks for. No ROS import.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from bridge_shadow.errors import ConfigError
from bridge_shadow.model.surrogate_file import Surrogate, read_surrogate_document
from bridge_shadow.paths import config_file

__all__ = [
    "BEARING_STIFFNESS_N_PER_M",
    "CONNECTOR_EI_SHARE",
    "FIRST_ORDER_PARAMETERS",
    "HOGGING_ZONE_SHARE",
    "StiffnessSensitivity",
    "change_surrogate",
    "hogging_stiffness_factors",
    "parse_sensitivity",
    "placeholder_sensitivities",
    "read_sensitivities_block",
    "stiffness_sensitivities",
    "support_spring_change",
]

#: Parameters with first-order sensitivities (file block or placeholder), in this order.
FIRST_ORDER_PARAMETERS: tuple[str, ...] = ("bearing_stiffness", "connector_stiffness", "slab_joint_opening")

#: Placeholder vertical stiffness of one central bearing with its load cell, N/m (a stiff steel pot
#: bearing; assumption).
BEARING_STIFFNESS_N_PER_M = 2.0e9
#: Placeholder relative change of the composite bending stiffness per unit relative connector
#: stiffness change (about half of EI comes from composite action; a partially flexible connection
#: passes on about 0.6 of a connector stiffness change).
CONNECTOR_EI_SHARE = 0.3
#: Placeholder length of the hogging zone on each side of the central support, as a share of the
#: span: a continuous two-span beam under uniform load has its moment zero point at 3/4 of the
#: span from the end support, so the slab is in tension over the last quarter of each span.
HOGGING_ZONE_SHARE = 0.25
#: Placeholder bending stiffness of one girder, N m^2, when the surrogate's provenance has no
#: closed forms: steel HEB1000 alone (E 210 GPa, I 6.447e-3 m^4) and composite (as in
#: ``placeholder_surrogate``).
_EI_STEEL, _EI_COMPOSITE, _SPAN_M = 1.354e9, 3.0e9, 15.0

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
        value: the parameter value the surrogate was built with (SI), when the file says so.

    """

    dA: np.ndarray
    du0: np.ndarray
    dthermal: dict[str, np.ndarray] = field(default_factory=dict)
    source: str = ""
    value: float | None = None

    def to_dict(self) -> dict[str, Any]:
        """Plain data (lists), e.g. for the twin's ground-truth file."""
        return {
            "dA": self.dA.tolist(),
            "du0": self.du0.tolist(),
            "dthermal": {k: v.tolist() for k, v in self.dthermal.items()},
            "source": self.source,
            "value": self.value,
        }


def placeholder_sensitivities(s: Surrogate) -> dict[str, StiffnessSensitivity]:
    """Closed-form stand-in for the FE sensitivities (used when the surrogate file has none).

    Bearings: each central bearing is a spring ``k_b`` (``BEARING_STIFFNESS_N_PER_M``) in series
    with the beam, ``A_eff = (A^-1 + I / k_b)^-1``, and every reaction to an imposed deformation
    or load scales by ``A_eff A^-1``; hence ``dA/dr = A_eff A_eff / k_b`` and
    ``du0/dr = dA/dr A^-1 u0`` (likewise the thermal cases). Connectors: the composite bending
    stiffness scales by ``1 + CONNECTOR_EI_SHARE r``, so ``A`` and the thermal cases scale by
    ``CONNECTOR_EI_SHARE`` per unit ``r``; ``u0`` of a uniform two-span beam does not depend on
    ``EI``. Slab-joint opening: open joints leave the bare steel girders over the hogging zone
    (``hogging_stiffness_factors``); the change is linear in the fraction kept, from closed joints
    (``f = 1``, as built) to open ones (``f = 0``), with the girders' ``EI`` and span from the
    surrogate's ``provenance.closed_forms`` when the FE solver wrote them.
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
    closed = s.provenance.get("closed_forms") if isinstance(s.provenance, dict) else None
    closed = closed if isinstance(closed, dict) else {}
    k_ratio, r_ratio = hogging_stiffness_factors(
        float(closed.get("EI_steel_Nm2", _EI_STEEL)),
        float(closed.get("EI_composite_Nm2", _EI_COMPOSITE)),
        float(closed.get("span_m", _SPAN_M)),
    )
    # Linear in f between closed joints (f = 1) and open ones (f = 0): the change per unit
    # r = f - 1 is the whole difference (the secant, not the tangent at f = 1).
    slab = StiffnessSensitivity(
        (1.0 - k_ratio) * s.A,
        (1.0 - r_ratio) * s.u0,
        {k: (1.0 - k_ratio) * v for k, v in s.thermal.items()},
        _PLACEHOLDER,
    )
    return {"bearing_stiffness": bearing, "connector_stiffness": connector, "slab_joint_opening": slab}


def hogging_stiffness_factors(
    ei_steel: float, ei_composite: float, span_m: float, zone_share: float = HOGGING_ZONE_SHARE
) -> tuple[float, float]:
    """Ratios (settlement stiffness, dead-load central reaction) with open slab joints over the hogging zone.

    A continuous girder over two equal spans ``L`` with the composite bending stiffness ``EI_c``,
    except over ``a = zone_share L`` on each side of the central support where open slab joints
    leave the bare steel girder ``EI_s``. By the unit-load method on the simply supported beam of
    length ``2 L``: the central flexibility ``delta = 2 int_0^L (x / 2)^2 / EI dx`` and the
    deflection under a uniform load ``Delta = 2 int_0^L w x (2 L - x) / 2 * x / 2 / EI dx``; the
    settlement stiffness is ``1 / delta`` and the central reaction ``Delta / delta``. Returns
    both relative to a uniform ``EI_c`` (``1 / delta`` = ``6 EI_c / L^3``, reaction ``5 w L / 4``).
    The placeholder applies the first ratio to all of ``A`` and to the thermal cases (a gradient
    acts through the same flexibility), the second to ``u0``.
    """
    big_l = span_m
    b = (1.0 - zone_share) * big_l

    def i1(p: float, q: float) -> float:
        return (q**3 - p**3) / 3.0

    def i2(p: float, q: float) -> float:
        return 2.0 * big_l * (q**3 - p**3) / 3.0 - (q**4 - p**4) / 4.0

    def flex(ei_h: float) -> tuple[float, float]:
        delta = 0.5 * (i1(0.0, b) / ei_composite + i1(b, big_l) / ei_h)
        deflection = 0.5 * (i2(0.0, b) / ei_composite + i2(b, big_l) / ei_h)
        return delta, deflection

    d_closed, w_closed = flex(ei_composite)
    d_open, w_open = flex(ei_steel)
    return d_closed / d_open, (w_open / d_open) / (w_closed / d_closed)


def support_spring_change(
    surrogate: Surrogate, springs_n_per_m: Any, *, levelled: bool = False
) -> tuple[Surrogate, np.ndarray]:
    """Surrogate with a support spring in series with each central bearing (exact).

    The bearing sits on a spring ``k`` (a trestle, jack or foundation; ``inf`` = rigid) whose
    ground point moves by ``x``; the spring shortens by ``R / k`` under the reaction ``R``, so
    ``R = A (x - C R) + u0`` with ``C = diag(1 / k_s, 1 / k_n)``, hence
    ``R = A' x + M u0`` with ``A' = (A^-1 + C)^-1`` and ``M = (I + A C)^-1 = A' A^-1``. Every load
    (dead load, thermal cases, traffic) maps through ``M``. ``levelled``: the support was set to
    the design level under the dead load (``x`` measured from there), so ``u0`` stays and only
    the changes map. Returns the changed surrogate and ``M`` (2, 2).
    """
    k = np.asarray(springs_n_per_m, float).reshape(2)
    if np.any(~(k > 0)):
        raise ValueError("support spring stiffness must be positive (inf: rigid)")
    c = np.where(np.isinf(k), 0.0, 1.0 / np.where(np.isinf(k), 1.0, k))
    a = surrogate.A
    # M = (I + A C)^-1; A' = M A (symmetric for symmetric A: (A^-1 + C)^-1).
    m = np.linalg.inv(np.eye(2) + a @ np.diag(c))
    a_new = m @ a
    a_new = 0.5 * (a_new + a_new.T)
    thermal = {name: m @ v for name, v in surrogate.thermal.items()}
    u0 = surrogate.u0.copy() if levelled else m @ surrogate.u0
    # the model's own uncertainty (a calibrated surrogate's model_cov) is kept: the change is on top of it
    prov = dict(surrogate.provenance)
    changed = Surrogate(a_new, u0, thermal, prov, surrogate.model_cov, surrogate.discrepancy)
    return changed, m


def change_surrogate(
    surrogate: Surrogate,
    sens: dict[str, StiffnessSensitivity] | None = None,
    ratios: dict[str, float] | None = None,
    springs_n_per_m: Any = (math.inf, math.inf),
    *,
    levelled: bool = False,
) -> tuple[Surrogate, np.ndarray]:
    """Surrogate after model-form changes: first-order parameter changes, then support springs.

    Args:
        surrogate: the model as built.
        sens: first-order sensitivities (``stiffness_sensitivities``), needed for ``ratios``.
        ratios: parameter name -> relative change ``r``: ``A + r dA``, ``u0 + r du0`` and the
            thermal cases alike.
        springs_n_per_m: support-spring stiffness [south, north] in N/m (``inf``: none), applied
            after the first-order changes (``support_spring_change``).
        levelled: the supports were levelled under the dead load (``u0`` kept by the springs).

    Returns:
        ``(changed surrogate, load map (2, 2))``; the load map takes the central reactions to a
        live load (traffic) of the as-built model to the changed one: ``I + diag(sum r du0 / u0)``
        (a live load acts like the dead load it is a part of), then the springs' ``M``.
    """
    a, u0 = surrogate.A.copy(), surrogate.u0.copy()
    thermal = {k: v.copy() for k, v in surrogate.thermal.items()}
    load_map = np.eye(2)
    for name, r in (ratios or {}).items():
        if r == 0.0:
            continue
        if sens is None or name not in sens:
            raise KeyError(f"no sensitivity for {name}")
        d = sens[name]
        a = a + r * d.dA
        u0 = u0 + r * d.du0
        for k in thermal:
            thermal[k] = thermal[k] + r * d.dthermal.get(k, np.zeros(2))
        load_map = load_map + np.diag(r * d.du0 / surrogate.u0)
    prov = dict(surrogate.provenance)
    changed = Surrogate(a, u0, thermal, prov, surrogate.model_cov, surrogate.discrepancy)
    k = np.asarray(springs_n_per_m, float).reshape(2)
    if np.any(np.isfinite(k)):
        changed, m = support_spring_change(changed, k, levelled=levelled)
        load_map = m @ load_map
    provenance = dict(surrogate.provenance)
    change: dict[str, Any] = {name: float(r) for name, r in (ratios or {}).items() if r}
    if np.any(np.isfinite(k)):
        change["support_spring_n_per_m"] = [float(v) for v in k]
        change["support_spring_levelled"] = bool(levelled)
    if change:
        provenance["model_form_change"] = change
    changed.provenance = provenance
    return changed, load_map


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
        data = read_surrogate_document(file) or {}
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
    value = entry.get("value")
    try:
        return StiffnessSensitivity(
            np.asarray(da, float).reshape(2, 2),
            np.asarray(du0, float).reshape(2),
            {k: np.asarray(v, float).reshape(2) for k, v in dth.items()},
            _FROM_FILE,
            None if value is None else float(value),
        )
    except (TypeError, ValueError, AttributeError) as err:
        raise ConfigError(f"surrogate sensitivities for {name} are malformed ({err})") from err


def stiffness_sensitivities(
    surrogate: Surrogate, block: dict[str, Any] | None = None
) -> dict[str, StiffnessSensitivity]:
    """Sensitivities for ``FIRST_ORDER_PARAMETERS``.

    Each from its entry in the file ``block`` (see ``parse_sensitivity``), else the placeholder.
    """
    out = placeholder_sensitivities(surrogate)
    for name in out:
        sens = parse_sensitivity(name, (block or {}).get(name))
        if sens is not None:
            out[name] = sens
    return out
