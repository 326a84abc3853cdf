"""Sensitivities of the surrogate to named parameters, by the adjoint route: no extra FE solve.

Let ``U_i`` be the displacement field (every DOF) of a unit settlement of central bearing ``i``
(the other held), ``u_c`` the field of load case ``c`` at zero settlement and ``f_c`` its load
vector. With the stiffness matrix ``K`` and reactions ``K u - f``:

    A_ij        = U_i^T K U_j               ->  dA_ij  = U_i^T dK U_j
    thermal_c,i = U_i^T (K u_c - f_c)       ->  dth_ci = U_i^T (dK u_c - df_c)
    u0_i        = V_i^T (K u_d - f_d)       ->  du0_i  = V_i^T (dK' u_d - df_d)

where ``d = d / d log p`` (the change per unit relative change of parameter ``p``). The terms
with ``dU`` and ``du`` drop out because ``U_i`` and ``u_c`` are equilibrium fields of the same
constrained space (``C_f^T K U_i = 0``; the reaction at ``i`` of ``K du`` vanishes). For ``u0`` the
supports are height-adjustable and set under the dead load (``bridge.yaml``,
``support_spring_*``): ``V_i`` is the unit field with the bearing's top (ground node) prescribed,
``V = U W^-1`` with ``W_ki`` the top displacement of bearing ``k`` in ``U_i``, ``u_d`` the dead-load
field with the tops at rest, and ``dK'`` leaves out the support springs (which then carry no
change of ``u0``).

``dK`` (and ``df`` for loads that scale with a stiffness, e.g. the thermal loads of the slab with
``E_concrete``) comes from assembling only the element sets whose data change with ``p``: the
model at ``p`` minus the model at ``p / 2``, divided by ``log 2``'s linear counterpart ``1/2``
(every named stiffness enters its sets linearly, so this is exact; ``test_model_adjoint.py``
checks it against finite differences of full solves). A spring at ``.inf`` has no relative
sensitivity (zero).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from bridge_shadow.fe import LoadCase, Model
from bridge_shadow.fe.loads import load_vector
from bridge_shadow.fe.solve import assemble_stiffness
from bridge_shadow.model.build import build_model
from bridge_shadow.model.config import BridgeConfig
from bridge_shadow.model.mesh import BridgeMesh, build_mesh
from bridge_shadow.model.solution import BridgeSolution, dead_and_thermal_cases

__all__ = ["ParameterDerivative", "changed_sets", "parameter_derivatives"]

#: Factor by which a parameter is scaled down to find the element sets that depend on it.
_SCALE = 0.5
#: Tag prefix of the support-system springs (no change of u0 by construction, see the docstring).
_SUPPORT_TAG = "support_"


@dataclass(frozen=True)
class ParameterDerivative:
    """Change of the surrogate per unit relative change of one parameter (``d / d log p``).

    Attributes:
        name: parameter name. value: its value (SI) where the derivative was taken.
        A: (2, 2) N/m. u0: (2,) N. thermal: case -> (2,) N/K.
        sets: tags of the element sets that depend on the parameter.

    """

    name: str
    value: float
    A: np.ndarray
    u0: np.ndarray
    thermal: dict[str, np.ndarray]
    sets: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, object]:
        """Plain data in the surrogate file's ``sensitivities`` entry format."""
        return {
            "value": float(self.value),
            "A": self.A.tolist(),
            "u0": self.u0.tolist(),
            "thermal": {k: v.tolist() for k, v in self.thermal.items()},
        }


def _same(a: object, b: object) -> bool:
    """Field equality of two element sets (arrays compared exactly)."""
    for f in dataclasses.fields(a):  # type: ignore[arg-type]
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
            if x is None or y is None or np.shape(x) != np.shape(y) or not np.array_equal(x, y):
                return False
        elif x != y:
            return False
    return True


def changed_sets(base: Model, other: Model) -> list[str]:
    """Tags of the shell, beam and spring sets whose data differ between two models of one mesh."""
    out = []
    for kind in ("shells", "beams", "springs"):
        a = {s.tag: s for s in getattr(base, kind)}
        b = {s.tag: s for s in getattr(other, kind)}
        if set(a) != set(b):
            raise ValueError(f"the two models have different {kind} sets: {sorted(set(a) ^ set(b))}")
        out += [tag for tag in a if not _same(a[tag], b[tag])]
    return out


def _partial(model: Model, tags: Iterable[str]) -> Model:
    """Return the model restricted to the element sets ``tags`` (no supports, no links)."""
    keep = set(tags)
    return Model(
        model.nodes,
        shells=[s for s in model.shells if s.tag in keep],
        beams=[b for b in model.beams if b.tag in keep],
        springs=[s for s in model.springs if s.tag in keep],
    )


def _case_on(case: LoadCase, tags: set[str]) -> LoadCase:
    """``case`` restricted to the element sets ``tags`` (pressure, thermal; gravity kept)."""
    return LoadCase(
        name=case.name,
        gravity=case.gravity,
        pressure={t: v for t, v in case.pressure.items() if t in tags},
        thermal=[t for t in case.thermal if t.tag in tags],
        beam_loads=[b for b in case.beam_loads if b.tag in tags],
    )


def _stiffness_and_loads(
    model: Model, tags: Sequence[str], cases: Sequence[LoadCase]
) -> tuple[sp.csr_matrix, np.ndarray]:
    """Stiffness ``(n_dofs, n_dofs)`` and load vectors ``(n_dofs, n_cases)`` of the sets ``tags``."""
    part = _partial(model, tags)
    k, kins, geos = assemble_stiffness(part)
    present = {s.tag for s in (*part.shells, *part.beams)}
    f = np.column_stack([load_vector(part, _case_on(c, present), kins, geos) for c in cases])
    return k, f


def parameter_derivatives(
    cfg: BridgeConfig,
    solution: BridgeSolution,
    names: Sequence[str],
    level: str,
    mesh: BridgeMesh | None = None,
) -> dict[str, ParameterDerivative]:
    """``d(A, u0, thermal) / d log p`` at ``cfg`` for each parameter in ``names`` (adjoint, no solve).

    ``solution`` is ``solve_bridge(cfg, level)`` (it carries the unit, dead and thermal fields and
    the load cases). A parameter at ``.inf`` gets zeros.
    """
    mesh = mesh if mesh is not None else solution.mesh
    base = solution.model
    cases = dead_and_thermal_cases(cfg, mesh)
    fields = solution.fields
    u_unit, v_top = fields["unit"], fields["unit_top"]  # (2, n_dofs)
    u_cases = np.column_stack([fields["dead"], *[fields[c.name] for c in cases[1:]]])  # (n_dofs, 4)
    out: dict[str, ParameterDerivative] = {}
    for name in names:
        value = float(cfg.params[name])
        thermal_names = [c.name for c in cases[1:]]
        if not np.isfinite(value):
            zero = np.zeros(2)
            out[name] = ParameterDerivative(
                name, value, np.zeros((2, 2)), zero, {c: zero for c in thermal_names}
            )
            continue
        scaled = cfg.with_overrides({name: value * _SCALE})
        other = build_model(scaled, build_mesh(scaled, level))
        tags = changed_sets(base, other)
        k1, f1 = _stiffness_and_loads(base, tags, cases)
        k0, f0 = _stiffness_and_loads(other, tags, cases)
        dk = (k1 - k0) / (1.0 - _SCALE)  # K linear in p: K(p) - K(p s) = (1 - s) p dK/dp
        df = (f1 - f0) / (1.0 - _SCALE)
        da = u_unit @ (dk @ u_unit.T)
        r = dk @ u_cases - df  # (n_dofs, 4): dK u_c - df_c
        thermal = {c: u_unit @ r[:, i + 1] for i, c in enumerate(thermal_names)}
        u0_tags = [t for t in tags if not t.startswith(_SUPPORT_TAG)]
        if len(u0_tags) == len(tags):
            du0 = v_top @ r[:, 0]
        elif u0_tags:
            k1, f1 = _stiffness_and_loads(base, u0_tags, cases[:1])
            k0, f0 = _stiffness_and_loads(other, u0_tags, cases[:1])
            du0 = v_top @ ((k1 - k0) @ u_cases[:, 0] - (f1 - f0)[:, 0]) / (1.0 - _SCALE)
        else:
            du0 = np.zeros(2)
        out[name] = ParameterDerivative(name, value, 0.5 * (da + da.T), du0, thermal, tuple(tags))
    return out
