"""One FE solve of the bridge for the surrogate: the unit-settlement, dead-load and thermal cases.

``solve_bridge`` builds the mesh and model at a mesh level, factorizes once and solves the six
load cases; ``BridgeSolution`` carries the surrogate numbers (``A``, ``u0``, ``thermal``) and the
displacement fields the adjoint sensitivities (:mod:`.adjoint`) and the sweeps (:mod:`.sweeps`)
build on. The surrogate itself (checks, sensitivities, provenance) is :mod:`.surrogate`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from bridge_shadow.fe import LinearStaticSolver, LoadCase, Model, Result
from bridge_shadow.model.build import (
    THERMAL_CASE_NAMES,
    build_model,
    dead_load_case,
    has_support_springs,
    settlement_cases,
    thermal_cases,
)
from bridge_shadow.model.config import BridgeConfig
from bridge_shadow.model.mesh import CENTRAL_BEARINGS, END_BEARINGS, BridgeMesh, build_mesh

__all__ = ["BridgeSolution", "dead_and_thermal_cases", "solve_bridge"]


@dataclass
class BridgeSolution:
    """One FE solve of the bridge: the surrogate numbers and what produced them.

    Attributes:
        A: (2, 2) N/m. u0: (2,) N. thermal: case -> (2,) N/K.
        end_reactions: end bearing name -> vertical reaction under dead load, N.
        results: FE results of the settlement, dead and thermal cases (for VTK).
        model, mesh: the FE model and mesh. solver: backend name. seconds: wall time.
        fields: displacement fields, each ``(n_dofs,)`` m (``(2, n_dofs)`` for the unit cases):
            ``unit`` (unit settlement of each central bearing at its settlement node),
            ``unit_top`` (unit displacement of each bearing's top, the supports following),
            ``dead`` (dead load, bearing tops at rest) and one per thermal case.
        jack_preset: (2,) m, the settlement-node displacement that puts the bearing tops back at
            rest under the dead load (0 without support springs).

    """

    A: np.ndarray
    u0: np.ndarray
    thermal: dict[str, np.ndarray]
    end_reactions: dict[str, float]
    results: list[Result]
    model: Model
    mesh: BridgeMesh
    solver: str
    seconds: float
    n_free: int
    fields: dict[str, np.ndarray] = field(default_factory=dict)
    jack_preset: np.ndarray = field(default_factory=lambda: np.zeros(2))


def dead_and_thermal_cases(cfg: BridgeConfig, mesh: BridgeMesh) -> list[LoadCase]:
    """Return the dead-load case followed by the thermal cases (``THERMAL_CASE_NAMES`` order)."""
    return [dead_load_case(cfg), *thermal_cases(mesh)]


def solve_bridge(cfg: BridgeConfig, level: str) -> BridgeSolution:
    """Build the mesh and model of ``cfg`` at mesh ``level`` and solve all surrogate load cases.

    One factorization, six right-hand sides (two unit settlements, dead load, three thermal
    cases). With support springs the dead-load state is superposed with the unit settlements so
    that the bearing tops are at rest (jacks set under the dead load): with ``W`` (2, 2) the top
    displacements of the unit cases and ``w`` those of the plain dead-load solve, the jacks preset
    ``p = -W^-1 w`` and ``u0 = R_dead + A p``.
    """
    t0 = time.perf_counter()
    mesh = build_mesh(cfg, level)
    model = build_model(cfg, mesh)
    solver = LinearStaticSolver(model)
    cases = [*settlement_cases(), *dead_and_thermal_cases(cfg, mesh)]
    results: list[Result] = solver.solve(cases)  # type: ignore[assignment]
    names = CENTRAL_BEARINGS

    def central(r: Result) -> np.ndarray:
        return np.array([r.reaction(n, "uz") for n in names])

    a_matrix = np.column_stack([central(r) for r in results[:2]])
    unit = np.stack([r.u.ravel() for r in results[:2]])  # (2, n_dofs)
    dead = results[2]
    preset = np.zeros(2)
    top = np.array([6 * mesh.bearings[n].ground + 2 for n in names])
    w_unit = unit[:, top].T  # W_ki: top k in unit case i
    if has_support_springs(cfg):
        preset = -np.linalg.solve(w_unit, dead.u.ravel()[top])
        dead.u = (dead.u.ravel() + preset @ unit).reshape(dead.u.shape)
        for n in dead.reactions:
            dead.reactions[n] = dead.reactions[n] + sum(preset[j] * results[j].reactions[n] for j in range(2))
    u0 = central(dead)
    thermal = {name: central(r) for name, r in zip(THERMAL_CASE_NAMES, results[3:], strict=True)}
    ends = {n: dead.reaction(n, "uz") for n in END_BEARINGS}
    fields = {
        "unit": unit,
        "unit_top": np.linalg.solve(w_unit.T, unit),  # V = U W^-1, rows (V^T) = W^-T U^T
        "dead": dead.u.ravel(),
        **{name: r.u.ravel() for name, r in zip(THERMAL_CASE_NAMES, results[3:], strict=True)},
    }
    return BridgeSolution(
        A=a_matrix,
        u0=u0,
        thermal=thermal,
        end_reactions=ends,
        results=results,
        model=model,
        mesh=mesh,
        solver=solver.backend,
        seconds=time.perf_counter() - t0,
        n_free=solver.n_free,
        fields=fields,
        jack_preset=preset,
    )
