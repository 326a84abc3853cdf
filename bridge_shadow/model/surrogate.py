"""FE surrogate of the bridge: ``u = A x + u0`` plus thermal and stiffness sensitivities.

- ``A`` (2x2, N/m, [south, north]): reaction change of FRC-01/FRC-02 per metre of upward
  displacement of each central bearing's ground point, from two unit-settlement solves; checked
  against the Schur complement of the stiffness matrix on the two ground DOFs (an independent
  assembly and factorization, see ``provenance.schur_check``).
- ``u0`` (N): central reactions under self-weight + superimposed load at zero settlement.
- ``thermal`` (N/K): reaction change per kelvin of the three thermal cases of :mod:`.build`.
- ``sensitivities``: for ``bearing_stiffness`` and ``connector_stiffness``, the change of ``A``,
  ``u0`` and each ``thermal`` vector per unit relative change of that parameter (central difference
  with a relative step of ``rel_step``); same units as the quantity.
"""

from __future__ import annotations

import datetime as _dt
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from bridge_shadow import __version__
from bridge_shadow.errors import ConfigError
from bridge_shadow.fe import LinearStaticSolver, Model, Result, assemble_stiffness, schur_complement
from bridge_shadow.fe.constraints import build_constraints
from bridge_shadow.model.build import (
    THERMAL_CASE_NAMES,
    build_model,
    dead_load_case,
    settlement_cases,
    thermal_cases,
)
from bridge_shadow.model.config import BridgeConfig
from bridge_shadow.model.mesh import CENTRAL_BEARINGS, END_BEARINGS, BridgeMesh, build_mesh
from bridge_shadow.model.surrogate_file import Surrogate

__all__ = [
    "SENSITIVITY_PARAMETERS",
    "BridgeSolution",
    "SurrogateRun",
    "closed_forms",
    "compute_surrogate",
    "load_sensitivities",
    "schur_A",
    "solve_bridge",
    "write_surrogate",
]

#: Parameters whose sensitivities the surrogate file carries (gap diagnosis, truth twin).
SENSITIVITY_PARAMETERS: tuple[str, str] = ("bearing_stiffness", "connector_stiffness")


@dataclass
class BridgeSolution:
    """One FE solve of the bridge: the surrogate numbers and what produced them.

    Attributes:
        A: (2, 2) N/m. u0: (2,) N. thermal: case -> (2,) N/K.
        end_reactions: end bearing name -> vertical reaction under dead load, N.
        results: FE results of the settlement, dead and thermal cases (for VTK).
        model, mesh: the FE model and mesh. solver: backend name. seconds: wall time.

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


@dataclass
class SurrogateRun:
    """A surrogate with its sensitivities, checks and the base solution (for VTK / plots)."""

    surrogate: Surrogate
    sensitivities: dict[str, Any]
    base: BridgeSolution
    schur: np.ndarray
    extra: dict[str, Any] = field(default_factory=dict)

    def document(self) -> dict[str, Any]:
        """Plain-data form: the contract keys plus ``sensitivities`` (SI units)."""
        doc = self.surrogate.to_dict()
        doc["sensitivities"] = self.sensitivities
        return doc


def solve_bridge(cfg: BridgeConfig, level: str) -> BridgeSolution:
    """Build the mesh and model of ``cfg`` at mesh ``level`` and solve all surrogate load cases."""
    t0 = time.perf_counter()
    mesh = build_mesh(cfg, level)
    model = build_model(cfg, mesh)
    solver = LinearStaticSolver(model)
    cases = [*settlement_cases(), dead_load_case(cfg), *thermal_cases(mesh)]
    results: list[Result] = solver.solve(cases)  # type: ignore[assignment]
    names = CENTRAL_BEARINGS

    def central(r: Result) -> np.ndarray:
        return np.array([r.reaction(n, "uz") for n in names])

    a_matrix = np.column_stack([central(r) for r in results[:2]])
    dead = results[2]
    thermal = {name: central(r) for name, r in zip(THERMAL_CASE_NAMES, results[3:], strict=True)}
    ends = {n: dead.reaction(n, "uz") for n in END_BEARINGS}
    return BridgeSolution(
        A=a_matrix,
        u0=central(dead),
        thermal=thermal,
        end_reactions=ends,
        results=results,
        model=model,
        mesh=mesh,
        solver=solver.backend,
        seconds=time.perf_counter() - t0,
        n_free=solver.n_free,
    )


def schur_A(cfg: BridgeConfig, mesh: BridgeMesh) -> np.ndarray:
    """Return ``A`` as the Schur complement of K on the two central ground-point uz DOFs (N/m).

    Independent of :func:`solve_bridge`: the model is assembled with those DOFs free, the other
    supports eliminated, and the complement is formed with its own factorization.
    """
    model = build_model(cfg, mesh, free_central_uz=True)
    model.validate()
    k, _, _ = assemble_stiffness(model)
    con = build_constraints(model)
    kf = (con.cf.T @ k @ con.cf).tocsr()
    ground = np.array([6 * mesh.bearings[n].ground + 2 for n in CENTRAL_BEARINGS])
    keep = np.searchsorted(con.free, ground)
    if not np.array_equal(con.free[keep], ground):
        raise ConfigError("central ground DOFs are not free in the condensation model")
    return schur_complement(kf, keep)


def closed_forms(cfg: BridgeConfig) -> dict[str, float]:
    """Two-equal-span beam formulas per girder for the bare steel and the composite section.

    The composite section takes half the deck width per girder at the slab mid-plane, uncracked,
    full shear connection, modular ratio ``E_steel / E_concrete``. Returns EI (N m^2) and the
    settlement stiffness ``6 EI / L^3`` (N/m) of each, and ``-3 EI alpha / (h L)`` (N/K) for a
    1 K linear gradient over the girder depth.
    """
    geo, sec = cfg.data["geometry"], cfg.data["sections"]["heb1000"]
    steel = cfg.data["materials"]["steel"]
    h, b, tw, tf = sec["h"], sec["b"], sec["tw"], sec["tf"]
    span = float(geo["spans"][0])
    hw = h - tf  # distance between flange mid-planes
    a_s = tw * hw + 2 * b * tf
    i_s = tw * hw**3 / 12 + 2 * (b * tf**3 / 12 + b * tf * (hw / 2) ** 2)
    n = steel["E"] / cfg.params["E_concrete"]
    bw, t = geo["deck_width"] / 2, geo["slab_thickness"]
    a_c, i_c = bw * t / n, bw * t**3 / 12 / n
    z_s, z_c = h / 2, h + t / 2
    z_na = (a_s * z_s + a_c * z_c) / (a_s + a_c)
    i_comp = i_s + a_s * (z_s - z_na) ** 2 + i_c + a_c * (z_c - z_na) ** 2
    out: dict[str, float] = {"span_m": span}
    for label, inertia in (("steel", i_s), ("composite", i_comp)):
        ei = steel["E"] * inertia
        out[f"EI_{label}_Nm2"] = ei
        out[f"k_settle_{label}_N_per_m"] = 6 * ei / span**3
        out[f"gradient_{label}_N_per_K"] = -3 * ei * steel["alpha"] / (h * span)
    return out


def _delta(plus: BridgeSolution, minus: BridgeSolution, step: float) -> dict[str, Any]:
    scale = 1.0 / (2.0 * step)
    return {
        "A": ((plus.A - minus.A) * scale).tolist(),
        "u0": ((plus.u0 - minus.u0) * scale).tolist(),
        "thermal": {k: ((plus.thermal[k] - minus.thermal[k]) * scale).tolist() for k in THERMAL_CASE_NAMES},
    }


def compute_surrogate(
    cfg: BridgeConfig,
    level: str = "default",
    *,
    sensitivities: bool = True,
    rel_step: float = 0.1,
    report: Callable[[float, str], None] | None = None,
) -> SurrogateRun:
    """Solve the bridge, check ``A`` against the Schur complement, add sensitivities and provenance."""
    t0 = time.perf_counter()
    steps = 2 + (2 * len(SENSITIVITY_PARAMETERS) if sensitivities else 0)
    done = 0

    def tick(label: str) -> None:
        nonlocal done
        done += 1
        if report is not None:
            report(done / steps, label)

    base = solve_bridge(cfg, level)
    tick("base")
    a_schur = schur_A(cfg, base.mesh)
    tick("schur")
    rel = float(np.max(np.abs(a_schur - base.A)) / np.max(np.abs(base.A)))
    sens: dict[str, Any] = {}
    if sensitivities:
        sens = {"relative_step": rel_step, "units": "same as the quantity, per unit relative change"}
        for name in SENSITIVITY_PARAMETERS:
            value = cfg.params[name]
            plus = solve_bridge(cfg.with_overrides({name: value * (1 + rel_step)}), level)
            tick(f"{name}+")
            minus = solve_bridge(cfg.with_overrides({name: value * (1 - rel_step)}), level)
            tick(f"{name}-")
            sens[name] = {"value": value, **_delta(plus, minus, rel_step)}
    counts = base.mesh.element_counts()
    dead_total = float(base.u0.sum() + sum(base.end_reactions.values()))
    provenance: dict[str, Any] = {
        "model": "config/bridge.yaml",
        "model_sha256": cfg.sha256,
        "overrides": dict(cfg.overrides),
        "mesh": level,
        "nodes": int(base.model.n_nodes),
        "dofs": int(base.model.n_dofs),
        "free_dofs": int(base.n_free),
        "elements": counts,
        "solver": f"bridge_shadow.fe.LinearStaticSolver ({base.solver})",
        "seconds": round(time.perf_counter() - t0, 3),
        "seconds_base_solve": round(base.seconds, 3),
        "package_version": __version__,
        "created_utc": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "sign_convention": "x up (m), reactions compression-positive (N), order [FRC-01 south, FRC-02 north]",
        "schur_check": {"A_schur": a_schur.tolist(), "max_rel_diff": rel, "tolerance": 1e-8},
        "end_reactions_N": {k: float(v) for k, v in base.end_reactions.items()},
        "total_dead_load_N": dead_total,
        "closed_forms": closed_forms(cfg),
    }
    surrogate = Surrogate(base.A, base.u0, base.thermal, provenance)
    return SurrogateRun(surrogate, sens, base, a_schur)


def write_surrogate(run: SurrogateRun, path: str | Path) -> Path:
    """Write the surrogate YAML (contract keys + ``sensitivities``), atomically; return the path."""
    from bridge_shadow.fileio import atomic_write_text
    from bridge_shadow.model.surrogate_file import surrogate_target

    file = surrogate_target(path)
    prov = run.surrogate.provenance
    header = (
        "# Generated by `bridge-shadow surrogate` from config/bridge.yaml; do not edit by hand.\n"
        f"# mesh {prov['mesh']}, overrides {prov['overrides'] or 'none'}. Units: A N/m, u0 N, thermal N/K,\n"
        "# sensitivities per unit relative change of the parameter (same units).\n"
    )
    text = header + yaml.safe_dump(run.document(), sort_keys=False, default_flow_style=None)
    return atomic_write_text(file, text, "surrogate file")


def load_sensitivities(path: str | Path | None = None) -> dict[str, Any]:
    """Return the ``sensitivities`` block of a surrogate file (default ``config/surrogate.yaml``).

    Maps parameter name -> ``{"value": float, "A": (2, 2), "u0": (2,), "thermal": {case: (2,)}}``
    (numpy arrays, per unit relative change of the parameter around ``value``); empty when the file
    has no such block. Read and parsed by :mod:`bridge_shadow.model.sensitivities`.
    """
    from bridge_shadow.model.sensitivities import parse_sensitivity, read_sensitivities_block

    out: dict[str, Any] = {}
    for name, block in (read_sensitivities_block(path, required=True) or {}).items():
        if isinstance(block, dict) and "A" in block:
            sens = parse_sensitivity(name, block)
            if sens is None:
                raise ConfigError(f"surrogate sensitivities for {name} have no u0")
            out[name] = {
                "value": float(block.get("value", np.nan)),
                "A": sens.dA,
                "u0": sens.du0,
                "thermal": sens.dthermal,
            }
    return out
