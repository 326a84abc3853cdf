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

from bridge_shadow.effects import EFFECTS
from bridge_shadow.errors import ConfigError
from bridge_shadow.gap.drivers import Drivers
from bridge_shadow.model.sensitivities import StiffnessSensitivity, read_sensitivities_block
from bridge_shadow.model.sensitivities import stiffness_sensitivities as _stiffness_sensitivities
from bridge_shadow.model.surrogate_file import Surrogate

__all__ = [
    "CANDIDATES",
    "Candidate",
    "Sensitivity",
    "stiffness_sensitivities",
]

#: Thermal-lag grid in hours (0.25 h to 8 h, about geometric). Longer lags are left out on purpose:
#: ``T - lag(T)`` with a lag of days becomes ``T - mean(T)``, the uniform-temperature driver.
LAG_GRID_H: tuple[float, ...] = (0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0)


#: The stiffness sensitivity type (one implementation in :mod:`bridge_shadow.model.sensitivities`).
Sensitivity = StiffnessSensitivity


def stiffness_sensitivities(s: Surrogate, path: str | Path | None = None) -> dict[str, Sensitivity]:
    """Stiffness sensitivities from the surrogate's ``sensitivities`` block, else the placeholder.

    The block (written by ``bridge-shadow surrogate``, see :mod:`bridge_shadow.model.sensitivities`)
    is read from the ``Surrogate`` attribute ``sensitivities`` when present, or else from the YAML
    file ``path`` (default ``config/surrogate.yaml``); an unreadable file counts as no block.
    """
    block: Any = getattr(s, "sensitivities", None)
    if block is None:
        try:
            block = read_sensitivities_block(path)
        except ConfigError:
            block = None
    return _stiffness_sensitivities(s, block if isinstance(block, dict) else None)


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
