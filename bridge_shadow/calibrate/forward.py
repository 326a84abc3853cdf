"""The forward model of the calibration: named FE parameters -> surrogate (A, u0, thermal) + derivatives.

One FE solve per parameter vector (``solve_bridge``: one factorization, six right-hand sides) and
the derivatives by the adjoint route (:mod:`bridge_shadow.model.adjoint`, no extra solve). Results
are cached by parameter vector, so the evidence of several explanations that share a point costs
one solve.

The support-system springs (``support_spring_south/north``) are applied in closed form on top of
the FE solve of the structure with rigid supports; this is exact for springs in series with the
bearings (``test_model_support.py`` checks it against the FE with springs):

    A_e = (A^-1 + C)^-1,   S = A_e A^-1 = (I + A C)^-1,   thermal_e = S thermal,   u0_e = u0,

with ``C = diag(1/k_s, 1/k_n)`` (0 for ``.inf``); ``u0`` is unchanged because the
height-adjustable supports are set under the dead load (``config/bridge.yaml``). Derivatives: for
an FE parameter with ``dA, dt, du0``: ``dA_e = S dA S'``, ``dt_e = S (dt - dA C t_e)``,
``du0_e = du0``; for ``log k_i``: ``dA_e = A_e (c_i e_i e_i') A_e``,
``dt_e = S A (c_i e_i e_i') t_e``. So a calibration of the springs alone needs one FE solve.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bridge_shadow.model.adjoint import parameter_derivatives
from bridge_shadow.model.build import SUPPORT_SPRINGS, THERMAL_CASE_NAMES
from bridge_shadow.model.config import BridgeConfig
from bridge_shadow.model.solution import BridgeSolution, solve_bridge

__all__ = ["Evaluation", "ForwardModel", "SolutionStore", "assemble", "series_springs"]

log = logging.getLogger(__name__)

_SPRINGS = tuple(SUPPORT_SPRINGS.values())


@dataclass
class Evaluation:
    """The surrogate at one parameter vector and its derivatives per unit ``log`` of each parameter.

    Attributes:
        values: parameter name -> value (SI) of every named parameter of the model (after overrides).
        A: (2, 2) N/m. u0: (2,) N. thermal: case -> (2,) N/K.
        dA: (p, 2, 2), du0: (p, 2), dthermal: case -> (p, 2): derivatives ``d / d log p_k`` in the
            order of ``names``.
        names: the parameters differentiated.

    """

    values: dict[str, float]
    A: np.ndarray
    u0: np.ndarray
    thermal: dict[str, np.ndarray]
    dA: np.ndarray
    du0: np.ndarray
    dthermal: dict[str, np.ndarray]
    names: tuple[str, ...] = ()


def series_springs(
    a: np.ndarray,
    u0: np.ndarray,
    thermal: Mapping[str, np.ndarray],
    k: np.ndarray,
    da: np.ndarray | None = None,
    du0: np.ndarray | None = None,
    dthermal: Mapping[str, np.ndarray] | None = None,
) -> tuple[
    np.ndarray, np.ndarray, dict[str, np.ndarray], np.ndarray, np.ndarray, dict[str, np.ndarray], np.ndarray
]:
    """Surrogate with support springs ``k`` (2,) N/m in series (``inf`` = rigid), and derivatives.

    ``da (p, 2, 2)``, ``du0 (p, 2)``, ``dthermal[c] (p, 2)`` are derivatives of the rigid-support
    surrogate; returned are the same for the sprung one, plus ``dA_k (2, 2, 2)``: ``d A_e / d log k_i``
    (and the thermal ones are appended to ``dthermal`` as the last two rows of each case, see
    ``ForwardModel``). Returns ``(A_e, u0_e, thermal_e, dA_e, du0_e, dthermal_e, dA_k)``.
    """
    k = np.asarray(k, float)
    c = np.where(np.isfinite(k), 1.0 / k, 0.0)
    s = np.linalg.inv(np.eye(2) + a * c[None, :])  # S = (I + A C)^-1
    a_e = s @ a
    a_e = 0.5 * (a_e + a_e.T)
    t_e = {n: s @ np.asarray(v, float) for n, v in thermal.items()}
    p = 0 if da is None else len(da)
    da = np.zeros((0, 2, 2)) if da is None else np.asarray(da, float)
    du0 = np.zeros((0, 2)) if du0 is None else np.asarray(du0, float)
    dthermal = dthermal or {n: np.zeros((0, 2)) for n in thermal}
    da_e = np.einsum("ij,pjk,lk->pil", s, da, s) if p else np.zeros((0, 2, 2))
    dt_e: dict[str, np.ndarray] = {}
    for n, t in t_e.items():
        rows = [s @ (dthermal[n][q] - da[q] @ (c * t)) for q in range(p)]
        rows += [c[i] * (s @ a[:, i]) * t[i] for i in range(2)]  # d/dlog k_i: S A (c_i e_i e_i') t_e
        dt_e[n] = np.array(rows)
    da_k = np.array([c[i] * np.outer(a_e[:, i], a_e[:, i]) for i in range(2)])  # A_e (c_i e_i e_i') A_e
    return a_e, np.asarray(u0, float).copy(), t_e, da_e, du0.copy(), dt_e, da_k


def assemble(
    values: dict[str, float],
    names: tuple[str, ...],
    fe: tuple[str, ...],
    sprung: tuple[Any, ...],
    derivatives: bool = True,
) -> Evaluation:
    """Build an :class:`Evaluation` from ``series_springs``' output, derivatives in ``names`` order.

    ``fe``: the differentiated parameters that are not support springs, in the order of the rows
    of ``series_springs``' derivative arrays (the springs' rows follow them in ``dthermal``).
    """
    a_e, u0_e, t_e, da_e, du0_e, dt_e, da_k = sprung
    p = len(names)
    dA, dU, dT = np.zeros((p, 2, 2)), np.zeros((p, 2)), {c: np.zeros((p, 2)) for c in t_e}
    if derivatives:
        for q, n in enumerate(names):
            if n in _SPRINGS:
                i = _SPRINGS.index(n)
                dA[q] = da_k[i]
                for c in t_e:
                    dT[c][q] = dt_e[c][len(fe) + i]
            else:
                j = fe.index(n)
                dA[q], dU[q] = da_e[j], du0_e[j]
                for c in t_e:
                    dT[c][q] = dt_e[c][j]
    return Evaluation(values, a_e, u0_e, t_e, dA, dU, dT, names)


@dataclass
class SolutionStore:
    """FE solutions by parameter vector, shared by the forward models of several explanations.

    Attributes:
        solves: FE solves done. seconds: time in them and in the adjoint derivatives.
        cache: key -> (solution, {name: ParameterDerivative}); the key holds the FE parameters that
            differ from the bridge model's values (log, rounded to 1e-12).
        on_solve: called after each FE solve and each set of adjoint derivatives (the command's
            progress: one explanation's fit is minutes of them), or None.

    """

    solves: int = 0
    seconds: float = 0.0
    cache: dict[tuple, tuple[BridgeSolution, dict]] = field(default_factory=dict, repr=False)
    on_solve: Callable[[], None] | None = field(default=None, repr=False, compare=False)

    def solved(self) -> None:
        """Say that an FE solve or a set of derivatives is done (``on_solve``)."""
        if self.on_solve is not None:
            self.on_solve()


@dataclass
class ForwardModel:
    """Named parameter values -> :class:`Evaluation`, caching FE solves.

    Attributes:
        cfg: the bridge model (its values are the fixed ones for parameters not given).
        level: mesh level. names: parameters to differentiate (``d / d log p``).
        store: the FE solutions (share one between explanations to reuse solves).

    """

    cfg: BridgeConfig
    level: str
    names: tuple[str, ...]
    store: SolutionStore = field(default_factory=SolutionStore)

    def __post_init__(self) -> None:
        self.names = tuple(self.names)
        unknown = [n for n in self.names if n not in self.cfg.params]
        if unknown:
            from bridge_shadow.calibrate.errors import CalibrationError

            raise CalibrationError(f"unknown model parameter(s) {', '.join(unknown)}")

    @property
    def solves(self) -> int:
        """FE solves done by the store."""
        return self.store.solves

    @property
    def fe_names(self) -> tuple[str, ...]:
        """The differentiated parameters that need the FE (all but the support springs)."""
        return tuple(n for n in self.names if n not in _SPRINGS)

    def _solve(self, overrides: dict[str, float], derivatives: bool = True) -> tuple[BridgeSolution, dict]:
        base = self.cfg.params
        fe = {n: v for n, v in overrides.items() if n not in _SPRINGS and v != base[n]}
        key = tuple(sorted((n, float(np.round(np.log(v), 12))) for n, v in fe.items()))
        cfg = self.cfg.with_overrides({**fe, **dict.fromkeys(_SPRINGS, np.inf)})
        store = self.store
        if key not in store.cache:
            t0 = time.perf_counter()
            sol = solve_bridge(cfg, self.level)
            store.solves += 1
            store.seconds += time.perf_counter() - t0
            log.debug("FE solve %d (%.2f s): %s", store.solves, time.perf_counter() - t0, fe)
            store.cache[key] = (sol, {})
            store.solved()
        sol, derivs = store.cache[key]
        missing = [n for n in self.fe_names if n not in derivs]
        if derivatives and missing:
            t0 = time.perf_counter()
            derivs.update(parameter_derivatives(cfg, sol, missing, self.level))
            store.seconds += time.perf_counter() - t0
            store.solved()
        return sol, derivs

    def evaluate(self, values: Mapping[str, float], derivatives: bool = True) -> Evaluation:
        """Return the surrogate at ``values`` (name -> SI value; others from ``cfg``) and its derivatives.

        With ``derivatives`` false the derivative arrays are zeros (a trial point costs the solve only).
        """
        overrides = {n: float(v) for n, v in values.items()}
        sol, derivs = self._solve(overrides, derivatives)
        allv = {**self.cfg.params, **overrides}
        k = np.array([allv[n] for n in _SPRINGS])
        fe = self.fe_names if derivatives else ()
        da = np.array([derivs[n].A for n in fe]) if fe else np.zeros((0, 2, 2))
        du0 = np.array([derivs[n].u0 for n in fe]) if fe else np.zeros((0, 2))
        dth = {
            c: (np.array([derivs[n].thermal[c] for n in fe]) if fe else np.zeros((0, 2)))
            for c in THERMAL_CASE_NAMES
        }
        sprung = series_springs(sol.A, sol.u0, sol.thermal, k, da, du0, dth)
        return assemble(dict(allv), self.names, fe, sprung, derivatives)

    def solution(self, values: Mapping[str, float]) -> BridgeSolution:
        """Return the (cached) FE solution with rigid supports behind ``evaluate(values)``."""
        return self._solve({n: float(v) for n, v in values.items()})[0]
