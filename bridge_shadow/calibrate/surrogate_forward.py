"""A forward model of the calibration without FE solves: a surrogate file's sweeps and closed forms.

:class:`bridge_shadow.calibrate.forward.ForwardModel` re-solves the FE model at every parameter
vector (a second or more each); the gap diagnosis fits a stiffness to a known imposed step in a
fraction of a second from what the surrogate file already holds:

- the swept FE parameters (``model.sweeps``: ``bearing_stiffness``, ``connector_stiffness``,
  ``slab_joint_opening``): the surrogate plus the sweep's change from the built value, exact at the
  solved points and a cubic spline in ``log(value)`` between them; a parameter without a sweep
  falls back to the first-order sensitivity (``model.sensitivities``), ``A + (v / v0 - 1) dA``;
- the support springs: the exact series closed form of :func:`.forward.series_springs` on the
  surrogate with its own springs taken out (``A_rigid^-1 = A^-1 - C_built``; ``C_built`` from the
  springs the surrogate was solved with, ``provenance.overrides``).

The result is an :class:`.forward.Evaluation` with derivatives per unit ``log`` of each parameter,
so :class:`.problem.CalibrationProblem` (Levenberg-Marquardt, Laplace evidence) runs on it as on
the FE. No ROS import.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bridge_shadow.calibrate.forward import Evaluation, assemble, series_springs
from bridge_shadow.model.build import SUPPORT_SPRINGS
from bridge_shadow.model.sensitivities import StiffnessSensitivity
from bridge_shadow.model.surrogate_file import THERMAL_CASES, Surrogate
from bridge_shadow.model.sweeps import Sweep

__all__ = ["SurrogateForward", "built_springs"]

_SPRINGS = tuple(SUPPORT_SPRINGS.values())


def built_springs(surrogate: Surrogate) -> np.ndarray:
    """(2,) N/m, the support springs the surrogate was solved with (``inf``: rigid, as built)."""
    over = surrogate.provenance.get("overrides") if isinstance(surrogate.provenance, dict) else None
    over = over if isinstance(over, dict) else {}
    return np.array([float(over.get(n, np.inf)) for n in _SPRINGS])


@dataclass
class SurrogateForward:
    """Named parameter values -> :class:`Evaluation`, from a surrogate's sweeps and closed forms.

    Attributes:
        surrogate: the model in use (``A``, ``u0``, ``thermal``, ``provenance``).
        names: the parameters (``support_spring_south/north`` and swept or first-order ones).
        sweeps: parameter -> its sweep (``model.sweeps.read_sweeps``).
        sensitivities: first-order fallbacks (``model.sensitivities.stiffness_sensitivities``).
        built: parameter -> the value the surrogate was built with (SI).
        solves: 0 (the interface of ``ForwardModel``: no FE solve here).

    """

    surrogate: Surrogate
    names: tuple[str, ...]
    sweeps: Mapping[str, Sweep] = field(default_factory=dict)
    sensitivities: Mapping[str, StiffnessSensitivity] = field(default_factory=dict)
    built: dict[str, float] = field(default_factory=dict)
    solves: int = 0

    def __post_init__(self) -> None:
        self.names = tuple(self.names)
        springs = built_springs(self.surrogate)
        for i, n in enumerate(_SPRINGS):
            self.built.setdefault(n, float(springs[i]))
        for n in self.names:
            if n in _SPRINGS:
                continue
            if n in self.sweeps:
                self.built.setdefault(n, self.sweeps[n].built)
            elif n in self.sensitivities and self.sensitivities[n].value is not None:
                self.built.setdefault(n, float(self.sensitivities[n].value))
            else:
                from bridge_shadow.calibrate.errors import CalibrationError

                raise CalibrationError(f"the surrogate has neither a sweep nor a sensitivity for {n}")

    @property
    def fe_names(self) -> tuple[str, ...]:
        """The parameters that are not support springs."""
        return tuple(n for n in self.names if n not in _SPRINGS)

    def _fe_change(self, name: str, value: float) -> tuple[np.ndarray, np.ndarray]:
        """(12,) change of ``[A, u0, thermal]`` from the built value and its derivative per log."""
        if name in self.sweeps:
            return self.sweeps[name].change(value)
        s = self.sensitivities[name]
        r = value / self.built[name] - 1.0
        per_r = np.concatenate(
            [s.dA.ravel(), s.du0, *(s.dthermal.get(c, np.zeros(2)) for c in THERMAL_CASES)]
        )
        return r * per_r, (1.0 + r) * per_r  # d / dlog v = v / v0 d / dr

    def evaluate(self, values: Mapping[str, float], derivatives: bool = True) -> Evaluation:
        """Return the surrogate at ``values`` (name -> SI value; others as built) and its derivatives."""
        s = self.surrogate
        vec = np.concatenate([s.A.ravel(), s.u0, *(s.thermal[c] for c in THERMAL_CASES)])
        fe = self.fe_names
        dvec = np.zeros((len(fe), 12))
        for q, n in enumerate(fe):
            change, deriv = self._fe_change(n, float(values.get(n, self.built[n])))
            vec = vec + change
            dvec[q] = deriv
        a = vec[:4].reshape(2, 2)
        u0 = vec[4:6]
        thermal = {c: vec[6 + 2 * i : 8 + 2 * i] for i, c in enumerate(THERMAL_CASES)}
        # take the built springs out: A = (A_rigid^-1 + C)^-1, so A_rigid = (I - A C)^-1 A and every
        # load of the rigid-support model is t_rigid = (I - A C)^-1 t (``forward.series_springs``)
        k_built = self.built_spring_array()
        c_built = np.where(np.isfinite(k_built), 1.0 / np.where(np.isfinite(k_built), k_built, 1.0), 0.0)
        inv_un = np.linalg.inv(np.eye(2) - a @ np.diag(c_built))
        a_rigid = inv_un @ a
        a_rigid = 0.5 * (a_rigid + a_rigid.T)
        t_rigid = {c: inv_un @ v for c, v in thermal.items()}
        # d A_rigid = U dA U', d t_rigid = U (dt + dA C t_rigid) with U = (I - A C)^-1
        da = np.array([inv_un @ d[:4].reshape(2, 2) @ inv_un.T for d in dvec]).reshape(-1, 2, 2)
        dth = {}
        for i, c in enumerate(THERMAL_CASES):
            ct = c_built * t_rigid[c]
            rows = [inv_un @ (d[6 + 2 * i : 8 + 2 * i] + d[:4].reshape(2, 2) @ ct) for d in dvec]
            dth[c] = np.array(rows).reshape(-1, 2)
        du0 = dvec[:, 4:6]
        k = np.array([float(values.get(n, self.built[n])) for n in _SPRINGS])
        sprung = series_springs(a_rigid, u0, t_rigid, k, da, du0, dth)
        allv: dict[str, float] = {**self.built, **{n: float(v) for n, v in values.items()}}
        return assemble(allv, self.names, fe, sprung, derivatives)

    def built_spring_array(self) -> np.ndarray:
        """(2,) N/m, the springs the surrogate was solved with."""
        return np.array([self.built[n] for n in _SPRINGS])

    def document(self) -> dict[str, Any]:
        """Describe what the forward model rests on (for the gap's JSON)."""
        return {
            "swept": [n for n in self.fe_names if n in self.sweeps],
            "first_order": [n for n in self.fe_names if n not in self.sweeps],
            "built": dict(self.built),
        }
