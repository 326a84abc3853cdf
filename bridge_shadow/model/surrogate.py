"""FE surrogate of the bridge: ``u = A x + u0`` plus thermal and stiffness sensitivities.

- ``A`` (2x2, N/m, [south, north]): reaction change of FRC-01/FRC-02 per metre of upward
  displacement of each central bearing's ground point, from two unit-settlement solves; checked
  against the Schur complement of the stiffness matrix on the two ground DOFs (an independent
  assembly and factorization, see ``provenance.schur_check``).
- ``u0`` (N): central reactions under self-weight + superimposed load at zero settlement. With
  support springs (``support_spring_*``) the height-adjustable supports are set under the dead
  load: ``u0`` is the reaction with the bearings' tops at rest (superposition of the dead-load
  solve and the two unit solves, see ``solve_bridge``), so the springs change ``A`` and the
  thermal response but not ``u0``.
- ``thermal`` (N/K): reaction change per kelvin of the three thermal cases of :mod:`.build`.
- ``sensitivities``: for ``SENSITIVITY_PARAMETERS`` (and any names asked for), the change of ``A``,
  ``u0`` and each ``thermal`` vector per unit relative change of that parameter (``d / d log p``,
  adjoint: no extra solve, :mod:`.adjoint`); same units as the quantity. A support spring at
  ``.inf`` (absent) has no relative sensitivity; its entry carries ``compliance``: the change per
  unit compliance ``c = 1 / k`` (m/N) at ``c = 0`` instead (exact series-spring closed form).
- ``sweeps`` (with ``sweeps=True``): ``A``, ``u0`` and ``thermal`` FE-solved over the plausible
  range of each of ``model.sweeps.SWEEP_PARAMETERS`` (:mod:`.sweeps`), for stiffness changes far
  beyond first order.
"""

from __future__ import annotations

import datetime as _dt
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bridge_shadow import __version__
from bridge_shadow.errors import ConfigError
from bridge_shadow.fe import assemble_stiffness, schur_complement
from bridge_shadow.fe.constraints import build_constraints
from bridge_shadow.model.adjoint import parameter_derivatives
from bridge_shadow.model.build import (
    SUPPORT_SPRINGS,
    build_model,
    has_support_springs,
    settlement_node,
)
from bridge_shadow.model.config import BridgeConfig
from bridge_shadow.model.mesh import CENTRAL_BEARINGS, BridgeMesh
from bridge_shadow.model.solution import BridgeSolution, solve_bridge
from bridge_shadow.model.surrogate_file import Surrogate
from bridge_shadow.model.sweeps import compute_sweeps

__all__ = [
    "SENSITIVITY_PARAMETERS",
    "SurrogateRun",
    "closed_forms",
    "compute_surrogate",
    "load_sensitivities",
    "schur_A",
    "write_surrogate",
]

#: Parameters whose sensitivities the surrogate file carries (gap diagnosis, truth twin).
SENSITIVITY_PARAMETERS: tuple[str, ...] = (
    "bearing_stiffness",
    "connector_stiffness",
    "support_spring_south",
    "support_spring_north",
    "slab_joint_opening",
)


@dataclass
class SurrogateRun:
    """A surrogate with its sensitivities, checks and the base solution (for VTK / plots)."""

    surrogate: Surrogate
    sensitivities: dict[str, Any]
    base: BridgeSolution
    schur: np.ndarray
    extra: dict[str, Any] = field(default_factory=dict)
    sweeps: dict[str, Any] = field(default_factory=dict)

    def document(self) -> dict[str, Any]:
        """Plain-data form: the contract keys plus ``sensitivities`` and ``sweeps`` (SI units)."""
        doc = self.surrogate.to_dict()
        doc["sensitivities"] = self.sensitivities
        if self.sweeps:
            doc["sweeps"] = {name: sw.to_dict() for name, sw in self.sweeps.items()}
        return doc


def schur_A(cfg: BridgeConfig, mesh: BridgeMesh) -> np.ndarray:
    """Return ``A`` as the Schur complement of K on the two central ground-point uz DOFs (N/m).

    Independent of :func:`solve_bridge`: the model is assembled with those DOFs free, the other
    supports eliminated, and the complement is formed with its own factorization. With support
    springs the DOFs are the foundation nodes' (the settlement is prescribed below the spring).
    """
    model = build_model(cfg, mesh, free_central_uz=True)
    model.validate()
    k, _, _ = assemble_stiffness(model)
    con = build_constraints(model)
    kf = (con.cf.T @ k @ con.cf).tocsr()
    ground = np.array([6 * settlement_node(cfg, mesh, n) + 2 for n in CENTRAL_BEARINGS])
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


def sensitivity_block(
    cfg: BridgeConfig, base: BridgeSolution, names: Sequence[str], level: str
) -> dict[str, Any]:
    """Return the surrogate file's ``sensitivities`` block for ``names`` at ``cfg`` (adjoint, no solve).

    Each entry ``{value, A, u0, thermal}`` is the change per unit relative change of the
    parameter. A support spring at ``.inf`` gets zeros and a ``compliance`` entry: the change per
    unit compliance ``c = 1 / k`` (m/N) at ``c = 0``, from the series closed form
    ``A_eff = (A^-1 + C)^-1``: ``dA/dc_i = -A e_i e_i^T A``, thermal ``-A e_i e_i^T t``, ``u0`` none.
    """
    derivs = parameter_derivatives(cfg, base, names, level)
    block: dict[str, Any] = {
        "method": "adjoint (U^T dK U, no extra solve), per unit relative change d/dlog(p)",
        "units": "same as the quantity, per unit relative change",
    }
    for name in names:
        entry = derivs[name].to_dict()
        if not np.isfinite(cfg.params[name]) and name in SUPPORT_SPRINGS.values():
            i = list(SUPPORT_SPRINGS.values()).index(name)
            col = base.A[:, i]
            entry["compliance"] = {
                "units": "per unit compliance 1/k (m/N) at 1/k = 0",
                "A": (-np.outer(col, col)).tolist(),
                "u0": [0.0, 0.0],
                "thermal": {k: (-col * v[i]).tolist() for k, v in base.thermal.items()},
            }
        block[name] = entry
    return block


def compute_surrogate(
    cfg: BridgeConfig,
    level: str = "default",
    *,
    sensitivities: bool = True,
    names: Sequence[str] = SENSITIVITY_PARAMETERS,
    report: Callable[[float, str], None] | None = None,
    sweeps: bool = False,
) -> SurrogateRun:
    """Solve the bridge, check ``A`` against the Schur complement, add sensitivities and provenance.

    ``sweeps``: also FE-solve the surrogate over the plausible range of each swept parameter
    (``model.sweeps``; about 20 more solves).
    """
    t0 = time.perf_counter()
    steps = (3 if sensitivities else 2) + (4 if sweeps else 0)
    done = 0

    def tick(label: str, n: int = 1) -> None:
        nonlocal done
        done += n
        if report is not None:
            report(done / steps, label)

    base = solve_bridge(cfg, level)
    tick("base")
    a_schur = schur_A(cfg, base.mesh)
    tick("schur")
    rel = float(np.max(np.abs(a_schur - base.A)) / np.max(np.abs(base.A)))
    sens: dict[str, Any] = {}
    if sensitivities:
        sens = sensitivity_block(cfg, base, names, level)
        tick("sensitivities")
    swept: dict[str, Any] = {}
    if sweeps:
        at = done

        def sweep_tick(frac: float, label: str) -> None:
            if report is not None:
                report((at + 4 * frac) / steps, label)

        swept = compute_sweeps(cfg, level, base=base, report=sweep_tick)
        tick("sweeps", 4)
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
    if has_support_springs(cfg):
        provenance["jack_preset_m"] = base.jack_preset.tolist()
    surrogate = Surrogate(base.A, base.u0, base.thermal, provenance)
    return SurrogateRun(surrogate, sens, base, a_schur, sweeps=swept)


def write_surrogate(
    run: SurrogateRun, path: str | Path, header: str | None = None, *, force: bool = False
) -> Path:
    """Write the surrogate YAML (contract keys, ``sensitivities``, ``sweeps``), atomically; return the path.

    ``header``: comment lines (each starting with ``#``) put on top; a default names the command.
    ``force`` replaces an existing surrogate file (``--force``); see ``save_surrogate``.
    """
    from bridge_shadow.model.surrogate_file import save_surrogate

    prov = run.surrogate.provenance
    if header is None:
        header = (
            "# Generated by `bridge-shadow surrogate` from config/bridge.yaml; do not edit by hand.\n"
            f"# mesh {prov['mesh']}, overrides {prov['overrides'] or 'none'}. "
            "Units: A N/m, u0 N, thermal N/K,\n"
            "# sensitivities per unit relative change of the parameter (same units).\n"
        )
    extra = {k: v for k, v in run.document().items() if k in ("sensitivities", "sweeps")}
    return save_surrogate(run.surrogate, path, header, force=force, extra=extra)


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
