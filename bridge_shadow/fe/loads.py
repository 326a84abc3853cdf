"""Load vectors: nodal forces, shell pressure, self-weight, thermal loads, beam line loads."""

from __future__ import annotations

import numpy as np

from bridge_shadow.fe.assembly import element_dofs, scatter_vector
from bridge_shadow.fe.elements.beam import BeamGeometry, beam_line_load_vector, beam_thermal_vector
from bridge_shadow.fe.elements.shell import (
    ShellKinematics,
    shell_mass_vector,
    shell_pressure_vector,
    shell_thermal_vector,
)
from bridge_shadow.fe.errors import ModelError
from bridge_shadow.fe.model import LoadCase, Model

__all__ = ["load_vector"]


def _mask(mask: object, n_el: int, tag: str) -> np.ndarray:
    if mask is None:
        return np.ones(n_el, bool)
    m = np.asarray(mask, bool)
    if m.shape != (n_el,):
        raise ModelError(f"load mask for {tag!r} must have shape ({n_el},), got {m.shape}")
    return m


def _per_shell(value: object, n_el: int, tag: str) -> np.ndarray:
    """Shell temperature: scalar or (n_el,) -> (n_el,); (n_el, 4) nodal values kept."""
    v = np.asarray(value, float)
    if v.ndim == 2:
        if v.shape != (n_el, 4):
            raise ModelError(f"nodal temperatures for {tag!r} must have shape ({n_el}, 4), got {v.shape}")
        return v
    try:
        return np.broadcast_to(v, (n_el,)).astype(float)
    except ValueError as err:
        raise ModelError(f"temperature for {tag!r} must be a scalar or shape ({n_el},)") from err


def _nodal(case: LoadCase, n_dofs: int) -> np.ndarray:
    f = np.zeros(n_dofs)
    rows = np.asarray(case.nodal, float).reshape(-1, 3) if len(case.nodal) else np.zeros((0, 3))
    if len(rows):
        node, dof = rows[:, 0].astype(np.int64), rows[:, 1].astype(np.int64)
        if node.min() < 0 or 6 * node.max() + 5 >= n_dofs or dof.min() < 0 or dof.max() > 5:
            raise ModelError(f"load case {case.name!r}: nodal load outside the model")
        np.add.at(f, 6 * node + dof, rows[:, 2])
    return f


def load_vector(
    model: Model,
    case: LoadCase,
    shell_kin: list[ShellKinematics],
    beam_geo: list[BeamGeometry],
) -> np.ndarray:
    """Global load vector ``(n_dofs,)`` (N, N m) of ``case``; ``shell_kin``/``beam_geo`` match the sets."""
    n = model.n_dofs
    f = _nodal(case, n)
    g = None if case.gravity is None else np.asarray(case.gravity, float).reshape(3)
    tags = {s.tag for s in (*model.shells, *model.beams)}
    for tag in (*case.pressure, *(t.tag for t in case.thermal), *(b.tag for b in case.beam_loads)):
        if tag not in tags:
            raise ModelError(f"load case {case.name!r}: no element set tagged {tag!r}")
    for s, kin in zip(model.shells, shell_kin, strict=True):
        dofs = element_dofs(s.conn)
        fe = np.zeros((s.n_el, 24))
        if s.tag in case.pressure:
            fe += shell_pressure_vector(kin, np.full(s.n_el, float(case.pressure[s.tag])))
        if g is not None:
            fe += shell_mass_vector(kin, s.thickness, s.rho, g)
        for th in case.thermal:
            if th.tag == s.tag:
                m = _mask(th.mask, s.n_el, s.tag)
                du = _per_shell(th.uniform, s.n_el, s.tag)
                dg = _per_shell(th.gradient, s.n_el, s.tag)
                du = du * (m if du.ndim == 1 else m[:, None])
                dg = dg * (m if dg.ndim == 1 else m[:, None])
                fe += shell_thermal_vector(kin, s.thickness, s.E, s.nu, s.alpha, du, dg)
        f += scatter_vector(n, dofs, fe)
    for b, geo in zip(model.beams, beam_geo, strict=True):
        dofs = element_dofs(b.conn)
        fe = np.zeros((b.n_el, 12))
        w = np.zeros((b.n_el, 3))
        if g is not None:
            w += (b.rho * b.A)[:, None] * g
        for bl in case.beam_loads:
            if bl.tag == b.tag:
                w += _mask(bl.mask, b.n_el, b.tag)[:, None] * np.asarray(bl.w, float).reshape(-1, 3)
        if np.any(w):
            fe += beam_line_load_vector(geo, w)
        for th in case.thermal:
            if th.tag == b.tag:
                m = _mask(th.mask, b.n_el, b.tag)
                fe += beam_thermal_vector(
                    geo,
                    b.A,
                    b.Iy,
                    b.Iz,
                    b.E,
                    b.alpha,
                    b.depth_y,
                    b.depth_z,
                    th.uniform * m,
                    th.gradient * m,
                    th.gradient_y * m,
                )
        f += scatter_vector(n, dofs, fe)
    return f
