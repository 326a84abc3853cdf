"""Parameter sweeps of the surrogate: A, u0 and the thermal cases over a parameter's plausible range.

A first-order sensitivity (``model.sensitivities``) holds near the value the surrogate was built
with; a stiffness the data may put two decades lower (bolts slipping in their holes, open slab
joints) needs the FE's whole curve. ``compute_sweeps`` re-solves the FE model at ``SWEEP_POINTS``
values of each named parameter, log-spaced over its plausible range (``model.parameters``: the one
table of ranges) plus the value the surrogate was built with; the surrogate file keeps them as a
``sweeps`` block ``{name: {value, values, A, u0, thermal}}`` (SI). ``Sweep`` interpolates them with
a monotone piecewise cubic in ``log(value)`` (PCHIP: exact at the solved points, no overshoot, so
the derivative keeps the sign of the data; a natural spline's end slope can point the wrong way
and stall a fit at a fraction's bound) and gives the derivative per unit ``log(value)`` for the
calibration's Jacobian.

The gap diagnosis (``gap.levels``) reads them to fit a stiffness to a known imposed step without an
FE solve. No ROS import.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from scipy.interpolate import PchipInterpolator

from bridge_shadow.errors import ConfigError
from bridge_shadow.model.parameters import parameter
from bridge_shadow.model.surrogate_file import THERMAL_CASES, read_surrogate_document

__all__ = ["SWEEP_PARAMETERS", "SWEEP_POINTS", "Sweep", "compute_sweeps", "read_sweeps", "sweep_values"]

#: Parameters swept: the first-order ones of ``model.sensitivities`` (the support springs have an
#: exact closed form and need none).
SWEEP_PARAMETERS: tuple[str, ...] = ("bearing_stiffness", "connector_stiffness", "slab_joint_opening")
#: Solved values per parameter over its plausible range (plus the built value). Seven points over
#: up to seven decades: the responses are smooth saturating curves in log(value), and the
#: interpolation through them is checked against extra FE solves between the points
#: (``test/test_model_sweeps.py``).
SWEEP_POINTS = 7


def sweep_values(name: str, built: float) -> np.ndarray:
    """Values (SI) a sweep solves: ``SWEEP_POINTS`` log-spaced over the plausible range, and ``built``."""
    lo, hi = parameter(name).bounds
    grid = np.exp(np.linspace(np.log(lo), np.log(hi), SWEEP_POINTS))
    out = np.unique(np.concatenate([grid, [float(built)]]))
    # drop grid points closer than 1 % in log to the built value (a spline needs distinct knots)
    keep = (np.abs(np.log(out / built)) > 0.01) | (out == built)
    return out[keep]


@dataclass(frozen=True)
class Sweep:
    """The surrogate over one parameter, interpolated in ``log(value)``.

    Attributes:
        name: the parameter. built: the value the surrogate was built with (SI).
        values: (k,) solved values, ascending. A: (k, 2, 2) N/m. u0: (k, 2) N.
        thermal: case -> (k, 2) N/K.

    """

    name: str
    built: float
    values: np.ndarray
    A: np.ndarray
    u0: np.ndarray
    thermal: dict[str, np.ndarray]

    def __post_init__(self) -> None:
        if len(self.values) < 2 or np.any(np.diff(self.values) <= 0):
            raise ConfigError(f"sweep {self.name}: need two or more ascending values")

    def _spline(self) -> PchipInterpolator:
        stacked = np.hstack(
            [self.A.reshape(-1, 4), self.u0, *(self.thermal[c] for c in THERMAL_CASES)]
        )  # (k, 12)
        return PchipInterpolator(np.log(self.values), stacked, axis=0)

    @property
    def range(self) -> tuple[float, float]:
        """Smallest and largest solved value (SI): outside it the sweep is not used."""
        return float(self.values[0]), float(self.values[-1])

    def change(self, value: float) -> tuple[np.ndarray, np.ndarray]:
        """(12,) change of ``[A, u0, thermal]`` from the built value to ``value``, and its derivative.

        The derivative is per unit ``log(value)``; the order is ``MODEL_UNCERTAINTY_ORDER_FULL``.
        ``value`` is clipped into the solved range. At an end of the range the derivative is the
        end interval's secant (PCHIP sets an end slope to zero when its three-point estimate
        disagrees in sign, which would stall a fit that starts there, as a fraction at 1 does).
        """
        spline = self._spline()
        logs = np.log(self.values)
        x = float(np.clip(np.log(value), logs[0], logs[-1]))
        x0 = float(np.log(self.built))
        if x <= logs[0] or x >= logs[-1]:
            i = 0 if x <= logs[0] else len(logs) - 2
            slope = (spline(logs[i + 1]) - spline(logs[i])) / (logs[i + 1] - logs[i])
        else:
            slope = spline.derivative()(x)
        return spline(x) - spline(x0), slope

    def to_dict(self) -> dict[str, Any]:
        """Plain data (SI) for the surrogate file."""
        return {
            "value": self.built,
            "values": self.values.tolist(),
            "A": self.A.tolist(),
            "u0": self.u0.tolist(),
            "thermal": {c: self.thermal[c].tolist() for c in THERMAL_CASES},
        }

    @classmethod
    def from_dict(cls, name: str, data: Mapping[str, Any]) -> Sweep:
        """Inverse of ``to_dict``; ConfigError with one line when malformed."""
        try:
            values = np.asarray(data["values"], float)
            k = len(values)
            return cls(
                name,
                float(data["value"]),
                values,
                np.asarray(data["A"], float).reshape(k, 2, 2),
                np.asarray(data["u0"], float).reshape(k, 2),
                {c: np.asarray(data["thermal"][c], float).reshape(k, 2) for c in THERMAL_CASES},
            )
        except (KeyError, TypeError, ValueError) as err:
            raise ConfigError(f"surrogate sweeps: {name} is malformed ({err})") from None


def compute_sweeps(
    cfg: Any,
    level: str,
    names: Sequence[str] = SWEEP_PARAMETERS,
    report: Callable[[float, str], None] | None = None,
    base: Any = None,
) -> dict[str, Sweep]:
    """FE-solve the bridge at ``sweep_values`` of each parameter (the others as in ``cfg``).

    ``base``: the solution at ``cfg`` itself (reused for the built value when given).
    """
    from bridge_shadow.model.solution import solve_bridge  # lazy: reading sweeps needs no FE

    out = {}
    total = sum(len(sweep_values(n, cfg.params[n])) for n in names)
    done = 0
    for name in names:
        built = float(cfg.params[name])
        values = sweep_values(name, built)
        rows = []
        for v in values:
            if v == built and base is not None:
                sol = base
            else:
                sol = solve_bridge(cfg.with_overrides({name: float(v)}), level)
            rows.append(sol)
            done += 1
            if report is not None:
                report(done / total, f"sweep {name}")
        out[name] = Sweep(
            name,
            built,
            values,
            np.array([r.A for r in rows]),
            np.array([r.u0 for r in rows]),
            {c: np.array([r.thermal[c] for r in rows]) for c in THERMAL_CASES},
        )
    return out


def read_sweeps(path: str | Path | None = None, block: Mapping[str, Any] | None = None) -> dict[str, Sweep]:
    """Read the ``sweeps`` block of a surrogate file (default ``config/surrogate.yaml``), or ``block``.

    Empty when the file has none (it was written before sweeps existed).
    """
    if block is None:
        from bridge_shadow.paths import config_file

        file = Path(path) if path is not None else config_file("surrogate.yaml")
        if not file.is_file():
            return {}
        try:
            block = (read_surrogate_document(file) or {}).get("sweeps") or {}
        except (OSError, yaml.YAMLError, AttributeError) as err:
            raise ConfigError(f"{file}: not a valid surrogate file ({err})") from err
    return {str(k): Sweep.from_dict(str(k), v) for k, v in block.items()}
