"""Shell benchmark problems: each builds its model from scratch, solves it and returns one number.

Every problem takes ``drill`` (the drilling penalty over G; None: the default) so that the suite can
sweep it, and the two convergence problems (Scordelis-Lo roof, simply supported plate) take a
``distortion``: interior nodes moved at random by up to that fraction of the mesh spacing in each
parametric direction (``seed`` fixes the draw). References and their sources: ``references.py``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from bridge_shadow.fe.meshes import fixities, grid, node_at
from bridge_shadow.fe.model import LoadCase, Model, ShellSet, Support, Thermal
from bridge_shadow.fe.solve import LinearStaticSolver
from bridge_shadow.fe.verify.case import Timer

__all__ = [
    "Solution",
    "macneal_cantilever",
    "macneal_nodes",
    "perturb_interior",
    "pinched_cylinder",
    "scordelis_lo",
    "scordelis_lo_model",
    "ss_plate",
    "thermal_strip",
    "twisted_beam",
]


class Solution(NamedTuple):
    """What a benchmark computed: ``value`` (its own units), ``dofs`` solved for, wall ``seconds``, mesh."""

    value: float
    dofs: int
    seconds: float
    mesh: str


def perturb_interior(st: np.ndarray, n: int, amplitude: float, seed: int) -> np.ndarray:
    """Move the interior nodes of an ``n x n`` unit-square grid ``st (m, 2)`` by ``U(-a, a) / n`` each way.

    Boundary nodes stay (symmetry planes, supports, the measured corner); ``amplitude`` below 0.25
    keeps every quad convex.
    """
    if amplitude == 0.0:
        return st
    eps = 1e-12
    inner = np.all((st > eps) & (st < 1 - eps), axis=1)
    out = st.copy()
    rng = np.random.default_rng(seed)
    out[inner] += rng.uniform(-amplitude, amplitude, (int(inner.sum()), 2)) / n
    return out


def _mesh_name(n: int, what: str, distortion: float) -> str:
    return f"{n}x{n} {what}" + (f" +-{distortion:.0%}" if distortion else "")


def scordelis_lo_model(
    n: int, distortion: float = 0.0, seed: int = 0, drill: float | None = None
) -> tuple[Model, LoadCase, int]:
    """Scordelis-Lo roof quarter model ``n x n``: model, self-weight case, node of the free-edge midpoint."""
    R, L, t = 25.0, 50.0, 0.25
    st, conn = grid(n, n)
    st = perturb_interior(st, n, distortion, seed)
    x, th = st[:, 0] * L / 2, st[:, 1] * np.deg2rad(40.0)
    nodes = np.column_stack([x, R * np.sin(th), R * np.cos(th)])
    shell = ShellSet(conn, t, 4.32e8, 0.0, rho=90.0 / t, tag="roof", drill_factor=drill)  # 90 per unit area
    eps = 1e-9
    sup = fixities(
        [
            (np.flatnonzero(np.abs(x) < eps), (1, 2)),  # rigid diaphragm
            (np.flatnonzero(np.abs(x - L / 2) < eps), (0, 4, 5)),  # symmetry x = L/2
            (np.flatnonzero(np.abs(th) < eps), (1, 3, 5)),  # symmetry at the crown
        ]
    )
    i = node_at(nodes, (L / 2, R * np.sin(np.deg2rad(40.0)), R * np.cos(np.deg2rad(40.0))))
    return Model(nodes, shells=[shell], supports=sup), LoadCase("self-weight", gravity=(0.0, 0.0, -1.0)), i


def scordelis_lo(n: int, distortion: float = 0.0, seed: int = 0, drill: float | None = None) -> Solution:
    """Scordelis-Lo roof, quarter model ``n x n``: vertical deflection at the free-edge midpoint."""
    with Timer() as tm:
        model, case, i = scordelis_lo_model(n, distortion, seed, drill)
        solver = LinearStaticSolver(model)
        w = -solver.solve(case).u[i, 2]
    return Solution(w, solver.n_free, tm.seconds, _mesh_name(n, "quarter", distortion))


def pinched_cylinder(n: int, drill: float | None = None) -> Solution:
    """Pinched cylinder with end diaphragms, octant model ``n x n``: radial deflection under the load."""
    with Timer() as tm:
        R, L, t = 300.0, 600.0, 3.0
        st, conn = grid(n, n)
        x, th = st[:, 0] * L / 2, st[:, 1] * np.pi / 2
        nodes = np.column_stack([x, R * np.sin(th), R * np.cos(th)])
        shell = ShellSet(conn, t, 3.0e6, 0.3, tag="cylinder", drill_factor=drill)
        eps = 1e-9
        sup = fixities(
            [
                (np.flatnonzero(np.abs(x) < eps), (1, 2, 3)),  # rigid diaphragm
                (np.flatnonzero(np.abs(x - L / 2) < eps), (0, 4, 5)),  # symmetry x = L/2
                (np.flatnonzero(np.abs(th) < eps), (1, 3, 5)),  # symmetry plane y = 0
                (np.flatnonzero(np.abs(th - np.pi / 2) < eps), (2, 3, 4)),  # symmetry plane z = 0
            ]
        )
        solver = LinearStaticSolver(Model(nodes, shells=[shell], supports=sup))
        i = node_at(nodes, (L / 2, 0.0, R))
        res = solver.solve(LoadCase("pinch", nodal=[(i, 2, -0.25)]))  # P = 1, a quarter on the octant
        w = -res.u[i, 2]
    return Solution(w, solver.n_free, tm.seconds, f"{n}x{n} octant")


def macneal_nodes(shape: str) -> np.ndarray:
    """MacNeal-Harder straight cantilever 6.0 x 0.2, 6 x 1 elements (their Fig. 2): nodes (14, 3).

    Bottom row then top row. Element boundaries cross the axis at x = 0..6; ``trapezoidal``: the
    interior ones alternate +-45 degrees (bottom 0, 1.1, 1.9, 3.1, 3.9, 5.1, 6; top 0, 0.9, 2.1, ...);
    ``parallelogram``: all interior ones at 45 degrees (bottom 0, 0.9, 1.9, ..., 4.9, 6; top 0, 1.1,
    2.1, ..., 5.1, 6); both ends stay straight.
    """
    offsets = {
        "rectangular": np.zeros(7),
        "trapezoidal": 0.1 * np.array([0, 1, -1, 1, -1, 1, 0]),
        "parallelogram": 0.1 * np.array([0, -1, -1, -1, -1, -1, 0]),
    }
    axis = np.arange(7.0)
    off = offsets[shape]
    return np.column_stack([np.concatenate([axis + off, axis - off]), np.repeat([0.0, 0.2], 7), np.zeros(14)])


def macneal_cantilever(
    shape: str,
    direction: str,
    drill: float | None = None,
    E: float = 1.0e7,
    thickness: float = 0.1,
) -> Solution:
    """MacNeal-Harder straight cantilever, unit tip shear in-plane (y) or out-of-plane (z): tip deflection."""
    with Timer() as tm:
        nodes = macneal_nodes(shape)
        n0 = np.arange(6)
        conn = np.column_stack([n0, n0 + 1, n0 + 8, n0 + 7])
        shell = ShellSet(conn, thickness, E, 0.3, tag="beam", drill_factor=drill)
        model = Model(nodes, shells=[shell], supports=[Support("clamp", [0, 7], (0, 1, 2, 3, 4, 5))])
        solver = LinearStaticSolver(model)
        d = 1 if direction == "inplane" else 2
        res = solver.solve(LoadCase("tip", nodal=[(6, d, 0.5), (13, d, 0.5)]))
        w = 0.5 * (res.u[6, d] + res.u[13, d])
    return Solution(w, solver.n_free, tm.seconds, f"6x1 {shape}")


def twisted_beam(direction: str, drill: float | None = None) -> Solution:
    """MacNeal-Harder twisted beam (90 degree twist, 12 x 2 warped quads): tip deflection along the load.

    Length 12, width 1.1, thickness 0.32, E = 29e6, nu = 0.22; the width turns from y at the root to
    z at the tip. Unit tip load in the plane of the tip, along z (``inplane``), or normal to it,
    along y (``outofplane``); every quad is warped.
    """
    with Timer() as tm:
        st, conn = grid(12, 2)
        phi = st[:, 0] * np.pi / 2
        v = (st[:, 1] - 0.5) * 1.1
        nodes = np.column_stack([st[:, 0] * 12.0, v * np.cos(phi), v * np.sin(phi)])
        shell = ShellSet(conn, 0.32, 29.0e6, 0.22, tag="twisted", drill_factor=drill)
        root = np.flatnonzero(st[:, 0] == 0.0)
        tip = np.flatnonzero(st[:, 0] == 1.0)  # ordered across the width
        solver = LinearStaticSolver(Model(nodes, shells=[shell], supports=[Support("root", root, range(6))]))
        d = 2 if direction == "inplane" else 1
        res = solver.solve(
            LoadCase("tip", nodal=[(int(i), d, f) for i, f in zip(tip, (0.25, 0.5, 0.25), strict=True)])
        )
        w = res.u[tip[1], d]
    return Solution(w, solver.n_free, tm.seconds, "12x2 warped")


def ss_plate(n: int, distortion: float = 0.0, seed: int = 0, drill: float | None = None) -> Solution:
    """Simply supported square plate (hard support), uniform pressure, quarter model: ``w D / (q a^4)``."""
    with Timer() as tm:
        a, t, E, nu, q = 1.0, 0.001, 2.0e11, 0.3, 1.0
        st, conn = grid(n, n)
        st = perturb_interior(st, n, distortion, seed)
        nodes = np.column_stack([st * a / 2, np.zeros(len(st))])
        x, y = nodes[:, 0], nodes[:, 1]
        eps = 1e-9
        sup = fixities(
            [
                (np.flatnonzero(np.abs(x - a / 2) < eps), (2, 3)),  # edge x = a/2: w, rx
                (np.flatnonzero(np.abs(y - a / 2) < eps), (2, 4)),  # edge y = a/2: w, ry
                (np.flatnonzero(np.abs(x) < eps), (0, 4)),  # symmetry
                (np.flatnonzero(np.abs(y) < eps), (1, 3)),  # symmetry
                (np.arange(len(nodes)), (5,)),  # flat plate: drilling stays at rest
            ]
        )
        shell = ShellSet(conn, t, E, nu, tag="plate", drill_factor=drill)
        solver = LinearStaticSolver(Model(nodes, shells=[shell], supports=sup))
        res = solver.solve(LoadCase("q", pressure={"plate": -q}))
        d = E * t**3 / (12 * (1 - nu**2))
        w = -res.u[node_at(nodes, (0.0, 0.0, 0.0)), 2] * d / (q * a**4)
    return Solution(w, solver.n_free, tm.seconds, _mesh_name(n, "quarter", distortion))


_PATCH_INNER = np.array([[0.04, 0.02], [0.18, 0.03], [0.16, 0.08], [0.08, 0.08]])


def _patch_mesh() -> tuple[np.ndarray, np.ndarray]:
    """MacNeal-Harder patch 0.24 x 0.12 with 4 distorted interior nodes: 8 nodes, 5 quads."""
    outer = np.array([[0.0, 0.0], [0.24, 0.0], [0.24, 0.12], [0.0, 0.12]])
    xy = np.vstack([outer, _PATCH_INNER])
    conn = np.array([[0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7], [4, 5, 6, 7]])
    return np.column_stack([xy, np.zeros(8)]), conn


def patch_test(kind: str, inner: np.ndarray | None = None, spin: float = 0.0) -> Solution:
    """Membrane or bending patch test: boundary nodes follow an exact constant-strain field.

    ``value`` is the largest error of the interior nodes' DOFs over the largest DOF value.
    ``inner`` (4, 2) replaces the interior node positions (property tests use random ones);
    ``spin`` (rad) adds a rigid in-plane rotation to the membrane field (``rz`` follows it).
    """
    with Timer() as tm:
        nodes, conn = _patch_mesh()
        if inner is not None:
            nodes[4:, :2] = inner
        x, y = nodes[:, 0], nodes[:, 1]
        exact = np.zeros((8, 6))
        if kind == "membrane":
            exact[:, 0] = 1e-3 * (x + y / 2) - spin * y
            exact[:, 1] = 1e-3 * (y + x / 2) + spin * x
            exact[:, 5] = spin  # omega = (v,x - u,y) / 2
        else:
            w = 1e-3 * (x**2 + x * y + y**2) / 2
            exact[:, 2] = w
            exact[:, 3] = 1e-3 * (x / 2 + y)  # rx = w,y
            exact[:, 4] = -1e-3 * (x + y / 2)  # ry = -w,x
        shell = ShellSet(conn, 0.001, 1.0e6, 0.25, tag="patch")
        supports = [Support(f"b{i}", [i], (0, 1, 2, 3, 4, 5)) for i in range(4)]
        solver = LinearStaticSolver(Model(nodes, shells=[shell], supports=supports))
        res = solver.solve(LoadCase("patch", prescribed={f"b{i}": exact[i] for i in range(4)}))
        err = np.abs(res.u[4:] - exact[4:]).max() / np.abs(exact).max()
    return Solution(err, solver.n_free, tm.seconds, "5 quads")


def thermal_strip(n: int) -> Solution:
    """Shell strip L x b under a through-thickness gradient, held at one root node: tip deflection.

    A free plate bends into ``kappa = alpha dT / h`` in both directions without stress; the root's
    middle node is clamped (statically determinate), the tip deflection along the axis is
    ``alpha dT L^2 / (2 h)`` downward when the +z face is warmer.
    """
    with Timer() as tm:
        L, b, h, alpha, dT = 1.0, 0.1, 0.01, 1.2e-5, 10.0
        st, conn = grid(n, 2)
        nodes = np.column_stack([st[:, 0] * L, (st[:, 1] - 0.5) * b, np.zeros(len(st))])
        root = node_at(nodes, (0.0, 0.0, 0.0))
        tip = node_at(nodes, (L, 0.0, 0.0))
        shell = ShellSet(conn, h, 2.1e11, 0.3, alpha=alpha, tag="strip")
        model = Model(nodes, shells=[shell], supports=[Support("root", [root], (0, 1, 2, 3, 4, 5))])
        solver = LinearStaticSolver(model)
        res = solver.solve(LoadCase("gradient", thermal=[Thermal("strip", gradient=dT)]))
        w = -res.u[tip, 2]
    return Solution(w, solver.n_free, tm.seconds, f"{n}x2")
