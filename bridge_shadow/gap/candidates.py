"""The candidate library: a spatial signature on the two reactions times a temporal driver.

Each candidate maps its linear parameters to a reaction change ``(n, 2)`` N through a design
array ``X: (n, 2, p)`` (the change per unit of each parameter), optionally for each value of one
nonlinear parameter on a grid (the thermal lag, the drifting channel). Signatures come from the
surrogate: the columns of ``A`` (settlements), the thermal load cases, and the stiffness
sensitivities (``dA``, ``du0``, ``dthermal`` per unit relative stiffness change); sensor effects
act on one channel only.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from bridge_shadow.effects import EFFECTS
from bridge_shadow.errors import ConfigError
from bridge_shadow.gap.drivers import Drivers
from bridge_shadow.model.surrogate_file import Surrogate
from bridge_shadow.paths import config_file

__all__ = [
    "CANDIDATES",
    "Candidate",
    "Sensitivity",
    "stiffness_sensitivities",
]

#: Thermal-lag grid in hours (0.25 h to 8 h, about geometric). Longer lags are left out on purpose:
#: ``T - lag(T)`` with a lag of days becomes ``T - mean(T)``, the uniform-temperature driver.
LAG_GRID_H: tuple[float, ...] = (0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0)


@dataclass(frozen=True)
class Sensitivity:
    """Change of the surrogate per unit relative stiffness change ``r`` (``k -> (1 + r) k``).

    Attributes:
        dA: (2, 2) N/m.
        du0: (2,) N.
        dthermal: case -> (2,) N/K.
        source: where the numbers come from.

    """

    dA: np.ndarray
    du0: np.ndarray
    dthermal: dict[str, np.ndarray]
    source: str


def _placeholder_sensitivities(s: Surrogate) -> dict[str, Sensitivity]:
    """Closed-form stand-in for the FE sensitivities (used when the surrogate has none).

    Bearings: each central bearing is a spring ``k_b = 2e9 N/m`` (a stiff pot bearing with load
    cell, assumption) in series with the beam: ``A_eff = (A^-1 + I/k_b)^-1``, and every reaction
    to an imposed deformation scales by ``A_eff A^-1``; hence ``dA/dr = A_eff A_eff / k_b`` and
    ``du0/dr = dA/dr A^-1 u0`` (likewise the thermal cases). Connectors: the composite bending
    stiffness scales by ``1 + 0.3 r`` (about half of ``EI`` comes from composite action; a
    partially flexible connection passes on about 0.6 of a connector stiffness change), so ``A``
    and the gradient cases scale by 0.3 per unit ``r``; ``u0`` of a uniform two-span beam does not
    depend on ``EI``.
    """
    k_b, kappa = 2.0e9, 0.3
    a_inv = np.linalg.inv(s.A)
    a_eff = np.linalg.inv(a_inv + np.eye(2) / k_b)
    da = a_eff @ a_eff / k_b
    bearing = Sensitivity(
        da, da @ a_inv @ s.u0, {k: da @ a_inv @ v for k, v in s.thermal.items()}, "closed-form placeholder"
    )
    connector = Sensitivity(
        kappa * s.A, np.zeros(2), {k: kappa * v for k, v in s.thermal.items()}, "closed-form placeholder"
    )
    return {"bearing_stiffness": bearing, "connector_stiffness": connector}


def stiffness_sensitivities(s: Surrogate, path: str | Path | None = None) -> dict[str, Sensitivity]:
    """Stiffness sensitivities from the surrogate's ``sensitivities`` block, else the placeholder.

    The block (written by ``bridge-shadow surrogate``) maps ``bearing_stiffness`` and
    ``connector_stiffness`` to ``{dA, du0, dthermal}`` (or ``{A, u0, thermal}``). It is read from
    the ``Surrogate`` attribute ``sensitivities`` when present, or else from the YAML file.
    """
    block: Any = getattr(s, "sensitivities", None)
    if block is None:
        file = Path(path) if path is not None else config_file("surrogate.yaml")
        if file.is_file():
            try:
                block = (yaml.safe_load(file.read_text()) or {}).get("sensitivities")
            except yaml.YAMLError:
                block = None
    out = _placeholder_sensitivities(s)
    if isinstance(block, dict):
        for name in out:
            b = block.get(name)
            if not isinstance(b, dict):
                continue
            # Either spelling: {dA, du0, dthermal} or {A, u0, thermal} (per unit r).
            du0 = b.get("du0", b.get("u0"))
            if du0 is None:
                continue
            da = b.get("dA", b.get("A", np.zeros((2, 2))))
            dth = b.get("dthermal", b.get("thermal")) or {}
            try:
                out[name] = Sensitivity(
                    np.asarray(da, float).reshape(2, 2),
                    np.asarray(du0, float).reshape(2),
                    {k: np.asarray(v, float).reshape(2) for k, v in dth.items()},
                    "surrogate sensitivities",
                )
            except (TypeError, ValueError) as err:
                raise ConfigError(f"surrogate sensitivities for {name} are malformed ({err})") from err
    return out


@dataclass
class Context:
    """What a candidate's design needs: the drivers, the surrogate and the sensitivities."""

    drivers: Drivers
    surrogate: Surrogate
    sensitivities: dict[str, Sensitivity]


Design = Callable[[Context, Any], np.ndarray]


@dataclass(frozen=True)
class Candidate:
    """One candidate effect of the vocabulary.

    Attributes:
        name: vocabulary name (``bridge_shadow.effects``).
        params: names of the linear parameters, with their SI unit in brackets.
        design: ``(ctx, g) -> X (n, 2, p)``, the reaction change in N per unit of each parameter.
        grid: values of the nonlinear parameter (``(None,)`` when there is none).
        grid_name: name of the nonlinear parameter.
        magnitude: ``(params, g) -> float``, the fitted value in the vocabulary's magnitude unit.

    """

    name: str
    params: tuple[str, ...]
    design: Design
    grid: tuple[Any, ...] = (None,)
    grid_name: str | None = None
    magnitude: Callable[[np.ndarray, Any], float] | None = None
    discrete: bool = False

    @property
    def part(self) -> str:
        """Model part: structural, thermal, sensor or load."""
        return EFFECTS[self.name].part

    @property
    def n_params(self) -> int:
        """Number of fitted parameters (linear ones plus the grid parameter)."""
        return len(self.params) + (self.grid_name is not None)

    def penalty(self, n_eff: float) -> float:
        """BIC penalty in ``-2 log L`` units.

        ``log n_eff`` per continuous parameter, ``2 log K`` for a choice among ``K`` discrete
        alternatives (the drifting channel).
        """
        pen = len(self.params) * np.log(n_eff)
        if self.grid_name is not None:
            pen += 2.0 * np.log(len(self.grid)) if self.discrete else np.log(n_eff)
        return float(pen)


def _const(ctx: Context, vec: np.ndarray, driver: np.ndarray) -> np.ndarray:
    return driver[:, None, None] * np.asarray(vec, float)[None, :, None]


def _settle_offset(ctx: Context, _: Any) -> np.ndarray:
    n = len(ctx.drivers)
    return np.broadcast_to(ctx.surrogate.A[None, :, :], (n, 2, 2)).copy()


def _settle_drift(ctx: Context, _: Any) -> np.ndarray:
    return ctx.drivers.t_day[:, None, None] * ctx.surrogate.A[None, :, :]


def _uniform(ctx: Context, _: Any) -> np.ndarray:
    return _const(ctx, np.ones(2), ctx.drivers.dtemp_k)


def _sun_case(case: str) -> Design:
    def design(ctx: Context, _: Any) -> np.ndarray:
        d = ctx.drivers
        return _const(ctx, ctx.surrogate.thermal[case], d.sun * d.clearness)

    return design


def _thermal_lag(ctx: Context, tau_h: float) -> np.ndarray:
    d = ctx.drivers
    return _const(ctx, ctx.surrogate.thermal["vertical_gradient"], d.temp_c - d.lagged_temp(tau_h))


def _stiffness(name: str) -> Design:
    def design(ctx: Context, _: Any) -> np.ndarray:
        sens = ctx.sensitivities[name]
        uniform = sens.dthermal.get("uniform", np.zeros(2))
        x = sens.du0[None, :] + ctx.drivers.dtemp_k[:, None] * uniform[None, :]
        return x[:, :, None]

    return design


def _sensor_drift(ctx: Context, channel: str) -> np.ndarray:
    e = np.array([1.0, 0.0]) if channel == "south" else np.array([0.0, 1.0])
    return _const(ctx, e, ctx.drivers.t_day)


def _traffic(ctx: Context, _: Any) -> np.ndarray:
    tr = ctx.drivers.traffic
    x = np.zeros((len(tr), 2, 2))
    x[:, 0, 0] = tr
    x[:, 1, 1] = tr
    return x


CANDIDATES: tuple[Candidate, ...] = (
    Candidate(
        "settlement_offset",
        ("x_south [m]", "x_north [m]"),
        _settle_offset,
        magnitude=lambda p, g: float(0.5 * (p[0] - p[1])),
    ),
    Candidate(
        "settlement_drift",
        ("v_south [m/day]", "v_north [m/day]"),
        _settle_drift,
        magnitude=lambda p, g: float(-p[0]),
    ),
    Candidate("uniform_temperature", ("c [N/K]",), _uniform, magnitude=lambda p, g: float(p[0])),
    Candidate(
        "vertical_gradient",
        ("g [K]",),
        _sun_case("vertical_gradient"),
        magnitude=lambda p, g: float(p[0]),
    ),
    Candidate(
        "transverse_gradient",
        ("g [K]",),
        _sun_case("transverse_gradient"),
        magnitude=lambda p, g: float(p[0]),
    ),
    Candidate(
        "thermal_lag", ("scale [1]",), _thermal_lag, LAG_GRID_H, "tau [h]", magnitude=lambda p, g: float(g)
    ),
    Candidate(
        "bearing_stiffness", ("r [1]",), _stiffness("bearing_stiffness"), magnitude=lambda p, g: float(p[0])
    ),
    Candidate(
        "connector_stiffness",
        ("r [1]",),
        _stiffness("connector_stiffness"),
        magnitude=lambda p, g: float(p[0]),
    ),
    Candidate(
        "sensor_drift",
        ("d [N/day]",),
        _sensor_drift,
        ("south", "north"),
        "channel",
        magnitude=lambda p, g: float(p[0]),
        discrete=True,
    ),
    Candidate("traffic", ("b_south [1]", "b_north [1]"), _traffic, magnitude=lambda p, g: float(np.sum(p))),
)
